"""safety: collision risk, warning, AEB and the Euro NCAP-style outcome of the Monte-Carlo
driving scenes (issue 12; blindspot.safety.assess).

Predictors: none (blindspot.traj.stationary, its error model calibrated here on the calibration
stage's validation pairs with the same settings), constant velocity, Kalman, the scene LSTM and
the direct multi-step LSTM (lstm_direct, the train_direct stage's; their calibrated
distributions from data/calibration/models.json; both LSTMs' short histories completed as
warning.lstm_history says). Inputs (driving_track stage): the tracker's tracks (the
headline), the oracle-association and visible-truth reference tracks.
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import json

import numpy as np
import pandas as pd

from blindspot import experiment
from blindspot.cli import main_stage
from blindspot.io import write_json, write_parquet
from blindspot.safety.assess import assess
from blindspot.safety.outcome import body_boxes
from blindspot.safety.predict import TrackState, with_backfill
from blindspot.safety.risk import EgoShape
from blindspot.stage import StageResult
from blindspot.traj.calibration import calibrate, from_record, path_pairs
from blindspot.traj.direct import NAME as DIRECT
from blindspot.traj.lstm import LSTMPredictor
from blindspot.traj.paths import table_to_arrays
from blindspot.traj.seq2seq import Seq2SeqEnsemble
from blindspot.traj.stationary import Stationary
from blindspot.traj.windows import WindowSet


def _predictors(cfg, ctx, w):
    """name -> calibrated probabilistic predictor (module docstring)."""
    import torch

    torch.set_num_threads(1)
    c = experiment.calibration(cfg)
    lstm = LSTMPredictor.load(ctx.dep("train/model.pt")).with_workers(experiment.jobs(cfg))
    records = json.loads(ctx.dep("models.json").read_text())
    base = experiment.predictors(cfg, lstm)          # a new dict: the direct model joins it
    if DIRECT in w.predictors:
        base[DIRECT] = Seq2SeqEnsemble.load(ctx.dep("train_direct/model.pt"))
    out = {}
    for name in w.predictors:
        if name == "track_state":                  # the tracker's own state, Kalman-calibrated
            out[name] = TrackState(from_record(records["kalman"], base["kalman"], "kalman"))
            continue
        if name == "none":
            truth, measured, _ = table_to_arrays(pd.read_parquet(ctx.dep("paths.parquet")))
            val = np.unique(WindowSet.load(ctx.dep("val.parquet")).path_id)
            hist, fut = path_pairs(measured[val], truth[val], experiment.dataset(cfg).window,
                                   c.horizon_frames, c.stride)
            out[name] = calibrate({"none": Stationary()}, hist, fut, scale_method=c.scale_method,
                                  scale_level=c.scale_level,
                                  cv_fit_points=experiment.evaluation(cfg).cv_fit_points)["none"]
            continue
        if name not in records or name not in base:
            raise ValueError(f"config key 'warning.predictors' lists {name!r}: no calibrated "
                             f"distribution in {ctx.dep('models.json')} ({sorted(records)})")
        p = from_record(records[name], base[name], name)
        out[name] = with_backfill(p, base[name], w.lstm_history)
    return out


def run(cfg, ctx):
    w = experiment.warning(cfg)
    group, _ = experiment.scenarios(cfg)
    dt = float(experiment.driving_radar(cfg).frame_period_s)
    if abs(dt - float(experiment.radar(cfg).frame_period_s)) > 1e-9:
        raise ValueError(f"config keys 'driving_radar.frame_period_s' = {dt} and "
                         f"'radar.frame_period_s' = {cfg.radar.frame_period_s}: the predictors "
                         "were calibrated at the paper radar's frame period; expected equal")
    truth = pd.read_parquet(ctx.dep("truth.parquet"))
    meta = json.loads(ctx.dep("scenes.json").read_text())
    tracks = {"tracker": pd.read_parquet(ctx.dep("tracks.parquet")),
              **{name: pd.read_parquet(ctx.dep(f"tracks_{name}.parquet"))
                 for name in ("oracle", "visible_truth")}}
    # the points' truth labels say only when the lead pedestrian was first seen (scene_info)
    points = pd.read_parquet(ctx.dep("points.parquet"), columns=["scene", "frame", "source"])
    bodies = body_boxes(group)
    res = assess(truth, meta, tracks, _predictors(cfg, ctx, w), w, bodies=bodies, points=points,
                 points_name=str(ctx.dep("points.parquet")),
                 shape=EgoShape(group.ego.width_m, group.ego.length_m), frame_period_s=dt,
                 figure_scene=group.figure_scene,
                 only={"visible_truth": w.reference_predictors,
                       "oracle": w.reference_predictors})
    write_parquet(ctx.out("risk.parquet"), res.risk)
    write_parquet(ctx.out("scene_outcomes.parquet"), res.scenes)
    write_parquet(ctx.out("operating.parquet"), res.curves)
    write_parquet(ctx.out("ncap_grid.parquet"), res.grid)
    write_parquet(ctx.out("timeline.parquet"), res.timeline)
    write_json(ctx.out("safety.json"), res.metrics)
    logged = {}
    for name, m in res.metrics.items():
        logged[name] = {"by_input": {inp: {k: v[k] for k in ("avoided_rate",
                                                             "avoided_after_visible_rate",
                                                             "false_activation_rate")}
                                     for inp, v in m["by_input"].items()},
                        "false_activation_rate": m["false_activation_rate"],
                        "avoided_rate": m["avoided_rate"],
                        "avoided_after_visible_rate": m["avoided_after_visible_rate"],
                        "by_speed_kmh": {k: {kk: v[kk] for kk in ("avoided_rate",
                                                                   "avoided_after_visible_rate",
                                                                   "impact_speed_kmh_mean",
                                                                   "lead_time_s_median")}
                                         for k, v in m["by_speed_kmh"].items()}}
        print(f"safety {name}: avoided {m['avoided_rate']} ("
              f"{m['avoided_after_visible_rate']} with the AEB requested after the lead "
              f"pedestrian was visible), false activations "
              f"{m['false_activation_rate']}; impact km/h by speed "
              + ", ".join(f"{k}: {v['impact_speed_kmh_mean']:.1f}"
                          for k, v in m["by_speed_kmh"].items()))
    return StageResult(metrics=_numeric(logged))


def _numeric(d):
    """Drop None leaves (MLflow logs numbers only)."""
    if isinstance(d, dict):
        return {k: _numeric(v) for k, v in d.items() if v is not None}
    return d


if __name__ == "__main__":
    main_stage(run, "safety")
