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
  detections, then the largest summed SNR) is taken as the pedestrian. A frame without a moving
  detection with an angle gives no point: nothing is ever interpolated or invented here.
* The body's point from its cluster (``estimator``):

  - ``"median"``: the SNR-weighted median of the cluster's ranges, and separately of its angles
    (and velocities), turned into x, y by eq. 7. A walking body is an extended target: the
    torso (-5.5 dBsm of the body's -3.1 dBsm) moves at the bulk velocity and the limbs swing
    around it (Chen, *The Micro-Doppler Effect in Radar*, 2nd ed. 2019, ch. 5, Boulic walking
    model), so the limbs' micro-Doppler splits the body into detections in several Doppler
    cells, each at its own range and angle. The weighted median is the robust (L1) location
    estimate of those scattering centres (Huber & Ronchetti, *Robust Statistics*, 2009): one
    limb's detection cannot pull it as it pulls the centroid, and it works in the polar
    coordinates where the chain's errors are independent (range from the beat frequency,
    angle from the array). With two detections it is the stronger one.
  - ``"strongest"``: the cluster's strongest detection (largest SNR): its range, angle, x, y and
    velocity (the torso when it is the strongest cell).
  - ``"centroid"``: the SNR-weighted centroid (weights = linear SNR) of the cluster's x, y; range
    and angle those of the centroid, velocity SNR-weighted (the paper's step: each limb pulls
    the point towards itself by its share of the SNR).

  ``extent_m`` is the largest distance of a cluster detection from the point either way.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from blindspot.arrays import check_same_shape, checked_array
from blindspot.dsp.config import POINT_ESTIMATORS

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
    i, j = np.nonzero(d2 < gap_m ** 2)
    return connected_labels(len(xy), i, j)


POINT_FIELDS = POINT_COLUMNS[2:]  # the per-point values, without frame and time_s


ESTIMATORS = POINT_ESTIMATORS  # the choices of detect.point_estimator


def group_points(frame: np.ndarray, range_m: np.ndarray, velocity_mps: np.ndarray,
                 angle_deg: np.ndarray, snr_db: np.ndarray, min_speed_mps: float,
                 cluster_gap_m: float, *, estimator: str = "centroid") -> dict[str, np.ndarray]:
    """The pedestrian's point of every frame, from the detections of many frames at once.

    Args:
        frame: (D,) frame index of each detection (any order).
        range_m, velocity_mps, angle_deg, snr_db: (D,) per detection; a NaN angle means no
            angle was estimated (outside the DOA budget): such detections are not grouped.
        min_speed_mps: static-clutter threshold (``|v| <=`` it is static).
        cluster_gap_m: single-linkage distance.
        estimator: ``"strongest"`` or ``"centroid"`` (module docstring): the point of the
            chosen cluster.

    Returns:
        dict of (P,) arrays, one entry per frame that has a point, sorted by frame: ``frame``
        and :data:`POINT_FIELDS` (``n_detections`` int64). Frames without a moving detection
        with a finite angle have no entry (nothing is invented).

    All frames are clustered in one connected-components pass over the graph of detection pairs
    of the same frame closer than ``cluster_gap_m``; per frame the cluster with the most
    detections (then the largest summed linear SNR, then the later one) is the pedestrian.

    Raises:
        PointError: arrays not (D,) of one length, a non-integer frame, NaN/inf in range,
            velocity or SNR (inf in angle), a negative speed threshold, a gap that is not
            positive or an unknown estimator.
    """
    where = "group_points"
    if estimator not in ESTIMATORS:
        raise PointError(f"{where}: estimator must be one of {ESTIMATORS}; found {estimator!r}")
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
    fields = cluster_points(point_of[labels[sel]], x[sel], y[sel], v[sel], s[sel], best.size,
                            estimator)
    return {"frame": c_frame[best].astype(np.int64), **fields}


def cluster_points(slot: np.ndarray, x: np.ndarray, y: np.ndarray, v: np.ndarray,
                   snr_db: np.ndarray, n_points: int, estimator: str) -> dict[str, np.ndarray]:
    """The point of each of ``n_points`` groups of detections (the module docstring's
    estimators).

    slot: (N,) group of each detection in [0, n_points), every group non-empty; x, y (m),
    v (m/s), snr_db: (N,) finite. Returns :data:`POINT_FIELDS` as (n_points,) arrays
    (``n_detections`` int64)."""
    w = 10 ** (snr_db / 10)
    wsum = np.bincount(slot, weights=w, minlength=n_points)
    ws = w / wsum[slot]
    if estimator == "centroid":
        cx = np.bincount(slot, weights=ws * x, minlength=n_points)
        cy = np.bincount(slot, weights=ws * y, minlength=n_points)
        cv = np.bincount(slot, weights=ws * v, minlength=n_points)
    elif estimator == "strongest":  # largest SNR (the first of equals)
        by_snr = np.lexsort((np.arange(slot.size)[::-1], snr_db, slot))
        top = by_snr[np.r_[slot[by_snr][1:] != slot[by_snr][:-1], True]]
        cx, cy, cv = x[top], y[top], v[top]
    else:  # median: SNR-weighted median of range, of angle and of velocity, each on its own
        r, a = np.hypot(x, y), np.degrees(np.arctan2(x, y))
        rm, am, cv = (weighted_medians(slot, z, w, n_points) for z in (r, a, v))
        cx, cy = to_cartesian(rm, am)
    ext2 = np.full(n_points, -np.inf)
    np.maximum.at(ext2, slot, (x - cx[slot]) ** 2 + (y - cy[slot]) ** 2)
    snr = np.full(n_points, -np.inf)
    np.maximum.at(snr, slot, snr_db)
    return {
        "range_m": np.hypot(cx, cy),
        "velocity_mps": cv,
        "angle_deg": np.degrees(np.arctan2(cx, cy)),
        "x_m": cx, "y_m": cy,
        "snr_db": snr,
        "n_detections": np.bincount(slot, minlength=n_points).astype(np.int64),
        "extent_m": np.sqrt(ext2),
    }


