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

from blindspot.arrays import check_same_shape, checked_array

DETECTION_COLUMNS = ("frame", "range_bin", "doppler_bin", "range_m", "velocity_mps", "power",
                     "snr_db", "angle_deg")
POINT_COLUMNS = ("frame", "time_s", "range_m", "velocity_mps", "angle_deg", "x_m", "y_m",
                 "snr_db", "n_detections", "extent_m")


class PointError(ValueError):
    """Per-detection arrays of the wrong shape or kind, NaN/inf where a value is needed, or a
    threshold that is not a finite non-negative (gap: positive) number."""


def _values(where: str, name: str, value: np.ndarray, *, nan_ok: bool = False,
            nonnegative: bool = False) -> np.ndarray:
    """A real float64 array; NaN only where ``nan_ok`` (a detection without an angle)."""
    a = checked_array(value, name, PointError, where=where, axes="an array (one value per detection)",
                      kind="real", finite=not nan_ok, nonnegative=nonnegative)
    a = a.astype(np.float64, copy=False)
    if nan_ok and np.isinf(a).any():
        raise PointError(f"{where}: {name} must be finite or NaN (no angle); found "
                         f"{int(np.isinf(a).sum())} infinite value(s)")
    return a


def _threshold(where: str, name: str, value: float, *, positive: bool = False) -> float:
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    if not ok or not np.isfinite(value) or value < 0 or (positive and value == 0):
        raise PointError(f"{where}: {name} must be a finite {'positive' if positive else 'non-negative'} "
                         f"number; found {value!r}")
    return float(value)


