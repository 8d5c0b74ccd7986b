"""How well the chain localises the pedestrian: its points against the simulated truth."""

from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = ["localisation_errors"]


def localisation_errors(points: pd.DataFrame, truth: pd.DataFrame) -> dict[str, dict[str, float]]:
    """Per scene, the Euclidean error of the points against the true torso position.

    points : one row per frame with a point; columns ``scene``, ``frame``, ``x_m``, ``y_m`` (m).
    truth  : one row per simulated frame; columns ``scene``, ``frame``, ``x_m``, ``y_m`` (m) and
             ``occluded`` (bool, torso hidden behind the car).
    Returns ``{scene: {n_frames, n_points, n_hidden_frames, n_points_while_hidden,
    error_median_m, error_p90_m, error_mean_m}}`` in the order of ``truth``; the errors are NaN
    for a scene without any point. Points of frames absent from ``truth`` are ignored.
    """
    merged = points.merge(truth[["scene", "frame", "x_m", "y_m", "occluded"]],
                          on=["scene", "frame"], suffixes=("", "_true"))
    merged["error_m"] = np.hypot(merged.x_m - merged.x_m_true, merged.y_m - merged.y_m_true)
    out = {}
    for scene, frames in truth.groupby("scene", sort=False):
        m = merged[merged.scene == scene]
        e = m.error_m.to_numpy()
        out[scene] = {
            "n_frames": int(len(frames)),
            "n_points": int(len(m)),
            "n_hidden_frames": int(frames.occluded.sum()),
            "n_points_while_hidden": int(m.occluded.sum()),
            "error_median_m": float(np.median(e)) if len(e) else float("nan"),
            "error_p90_m": float(np.percentile(e, 90)) if len(e) else float("nan"),
            "error_mean_m": float(e.mean()) if len(e) else float("nan"),
        }
    return out
