"""fig_safety: the warning/AEB figures, the Monte-Carlo and Euro NCAP nominal grid pages (issues
12, 40) from the safety stage's artifacts."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import json

import pandas as pd

from blindspot.cli import main_stage
from blindspot.io import save_figure, write_text
from blindspot.report.safety_figures import (fig_lead_times, fig_ncap_grid,
                                             fig_operating_characteristic, fig_safety_timeline)
from blindspot.report.safety_tables import grid_page, ncap_page, operating_inputs, predictor_names
from blindspot.stage import StageResult


def run(cfg, ctx):
    metrics = json.loads(ctx.dep("safety.json").read_text())
    truth, scenes, risk, curves, grid, timeline = (pd.read_parquet(p) for p in (
        ctx.dep("truth.parquet"), ctx.dep("scene_outcomes.parquet"), ctx.dep("risk.parquet"),
        ctx.dep("operating.parquet"), ctx.dep("ncap_grid.parquet"), ctx.dep("timeline.parquet")))
    predictors = predictor_names(metrics)
    settings = metrics[predictors[0]]["settings"]
    headline, name = settings["headline_input"], str(cfg.scenario.figure_scene)
    info = json.loads(ctx.dep("scenes.json").read_text())[name]

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
            ego_length_m=float(cfg.scenario.ego.length_m), predictor=best,
            **{k: settings[k] for k in ("warning_threshold", "aeb_threshold")},
            title=f"{name} at {info['speed_kmh']:g} km/h ({inp} input)")

    outs = [save_figure(timeline_figure(headline), ctx.out("safety_timeline.png"), dpi=110),
            save_figure(timeline_figure("noisy_position"),
                        ctx.out("safety_timeline_noisy_position.png"), dpi=110)]
    oc = operating_inputs(metrics, json.loads(ctx.dep("safety_bound.json").read_text()))
    outs.append(save_figure(fig_operating_characteristic(curves, *oc),
                            ctx.out("safety_operating.png"), dpi=110))
    ev = scenes[(scenes.input == headline) & scenes.evaluated & scenes.intruding]
    outs += [save_figure(fig, out, dpi=110) for fig, out in (
        (fig_ncap_grid(grid[grid.input == headline], predictors), ctx.out("safety_ncap_grid.png")),
        (fig_lead_times(ev, predictors), ctx.out("safety_lead_times.png")))]
    outs.append(write_text(ctx.out("safety_grid.md"), grid_page(grid, metrics)))
    ncap, held_bound = (json.loads(p.read_text()) for p in (
        ctx.dep("ncap.json"), ctx.dep("safety_held_out_bound.json")))
    outs.append(write_text(ctx.out("safety_ncap.md"), ncap_page(ncap, metrics, held_bound)))
    print("fig_safety: " + ", ".join(map(str, outs)))
    return StageResult(artifacts=outs)


if __name__ == "__main__":
    main_stage(run, "fig_safety")