def weighted_medians(group: np.ndarray, values: np.ndarray, weights: np.ndarray,
                     n_groups: int) -> np.ndarray:
    """Weighted median of each group, all groups at once.

    group: (N,) int in [0, n_groups), every group non-empty; values, weights: (N,) finite,
    weights > 0. Returns (n_groups,): per group the smallest value whose cumulative weight (in
    increasing order of value) reaches half the group's total weight, the minimiser of
    sum_i w_i |v_i - m| (the lower one when two values tie for it)."""
    order = np.lexsort((values, group))
    g, v, w = group[order], values[order], weights[order]
    cum = np.cumsum(w)
    total = np.bincount(g, weights=w, minlength=n_groups)
    before = np.concatenate([[0.0], np.cumsum(total)[:-1]])          # weight of earlier groups
    # the tolerance keeps an exact half (two equal weights) from being lost to rounding
    reached = cum - before[g] >= 0.5 * total[g] * (1.0 - 1e-12)
    first = np.full(n_groups, v.size)
    np.minimum.at(first, g, np.where(reached, np.arange(v.size), v.size))
    return v[first]


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
    return connected_labels(n, i[near], j[near])


def connected_labels(n: int, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """Connected components of the undirected graph on nodes 0..n-1 with edges (i[e], j[e]):
    labels (n,) int64 numbered in the order of each component's smallest node (the numbering
    of ``scipy.sparse.csgraph.connected_components``, tested equal).

    Min-label propagation with pointer jumping (Shiloach & Vishkin 1982): every node takes the
    smallest label among its neighbours, then the label of its label; labels only decrease, and
    the number of rounds grows with the logarithm of the components' diameter (one or two for
    a frame's few detections). Each round is a few whole-array operations, so it costs less
    than building scipy's sparse matrix for the tens of detections of a batch."""
    lab = np.arange(n)
    while True:
        new = lab.copy()
        np.minimum.at(new, i, lab[j])
        np.minimum.at(new, j, lab[i])
        new = new[new]  # pointer jumping: a label's own label
        if np.array_equal(new, lab):
            break
        lab = new
    return np.unique(lab, return_inverse=True)[1].astype(np.int64)


def group_point(range_m: np.ndarray, velocity_mps: np.ndarray, angle_deg: np.ndarray,
                snr_db: np.ndarray, min_speed_mps: float, cluster_gap_m: float, *,
                estimator: str = "centroid") -> dict | None:
    """The pedestrian's point from one frame's detections (arrays (n,)), or None when no moving
    detection with a finite angle exists. Keys: POINT_COLUMNS without frame and time_s.
    (:func:`group_points` for one frame.)"""
    pts = group_points(np.zeros(len(range_m), dtype=np.int64), range_m, velocity_mps, angle_deg,
                       snr_db, min_speed_mps, cluster_gap_m, estimator=estimator)
    if pts["frame"].size == 0:
        return None
    return {k: (int(pts[k][0]) if k == "n_detections" else float(pts[k][0]))
            for k in POINT_FIELDS}


def pedestrian_point(detections: pd.DataFrame, min_speed_mps: float,
                     cluster_gap_m: float, *, estimator: str = "centroid") -> dict | None:
    """:func:`group_point` on one frame's detection table (``DETECTION_COLUMNS``)."""
    return group_point(detections["range_m"].to_numpy(), detections["velocity_mps"].to_numpy(),
                       detections["angle_deg"].to_numpy(), detections["snr_db"].to_numpy(),
                       min_speed_mps, cluster_gap_m, estimator=estimator)


def frame_points(detections: pd.DataFrame, times_s: dict | pd.Series | np.ndarray | None,
                 min_speed_mps: float, cluster_gap_m: float, *,
                 estimator: str = "centroid") -> pd.DataFrame:
    """One pedestrian point per frame that has one (``POINT_COLUMNS``), all frames grouped in
    one pass (:func:`group_points` with ``estimator``); ``times_s`` maps frame index -> time
    (array indexed by frame, dict or Series), None gives NaN times."""
    if len(detections) == 0:
        return pd.DataFrame(columns=list(POINT_COLUMNS)).astype(
            {"frame": np.int64, "n_detections": np.int64})
    pts = group_points(detections["frame"].to_numpy(), detections["range_m"].to_numpy(),
                       detections["velocity_mps"].to_numpy(), detections["angle_deg"].to_numpy(),
                       detections["snr_db"].to_numpy(), min_speed_mps, cluster_gap_m,
                       estimator=estimator)
    if times_s is None:
        t = np.full(pts["frame"].size, np.nan)
    elif isinstance(times_s, dict | pd.Series):
        t = pd.Series(times_s).loc[pts["frame"]].to_numpy(np.float64)
    else:
        t = np.asarray(times_s, dtype=np.float64)[pts["frame"]]
    out = pd.DataFrame({"frame": pts["frame"], "time_s": t,
                        **{k: pts[k] for k in POINT_FIELDS}}, columns=list(POINT_COLUMNS))
    return out.astype({"frame": np.int64, "n_detections": np.int64})
