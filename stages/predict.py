"""predict: the future path of each car scene from the track seen so far (paper Fig. 9).

From eval.prediction_start_s on, every method in eval.prediction_methods (the LSTM rolled out
autoregressively, constant velocity, Kalman) predicts the rest of the scene (or
eval.horizon_frames) from the points seen before the start, their gaps filled by
eval.prediction_input (the paper: its own forward LSTM interpolation) without look-ahead.
Each method's predictive distribution, calibrated on validation paths by the calibration stage
(data/calibration/models.json), gives the covariance of every predicted point (cov_*_m2 columns).
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import json
from functools import partial

import numpy as np
import pandas as pd

from blindspot.radar.config import RadarConfig
from blindspot.radar.scene import load_scenes
from blindspot.traj.baselines import kalman_baseline, prediction_methods
from blindspot.traj.config import EvalConfig
from blindspot.traj.interpolation import scene_track
from blindspot.typed_config import jobs
from blindspot.cli import main_stage
from blindspot.io import write_parquet
from blindspot.stage import StageResult
from blindspot.traj.calibration import from_record
from blindspot.traj.distribution import DistributionError
from blindspot.traj.forecast import forecast_distributions, forecast_track
from blindspot.traj.interpolation import interpolate
from blindspot.traj.lstm import LSTMPredictor


def _once_per_history(fill):
    """``fill`` computed once per distinct history. Every method of a scene, for its path and for
    its distribution, fills the same history (the points before the start), and the LSTM
    interpolation is deterministic: without this the stage rolled the LSTM over the same gaps six
    times per scene (5/6 of its time). Returns a copy (the caller writes into it)."""
    done = {}

    def filled(past):
        past = np.ascontiguousarray(past)
        key = (past.shape, past.dtype.str, past.tobytes())
        if key not in done:
            done[key] = np.asarray(fill(past.copy()))
        return done[key].copy()

    return filled


def run(cfg, ctx):
    points = pd.read_parquet(ctx.dep("points.parquet"))
    lstm = LSTMPredictor.load(ctx.dep("model.pt")).with_workers(jobs(cfg))
    dt = float(cfg.radar.frame_period_s)
    fill = _once_per_history(partial(interpolate, method=str(cfg.eval.prediction_input),
                                     predictor=lstm, smoother=kalman_baseline(EvalConfig.from_cfg(cfg), RadarConfig.from_cfg(cfg).frame_period_s).smooth))
    methods = prediction_methods(EvalConfig.from_cfg(cfg), RadarConfig.from_cfg(cfg).frame_period_s, lstm)
    records = json.loads(ctx.dep("models.json").read_text())   # the calibration stage's fits
    rows = []
    for name, sc in load_scenes(cfg.scene).items():
        if not sc.with_car:
            continue
        track = scene_track(points, name, sc.n_frames)
        start = int(round(float(cfg.eval.prediction_start_s) / dt))
        horizon = cfg.eval.horizon_frames
        end = sc.n_frames if horizon is None else min(sc.n_frames, start + int(horizon))
        if not 0 < start < sc.n_frames:
            raise ValueError(f"config key 'eval.prediction_start_s' = {cfg.eval.prediction_start_s}: "
                             f"expected a time inside scene {name!r} (0..{sc.n_frames * dt:g} s)")
        for method, predictor in methods.items():
            pred = forecast_track(track, start, predictor, fill=fill, end=end)
            frames = np.arange(start, end)
            cov = np.full((len(frames), 2, 2), np.nan)
            if method in records:           # the calibrated predictive distribution, same input
                try:
                    cov = forecast_distributions(
                        track[None], np.array([start]), from_record(records[method], predictor,
                                                                    method),
                        fill=lambda b: fill(b[0])[None], end=np.array([end])).cov[0]
                except DistributionError as err:   # more steps than calibrated: no ellipse
                    print(f"predict {name} {method}: no distribution ({err})")
            rows.append(pd.DataFrame({
                "scene": name, "method": method, "step": np.arange(1, len(frames) + 1),
                "frame": frames, "time_s": frames * dt, "x_m": pred[:, 0], "y_m": pred[:, 1],
                "cov_xx_m2": cov[:, 0, 0], "cov_xy_m2": cov[:, 0, 1], "cov_yy_m2": cov[:, 1, 1],
            }))
    predictions = pd.concat(rows, ignore_index=True)
    write_parquet(ctx.out("predictions.parquet"), predictions)
    print(f"predict: {predictions.scene.nunique()} scenes x {predictions.method.nunique()} methods, "
          f"{predictions.step.max()} steps each")
    return StageResult(metrics={"n_predicted_points": len(predictions)})


if __name__ == "__main__":
    main_stage(run, "predict")
