"""The paper's scenes predicted from the track seen so far (the predict stage's work, Fig. 9).

:func:`predict_scenes`: from the prediction start on, every method predicts the rest of each car
scene (or a horizon) from the points seen before the start, their gaps filled without
look-ahead; each method's calibrated predictive distribution (the calibration stage's records)
gives the covariance of every predicted point.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from blindspot.traj.calibration import from_record
from blindspot.traj.distribution import DistributionError
from blindspot.traj.forecast import forecast_distributions, forecast_track
from blindspot.traj.interpolation import scene_track

__all__ = ["once_per_history", "predict_scenes"]


def once_per_history(fill):
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


def predict_scenes(points: pd.DataFrame, scenes: dict, methods: dict, records: dict, fill, *,
                   start_s: float, horizon_frames: int | None, dt: float) -> pd.DataFrame:
    """One row per scene (those with the car), method and predicted frame: x_m, y_m and the
    covariance (cov_*_m2; NaN where the method has no calibrated record or more steps than it
    was calibrated for). ``points``: the localise stage's; ``fill``: the gap filling of a
    history (see :func:`once_per_history`); ``start_s``: eval.prediction_start_s."""
    rows = []
    for name, sc in scenes.items():
        if not sc.with_car:
            continue
        track = scene_track(points, name, sc.n_frames)
        start = int(round(float(start_s) / dt))
        horizon = horizon_frames
        end = sc.n_frames if horizon is None else min(sc.n_frames, start + int(horizon))
        if not 0 < start < sc.n_frames:
            raise ValueError(f"config key 'eval.prediction_start_s' = {start_s}: "
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
    return pd.concat(rows, ignore_index=True)
