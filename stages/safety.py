"""safety: risk, warning, AEB and the Euro NCAP-style outcome of the driving scenes
(blindspot.safety.assess) per predictor and input (tracker, oracle association, noisy position,
true state): the main Monte-Carlo draw (its even / odd halves), the nominal grids (ncap.json) and
the independent tuning and held-out draws' blocks with each predictor's AEB operating point."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import json

import pandas as pd

from blindspot.radar.config import RadarConfig
from blindspot.radar.scenario import load_scenarios
from blindspot.safety.config import WarningConfig
from blindspot.typed_config import jobs
from blindspot.cli import main_stage
from blindspot.io import write_json, write_parquet
from blindspot.safety.assess import assess, logged_metrics, summary_lines
from blindspot.safety.draws import chain_digest, read_draw
from blindspot.safety.operating_point import operating_blocks
from blindspot.safety.oracle import true_state_tracks
from blindspot.safety.outcome import body_boxes
from blindspot.safety.predict import stage_predictors
from blindspot.safety.risk import EgoShape
from blindspot.stage import StageResult


def run(cfg, ctx):
    w, digest = WarningConfig.from_cfg(cfg), chain_digest(cfg)
    draws = (read_draw(ctx.dep("safety_tuning.json"), digest),      # first: fail fast
             read_draw(ctx.dep("safety_held_out.json"), digest))
    group, _ = load_scenarios(cfg.scenario)
    dt = float(RadarConfig.from_cfg(cfg, "driving_radar").frame_period_s)
    truth = pd.read_parquet(ctx.dep("truth.parquet"))
    tracks = {"tracker": pd.read_parquet(ctx.dep("tracks.parquet")),
              **{name: pd.read_parquet(ctx.dep(f"tracks_{name}.parquet"))
                 for name in ("oracle", "noisy_position")},
              "true_state": true_state_tracks(truth)}
    preds = stage_predictors(cfg, ctx.dep, jobs=jobs(cfg))
    res = assess(truth, json.loads(ctx.dep("scenes.json").read_text()), tracks, preds, w,
                 bodies=body_boxes(group), shape=EgoShape(group.ego.width_m, group.ego.length_m),
                 points=pd.read_parquet(ctx.dep("points.parquet"), columns=["scene", "frame", "source"]),
                 points_name=str(ctx.dep("points.parquet")), frame_period_s=dt,
                 figure_scene=group.figure_scene, draw_seed=group.monte_carlo.seed,
                 only=dict.fromkeys(("oracle", "noisy_position", "true_state"), w.reference_predictors))
    for name, table in {"risk": res.risk, "ncap_grid": res.grid, "scene_outcomes": res.scenes,
                        "operating": res.curves, "timeline": res.timeline}.items():
        write_parquet(ctx.out(f"{name}.parquet"), table)
    # the independent draws: each predictor's AEB operating point chosen on one, read on the other
    res.metrics["tuning_draw"], res.metrics["held_out"] = operating_blocks(
        *draws, w.false_activation_target)
    write_json(ctx.out("safety.json"), res.metrics)
    write_json(ctx.out("ncap.json"), res.ncap)
    print("\n".join(summary_lines(res.metrics)))
    return StageResult(metrics=logged_metrics(res.metrics))


if __name__ == "__main__":
    main_stage(run, "safety")
