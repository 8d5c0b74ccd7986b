"""From detections with angles to Cartesian points: the paper's eq. 7, static clutter removal
and one pedestrian point per frame.

* Position (eq. 7): ``x = R sin(theta)``, ``y = R cos(theta)``; radar at the origin, boresight +y,
  theta positive towards +x.
* Static clutter (the parked car, the ground) is removed by radial speed: detections with
  ``|v| <= min_speed_mps`` are dropped. A static target's energy stays within the zero-Doppler
  bin and its two Hann-window neighbours (a periodic Hann window has exactly three non-zero DFT
  coefficients), so a threshold between 1 and 2 Doppler bins removes it.
* Grouping: the moving detections of one frame are clustered by single linkage in the x-y plane
  (two detections closer than ``cluster_gap_m`` belong together); the largest cluster (most
  detections, then the largest summed SNR) is taken as the pedestrian, and its point is the
  SNR-weighted centroid (weights = linear SNR) of its detections' x, y; range, angle and velocity
  are those of the centroid (velocity SNR-weighted). A frame without a moving detection with an
  angle gives no point: nothing is ever interpolated or invented here.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import scipy.sparse
import scipy.sparse.csgraph

DETECTION_COLUMNS = ("frame", "range_bin", "doppler_bin", "range_m", "velocity_mps", "power",
                     "snr_db", "angle_deg")
POINT_COLUMNS = ("frame", "time_s", "range_m", "velocity_mps", "angle_deg", "x_m", "y_m",
                 "snr_db", "n_detections", "extent_m")


def to_cartesian(range_m: np.ndarray, angle_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 7: (x, y) = R (sin theta, cos theta)."""
    th = np.radians(np.asarray(angle_deg, dtype=np.float64))
    r = np.asarray(range_m, dtype=np.float64)
    return r * np.sin(th), r * np.cos(th)


def moving(velocity_mps: np.ndarray, min_speed_mps: float) -> np.ndarray:
    """True for detections faster than the static-clutter threshold."""
    return np.abs(np.asarray(velocity_mps)) > min_speed_mps


def cluster_labels(x: np.ndarray, y: np.ndarray, gap_m: float) -> np.ndarray:
    """Single-linkage cluster label per point: connected components of 'closer than gap_m'."""
    xy = np.stack([np.asarray(x, float), np.asarray(y, float)], axis=1)
    if len(xy) <= 1:
        return np.zeros(len(xy), dtype=np.int64)
    d2 = ((xy[:, None, :] - xy[None, :, :]) ** 2).sum(axis=-1)
    graph = scipy.sparse.csr_matrix(d2 < gap_m ** 2)
    _, labels = scipy.sparse.csgraph.connected_components(graph, directed=False)
    return labels


def group_point(range_m: np.ndarray, velocity_mps: np.ndarray, angle_deg: np.ndarray,
                snr_db: np.ndarray, min_speed_mps: float, cluster_gap_m: float) -> dict | None:
    """The pedestrian's point from one frame's detections (arrays (n,)), or None when no moving
    detection with a finite angle exists. Keys: POINT_COLUMNS without frame and time_s."""
    keep = moving(velocity_mps, min_speed_mps) & np.isfinite(angle_deg)
    if not keep.any():
        return None
    r, v, a, s = (np.asarray(z, dtype=np.float64)[keep]
                  for z in (range_m, velocity_mps, angle_deg, snr_db))
    x, y = to_cartesian(r, a)
    w = 10 ** (s / 10)
    labels = cluster_labels(x, y, cluster_gap_m)
    count = np.bincount(labels)
    weight = np.bincount(labels, weights=w)
    best = np.lexsort((weight, count))[-1]  # most detections, then largest summed SNR
    sel = labels == best
    ws = w[sel] / w[sel].sum()
    cx, cy = float(ws @ x[sel]), float(ws @ y[sel])
    return {
        "range_m": float(np.hypot(cx, cy)),
        "velocity_mps": float(ws @ v[sel]),
        "angle_deg": float(np.degrees(np.arctan2(cx, cy))),
        "x_m": cx, "y_m": cy,
        "snr_db": float(s[sel].max()),
        "n_detections": int(sel.sum()),
        "extent_m": float(np.sqrt(((x[sel] - cx) ** 2 + (y[sel] - cy) ** 2).max())),
    }


def pedestrian_point(detections: pd.DataFrame, min_speed_mps: float,
                     cluster_gap_m: float) -> dict | None:
    """:func:`group_point` on one frame's detection table (``DETECTION_COLUMNS``)."""
    return group_point(detections["range_m"].to_numpy(), detections["velocity_mps"].to_numpy(),
                       detections["angle_deg"].to_numpy(), detections["snr_db"].to_numpy(),
                       min_speed_mps, cluster_gap_m)


def frame_points(detections: pd.DataFrame, times_s: dict | pd.Series | np.ndarray | None,
                 min_speed_mps: float, cluster_gap_m: float) -> pd.DataFrame:
    """One pedestrian point per frame that has one (``POINT_COLUMNS``); ``times_s`` maps frame
    index -> time (array indexed by frame, dict or Series), None gives NaN times."""
    rows = []
    for frame, group in detections.groupby("frame", sort=True):  # one step per frame
        pt = pedestrian_point(group, min_speed_mps, cluster_gap_m)
        if pt is None:
            continue
        t = np.nan if times_s is None else float(np.asarray(times_s[frame]))
        rows.append({"frame": int(frame), "time_s": t, **pt})
    out = pd.DataFrame(rows, columns=list(POINT_COLUMNS))
    return out.astype({"frame": np.int64, "n_detections": np.int64})
