"""fig_safety: the warning/AEB figures and the Euro NCAP-shaped table (issue 12), read from the
safety stage's artifacts (blindspot.report.safety_figures computes nothing)."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import json

import pandas as pd

from blindspot.cli import main_stage
from blindspot.io import save_figure, write_text
from blindspot.report.safety_figures import (
    fig_lead_times, fig_ncap_grid, fig_operating_characteristic, fig_safety_timeline,
    ncap_grid_markdown,
)
from blindspot.stage import StageResult


def run(cfg, ctx):
    metrics = json.loads(ctx.dep("safety.json").read_text())
    truth = pd.read_parquet(ctx.dep("truth.parquet"))
    scenes_meta = json.loads(ctx.dep("scenes.json").read_text())
    scenes = pd.read_parquet(ctx.dep("scene_outcomes.parquet"))
    risk = pd.read_parquet(ctx.dep("risk.parquet"))
    curves = pd.read_parquet(ctx.dep("operating.parquet"))
    grid = pd.read_parquet(ctx.dep("ncap_grid.parquet"))
    timeline = pd.read_parquet(ctx.dep("timeline.parquet"))
    predictors = [p for p in metrics]
    settings = metrics[predictors[0]]["settings"]
    headline = settings["headline_input"]
    name = str(cfg.scenario.figure_scene)
    info = scenes_meta[name]
    def timeline_figure(inp):
        sfx = "" if inp == "tracker" else f"_{inp}"
        tracks = pd.read_parquet(ctx.dep(f"tracks{sfx}.parquet"))
        have = [p for p in predictors if inp in metrics[p]["by_input"]]
        best = max(have, key=lambda p: metrics[p]["by_input"][inp]["avoided_rate"] or 0.0)
        return fig_safety_timeline(
            truth[truth.scene == name], tracks[tracks.group == name],
            risk[(risk.group == name) & (risk.input == inp)], timeline[timeline.input == inp],
            scenes[(scenes.scene == name) & (scenes.input == inp)], info["car_polygons_xy_m"],
            ego_width_m=float(cfg.scenario.ego.width_m),
            ego_length_m=float(cfg.scenario.ego.length_m),
            warning_threshold=settings["warning_threshold"],
            aeb_threshold=settings["aeb_threshold"], predictor=best,
            title=f"{name} at {info['speed_kmh']:g} km/h ({inp} input)")

    # the headline input, and the visible-truth reference (what the logic does when the
    # pedestrian is seen whenever in line of sight)
    outs = [save_figure(timeline_figure(headline), ctx.out("safety_timeline.png"), dpi=110),
            save_figure(timeline_figure("visible_truth"),
                        ctx.out("safety_timeline_visible_truth.png"), dpi=110)]
    operating = {inp: {p: metrics[p]["by_input"][inp] for p in predictors
                       if inp in metrics[p]["by_input"]} for inp in settings["inputs"]}
    bound = json.loads(ctx.dep("safety_bound.json").read_text())
    bounds = {k: v["avoided_rate"] for k, v in bound.items() if k != "settings"}
    confirm = (bound["settings"]["confirm_m"], bound["settings"]["confirm_n"])
    outs.append(save_figure(fig_operating_characteristic(curves, operating, bounds, confirm),
                            ctx.out("safety_operating.png"), dpi=110))
    outs.append(save_figure(fig_ncap_grid(grid[grid.input == headline], predictors),
                            ctx.out("safety_ncap_grid.png"), dpi=110))
    ev = scenes[(scenes.input == headline) & scenes.evaluated & scenes.intruding]
    outs.append(save_figure(fig_lead_times(ev, predictors), ctx.out("safety_lead_times.png"),
                            dpi=110))
    md = [f"Euro NCAP-shaped grid of the Monte-Carlo intruding scenes ({headline} input; "
          "cells: scenes avoided / scenes, mean impact speed, 2026 band of that mean; and how "
          "many of them braked from a frame before anything, line of sight or a radar point, "
          "showed the lead pedestrian: for another pedestrian or clutter).\n"]
    for inp in settings["inputs"]:
        for p in predictors:
            if inp not in metrics[p]["by_input"]:
                continue
            md += [f"\n### {p} ({inp})\n\n", ncap_grid_markdown(grid[grid.input == inp], p)]
    outs.append(write_text(ctx.out("safety_grid.md"), "".join(md)))
    print("fig_safety: " + ", ".join(map(str, outs)))
    return StageResult(artifacts=outs)


if __name__ == "__main__":
    main_stage(run, "fig_safety")
