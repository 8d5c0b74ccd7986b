"""safety: risk, warning, AEB and the Euro NCAP-style outcome of the driving scenes (issues 12,
40; blindspot.safety.assess): the Monte-Carlo set (tuning / held-out halves) and the Euro NCAP
nominal grids (ncap.json). Predictors: warning.predictors (blindspot.safety.predict
.calibrated_predictors). Inputs: the tracker's tracks (headline), the oracle-association and
noisy visible-position references (driving_track), the true state from line of sight."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import json

import pandas as pd

from blindspot import experiment
from blindspot.cli import main_stage
from blindspot.io import write_json, write_parquet
from blindspot.safety.assess import assess, logged_metrics, summary_lines
from blindspot.safety.oracle import true_state_tracks
from blindspot.safety.outcome import body_boxes
from blindspot.safety.predict import calibrated_predictors
from blindspot.safety.risk import EgoShape
from blindspot.stage import StageResult
from blindspot.traj.lstm import LSTMPredictor


def run(cfg, ctx):
    w = experiment.warning(cfg)
    group, _ = experiment.scenarios(cfg)
    dt = float(experiment.driving_radar(cfg).frame_period_s)
    truth = pd.read_parquet(ctx.dep("truth.parquet"))
    tracks = {"tracker": pd.read_parquet(ctx.dep("tracks.parquet")),
              **{name: pd.read_parquet(ctx.dep(f"tracks_{name}.parquet"))
                 for name in ("oracle", "visible_truth")},
              "true_state": true_state_tracks(truth)}
    lstm = LSTMPredictor.load(ctx.dep("train/model.pt")).with_workers(experiment.jobs(cfg))
    preds = calibrated_predictors(
        w, experiment.predictors(cfg, lstm), json.loads(ctx.dep("models.json").read_text()),
        direct_path=ctx.dep("train_direct/model.pt"), paths=ctx.dep("paths.parquet"),
        val=ctx.dep("val.parquet"), window=experiment.dataset(cfg).window,
        calibration=experiment.calibration(cfg),
        cv_fit_points=experiment.evaluation(cfg).cv_fit_points, where=str(ctx.dep("models.json")),
        frame_periods_s=(dt, float(experiment.radar(cfg).frame_period_s)))
    res = assess(truth, json.loads(ctx.dep("scenes.json").read_text()), tracks, preds, w,
                 bodies=body_boxes(group), shape=EgoShape(group.ego.width_m, group.ego.length_m),
                 points=pd.read_parquet(ctx.dep("points.parquet"), columns=["scene", "frame",
                                                                             "source"]),
                 points_name=str(ctx.dep("points.parquet")), frame_period_s=dt,
                 figure_scene=group.figure_scene, draw_seed=group.monte_carlo.seed,
                 only={k: w.reference_predictors for k in ("oracle", "visible_truth",
                                                           "true_state")})
    for out, table in ((ctx.out("risk.parquet"), res.risk), (ctx.out("ncap_grid.parquet"),
                       res.grid), (ctx.out("scene_outcomes.parquet"), res.scenes),
                       (ctx.out("operating.parquet"), res.curves),
                       (ctx.out("timeline.parquet"), res.timeline)):
        write_parquet(out, table)
    write_json(ctx.out("safety.json"), res.metrics)
    write_json(ctx.out("ncap.json"), res.ncap)
    print("\n".join(summary_lines(res.metrics)))
    return StageResult(metrics=logged_metrics(res.metrics))

if __name__ == "__main__":
    main_stage(run, "safety")