def to_cartesian(range_m: np.ndarray, angle_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 7: (x, y) = R (sin theta, cos theta).

    range_m: (...) metres, finite and >= 0; angle_deg: same shape, degrees from boresight
    (positive towards +x), NaN for a detection without an angle (its x, y are NaN).
    Returns (x_m, y_m), float64 of that shape. Raises PointError for other input."""
    r = _values("to_cartesian", "range_m", range_m, nonnegative=True)
    a = _values("to_cartesian", "angle_deg", angle_deg, nan_ok=True)
    check_same_shape(PointError, "to_cartesian", "the per-detection arrays", range_m=r, angle_deg=a)
    th = np.radians(a)
    return np.asarray(r * np.sin(th)), np.asarray(r * np.cos(th))


def moving(velocity_mps: np.ndarray, min_speed_mps: float) -> np.ndarray:
    """True for detections faster than the static-clutter threshold: velocity_mps (...) m/s,
    finite -> bool (...). Raises PointError for NaN/inf or a negative threshold."""
    v = _values("moving", "velocity_mps", velocity_mps)
    return np.abs(v) > _threshold("moving", "min_speed_mps", min_speed_mps)


def cluster_labels(x: np.ndarray, y: np.ndarray, gap_m: float) -> np.ndarray:
    """Single-linkage cluster label per point: connected components of 'closer than gap_m'.

    x, y: (N,) metres, finite -> (N,) int labels. Raises PointError for other input."""
    x = _values("cluster_labels", "x", x)
    y = _values("cluster_labels", "y", y)
    check_same_shape(PointError, "cluster_labels", "the per-detection arrays", x=x, y=y)
    gap_m = _threshold("cluster_labels", "gap_m", gap_m, positive=True)
    xy = np.stack([x.ravel(), y.ravel()], axis=1)
    if len(xy) <= 1:
        return np.zeros(len(xy), dtype=np.int64)
    d2 = ((xy[:, None, :] - xy[None, :, :]) ** 2).sum(axis=-1)
    graph = scipy.sparse.csr_matrix(d2 < gap_m ** 2)
    _, labels = scipy.sparse.csgraph.connected_components(graph, directed=False)
    return labels


POINT_FIELDS = POINT_COLUMNS[2:]  # the per-point values, without frame and time_s


def group_points(frame: np.ndarray, range_m: np.ndarray, velocity_mps: np.ndarray,
                 angle_deg: np.ndarray, snr_db: np.ndarray, min_speed_mps: float,
                 cluster_gap_m: float) -> dict[str, np.ndarray]:
    """The pedestrian's point of every frame, from the detections of many frames at once.

    Args:
        frame: (D,) frame index of each detection (any order).
        range_m, velocity_mps, angle_deg, snr_db: (D,) per detection; a NaN angle means no
            angle was estimated (outside the DOA budget): such detections are not grouped.
        min_speed_mps: static-clutter threshold (``|v| <=`` it is static).
        cluster_gap_m: single-linkage distance.

    Returns:
        dict of (P,) arrays, one entry per frame that has a point, sorted by frame: ``frame``
        and :data:`POINT_FIELDS` (``n_detections`` int64). Frames without a moving detection
        with a finite angle have no entry (nothing is invented).

    All frames are clustered in one connected-components pass over the graph of detection pairs
    of the same frame closer than ``cluster_gap_m``; per frame the cluster with the most
    detections (then the largest summed linear SNR, then the later one) is the pedestrian.

    Raises:
        PointError: arrays not (D,) of one length, a non-integer frame, NaN/inf in range,
            velocity or SNR (inf in angle), a negative speed threshold or a gap that is not
            positive.
    """
    where = "group_points"
    f_all = checked_array(frame, "frame", PointError, where=where, kind="integer", ndim=1,
                          axes="a frame index per detection (D,)")
    range_m, velocity_mps, snr_db = (_values(where, k, v) for k, v in (
        ("range_m", range_m), ("velocity_mps", velocity_mps), ("snr_db", snr_db)))
    angle_deg = _values(where, "angle_deg", angle_deg, nan_ok=True)
    check_same_shape(PointError, where, "the per-detection arrays", frame=f_all, range_m=range_m,
                     velocity_mps=velocity_mps, angle_deg=angle_deg, snr_db=snr_db)
    cluster_gap_m = _threshold(where, "cluster_gap_m", cluster_gap_m, positive=True)
    keep = moving(velocity_mps, min_speed_mps) & np.isfinite(angle_deg)
    order = np.argsort(f_all[keep], kind="stable")
    f = f_all[keep][order]
    r, v, a, s = (np.asarray(z, dtype=np.float64)[keep][order]
                  for z in (range_m, velocity_mps, angle_deg, snr_db))
    n = f.size
    if n == 0:
        out = {k: np.zeros(0) for k in POINT_FIELDS}
        out["frame"], out["n_detections"] = np.zeros(0, np.int64), np.zeros(0, np.int64)
        return out
    x, y = to_cartesian(r, a)
    w = 10 ** (s / 10)
    labels = _cluster_within_frames(f, x, y, cluster_gap_m)
    count = np.bincount(labels)
    weight = np.bincount(labels, weights=w)
    first = np.zeros(count.size, dtype=np.int64)
    first[labels[::-1]] = np.arange(n)[::-1]          # first detection of each cluster
    c_frame = f[first]
    by = np.lexsort((np.arange(count.size), weight, count, c_frame))
    last_of_frame = np.r_[c_frame[by][1:] != c_frame[by][:-1], True]
    best = by[last_of_frame]                          # one cluster per frame, frames ascending
    point_of = np.full(count.size, -1)
    point_of[best] = np.arange(best.size)             # cluster label -> point (frame order)
    sel = point_of[labels] >= 0
    xs, ys, vs, ss, wsel = x[sel], y[sel], v[sel], s[sel], w[sel]
    slot = point_of[labels[sel]]
    wsum = np.bincount(slot, weights=wsel, minlength=best.size)
    ws = wsel / wsum[slot]
    cx = np.bincount(slot, weights=ws * xs, minlength=best.size)
    cy = np.bincount(slot, weights=ws * ys, minlength=best.size)
    ext2 = np.full(best.size, -np.inf)
    np.maximum.at(ext2, slot, (xs - cx[slot]) ** 2 + (ys - cy[slot]) ** 2)
    snr = np.full(best.size, -np.inf)
    np.maximum.at(snr, slot, ss)
    return {
        "frame": c_frame[best].astype(np.int64),
        "range_m": np.hypot(cx, cy),
        "velocity_mps": np.bincount(slot, weights=ws * vs, minlength=best.size),
        "angle_deg": np.degrees(np.arctan2(cx, cy)),
        "x_m": cx, "y_m": cy,
        "snr_db": snr,
        "n_detections": np.bincount(slot, minlength=best.size).astype(np.int64),
        "extent_m": np.sqrt(ext2),
    }


def _cluster_within_frames(frame_sorted: np.ndarray, x: np.ndarray, y: np.ndarray,
                           gap_m: float) -> np.ndarray:
    """Single-linkage labels (D,) of detections sorted by frame: connected components of the
    graph 'same frame and closer than gap_m', all frames in one pass (labels never span two
    frames; within a frame they are numbered in detection order, as :func:`cluster_labels`)."""
    n = frame_sorted.size
    starts = np.flatnonzero(np.r_[True, frame_sorted[1:] != frame_sorted[:-1]])
    sizes = np.diff(np.r_[starts, n])
    block = np.repeat(np.arange(starts.size), sizes)          # block (frame) of each detection
    i = np.repeat(np.arange(n), sizes[block])                 # every pair (i, j) of one block
    offset = np.arange(i.size) - np.repeat(np.cumsum(sizes[block]) - sizes[block], sizes[block])
    j = starts[block[i]] + offset
    d2 = (x[i] - x[j]) ** 2 + (y[i] - y[j]) ** 2
    near = d2 < gap_m ** 2
    graph = scipy.sparse.csr_matrix((np.ones(int(near.sum()), dtype=bool), (i[near], j[near])),
                                    shape=(n, n))
    _, labels = scipy.sparse.csgraph.connected_components(graph, directed=False)
    return labels


def group_point(range_m: np.ndarray, velocity_mps: np.ndarray, angle_deg: np.ndarray,
                snr_db: np.ndarray, min_speed_mps: float, cluster_gap_m: float) -> dict | None:
    """The pedestrian's point from one frame's detections (arrays (n,)), or None when no moving
    detection with a finite angle exists. Keys: POINT_COLUMNS without frame and time_s.
    (:func:`group_points` for one frame.)"""
    pts = group_points(np.zeros(len(range_m), dtype=np.int64), range_m, velocity_mps, angle_deg,
                       snr_db, min_speed_mps, cluster_gap_m)
    if pts["frame"].size == 0:
        return None
    return {k: (int(pts[k][0]) if k == "n_detections" else float(pts[k][0]))
            for k in POINT_FIELDS}


def pedestrian_point(detections: pd.DataFrame, min_speed_mps: float,
                     cluster_gap_m: float) -> dict | None:
    """:func:`group_point` on one frame's detection table (``DETECTION_COLUMNS``)."""
    return group_point(detections["range_m"].to_numpy(), detections["velocity_mps"].to_numpy(),
                       detections["angle_deg"].to_numpy(), detections["snr_db"].to_numpy(),
                       min_speed_mps, cluster_gap_m)


def frame_points(detections: pd.DataFrame, times_s: dict | pd.Series | np.ndarray | None,
                 min_speed_mps: float, cluster_gap_m: float) -> pd.DataFrame:
    """One pedestrian point per frame that has one (``POINT_COLUMNS``), all frames grouped in
    one pass (:func:`group_points`); ``times_s`` maps frame index -> time (array indexed by
    frame, dict or Series), None gives NaN times."""
    if len(detections) == 0:
        return pd.DataFrame(columns=list(POINT_COLUMNS)).astype(
            {"frame": np.int64, "n_detections": np.int64})
    pts = group_points(detections["frame"].to_numpy(), detections["range_m"].to_numpy(),
                       detections["velocity_mps"].to_numpy(), detections["angle_deg"].to_numpy(),
                       detections["snr_db"].to_numpy(), min_speed_mps, cluster_gap_m)
    if times_s is None:
        t = np.full(pts["frame"].size, np.nan)
    elif isinstance(times_s, dict | pd.Series):
        t = pd.Series(times_s).loc[pts["frame"]].to_numpy(np.float64)
    else:
        t = np.asarray(times_s, dtype=np.float64)[pts["frame"]]
    out = pd.DataFrame({"frame": pts["frame"], "time_s": t,
                        **{k: pts[k] for k in POINT_FIELDS}}, columns=list(POINT_COLUMNS))
    return out.astype({"frame": np.int64, "n_detections": np.int64})
