"""Scoring a predicted future path: the paper's metric and the time-aligned errors beside it.

For each scene and method the prediction ``pred`` (H, 2) covers the frames after the prediction
start. It is scored against
* the simulated truth of those frames, time-aligned (ADE/FDE at fixed horizons, error per step);
* the paper's metric (each predicted point's distance to the nearest point of the actual path),
  once against the truth path and once against the radar track of the same walk recorded without
  the car, which is what the paper could measure.
"""

from __future__ import annotations

import numpy as np

from blindspot.traj.metrics import displacement, path_error


def errors_at_horizons(err_per_step: np.ndarray, dt_s: float,
                       horizons_s: tuple[float, ...]) -> dict[str, float]:
    """ADE and FDE up to each horizon: ``ade_<h>s`` = mean error over steps 1..n, ``fde_<h>s`` the
    error at step n, n = round(h / dt). Horizons longer than the prediction give NaN."""
    out: dict[str, float] = {}
    for h in horizons_s:
        n = int(round(h / dt_s))
        key = f"{h:g}s"
        if 1 <= n <= len(err_per_step):
            out[f"ade_{key}"] = float(np.nanmean(err_per_step[:n]))
            out[f"fde_{key}"] = float(err_per_step[n - 1])
        else:
            out[f"ade_{key}"] = out[f"fde_{key}"] = float("nan")
    return out


def score_prediction(pred: np.ndarray, truth: np.ndarray, radar_track: np.ndarray | None,
                     dt_s: float, horizons_s: tuple[float, ...] = (0.5, 1.0, 2.0)) -> dict:
    """All errors of one predicted path.

    pred : (H, 2) predicted positions; truth : (H, 2) true positions at the same frames;
    radar_track : (M, 2) the radar's points of the same walk without the car (NaN rows allowed),
    or None. Returns a flat dict of floats plus ``per_step_m`` (H,) and ``path_error_m`` (H,).
    """
    per_step = displacement(pred, truth)
    to_truth = path_error(pred, truth)
    out = {
        "path_error_mean_m": float(np.nanmean(to_truth)),
        "path_error_first_m": float(to_truth[0]),
        "ade_m": float(np.nanmean(per_step)),
        "fde_m": float(per_step[-1]),
        "horizon_steps": int(len(pred)),
        **errors_at_horizons(per_step, dt_s, horizons_s),
        "per_step_m": per_step,
        "path_error_m": to_truth,
    }
    if radar_track is not None:
        to_radar = path_error(pred, radar_track)
        out["path_error_radar_mean_m"] = float(np.nanmean(to_radar))
        out["path_error_radar_m"] = to_radar
    return out
