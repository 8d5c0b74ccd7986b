"""Points of a target crossing the line of sight: zero Doppler is not zero speed.

The static-clutter filter of the points step (:func:`blindspot.dsp.points.moving`) drops every
detection with ``|v_r| <= detect.min_speed_mps``. A pedestrian walking across the radar's line
of sight has ``v_r = v . u`` near zero there (u the unit vector to the target), and so do the
swinging limbs (they swing along the walking direction, across the line of sight): on the
paper's straight walk the points break off for 1.4 s (frames 58-71) while the pedestrian is in
plain view, just because its radial speed is below 0.11 m/s.

A moving target with no radial speed still moves in range and angle. The bridge (``bridge``
config group, :class:`~blindspot.dsp.config.BridgeConfig`) uses the track of the points around
the gap, as a tracker's gating does (Blackman & Popoli, *Design and Analysis of Modern Tracking
Systems*, 1999, ch. 6: a measurement is associated with a track when it falls within a gate
around the track's predicted position):

1. For a frame without a point, the constant-velocity line fitted (least squares, x(t) and
   y(t)) to the points of the last ``history_s`` before it predicts the position p and the
   velocity v; at most ``max_gap_s`` after the last point, and from at least two points.
2. Only where the Doppler filter can have hidden the target: the predicted radial speed
   ``|v . p / |p||`` is at most ``min_speed_mps + margin_mps``. Elsewhere the target's own
   Doppler is visible, and a zero-Doppler detection near it is clutter.
3. The frame's zero-Doppler detections (with an angle) within ``gate_m`` of p are the target's
   detections, and its point comes from them by the points step's own estimator
   (:func:`blindspot.dsp.points.cluster_points`). The point is measured, never the prediction:
   a frame without a detection in the gate stays without a point.

Predictions extrapolate from the moving points only (a bridged point never feeds another
prediction), so every frame is decided at once, without a loop over frames.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from blindspot.dsp.config import BridgeConfig
from blindspot.dsp.points import POINT_COLUMNS, cluster_points, moving, to_cartesian

__all__ = ["bridge_zero_doppler"]


def bridge_zero_doppler(detections: pd.DataFrame, points: pd.DataFrame,
                        times_s: pd.Series, min_speed_mps: float, bridge: BridgeConfig,
                        estimator: str) -> tuple[pd.DataFrame, np.ndarray]:
    """Add the points of frames where the target's radial speed hid it (module docstring).

    Args:
        detections: one scene's detections: ``frame``, ``range_m``, ``velocity_mps``,
            ``angle_deg`` (NaN = no angle), ``snr_db``.
        points: the scene's points (``POINT_COLUMNS``), at most one per frame.
        times_s: frame -> time (s), for every frame of ``detections`` and ``points``.
        min_speed_mps: the static-clutter threshold the points were made with.
        bridge: the ``bridge`` group; method ``none`` returns the points unchanged.
        estimator: the points step's estimator (``detect.point_estimator``).

    Returns:
        (points sorted by frame, with the bridged frames' points added; bool (P,) True for an
        added point).

    Raises:
        KeyError: a frame missing from ``times_s`` (names the frame).
    """
    base = points.sort_values("frame", kind="stable").reset_index(drop=True)
    none = (base, np.zeros(len(base), dtype=bool))
    if bridge.method == "none" or len(base) < 2 or len(detections) == 0:
        return none
    pf = base["frame"].to_numpy()
    pt = base["time_s"].to_numpy(np.float64)
    px, py = base["x_m"].to_numpy(np.float64), base["y_m"].to_numpy(np.float64)
    f = detections["frame"].to_numpy()
    v = detections["velocity_mps"].to_numpy(np.float64)
    a = detections["angle_deg"].to_numpy(np.float64)
    cand = np.flatnonzero(~moving(v, min_speed_mps) & np.isfinite(a) & ~np.isin(f, pf))
    if cand.size == 0:
        return none
    cf = f[cand]
    ct = pd.Series(times_s).loc[cf].to_numpy(np.float64)
    # 1. the constant-velocity line through the points of the last history_s before the frame
    j = np.searchsorted(pt, ct, side="right") - 1            # last point before the frame
    jj = np.maximum(j, 0)
    i0 = np.searchsorted(pt, pt[jj] - bridge.history_s, side="right")
    tc = pt - pt[0]

    def window_sum(values: np.ndarray) -> np.ndarray:
        c = np.concatenate([[0.0], np.cumsum(values)])
        return c[jj + 1] - c[i0]

    n = (jj + 1 - i0).astype(np.float64)
    st, stt = window_sum(tc), window_sum(tc * tc)
    sx, sy, stx, sty = window_sum(px), window_sum(py), window_sum(tc * px), window_sum(tc * py)
    den = n * stt - st * st
    ok = (j >= 0) & (ct - pt[jj] <= bridge.max_gap_s) & (n >= 2) & (den > 1e-12)
    safe = np.where(ok, den, 1.0)
    vx, vy = (n * stx - st * sx) / safe, (n * sty - st * sy) / safe
    tq = ct - pt[0]
    nn = np.maximum(n, 1.0)
    x_hat = sx / nn + vx * (tq - st / nn)
    y_hat = sy / nn + vy * (tq - st / nn)
    # 2. only where the Doppler filter can have hidden the target
    rng_hat = np.hypot(x_hat, y_hat)
    v_r = (vx * x_hat + vy * y_hat) / np.where(rng_hat > 0, rng_hat, 1.0)
    ok &= np.abs(v_r) <= min_speed_mps + bridge.margin_mps
    # 3. zero-Doppler detections within the gate
    r = detections["range_m"].to_numpy(np.float64)[cand]
    x, y = to_cartesian(r, a[cand])
    ok &= np.hypot(x - x_hat, y - y_hat) <= bridge.gate_m
    if not ok.any():
        return none
    frames, slot = np.unique(cf[ok], return_inverse=True)
    snr = detections["snr_db"].to_numpy(np.float64)[cand][ok]
    fields = cluster_points(slot, x[ok], y[ok], v[cand][ok], snr, frames.size, estimator)
    added = pd.DataFrame({"frame": frames.astype(np.int64),
                          "time_s": pd.Series(times_s).loc[frames].to_numpy(np.float64),
                          **fields}, columns=list(POINT_COLUMNS))
    out = pd.concat([base[list(POINT_COLUMNS)], added], ignore_index=True)
    bridged = np.r_[np.zeros(len(base), dtype=bool), np.ones(len(added), dtype=bool)]
    order = np.argsort(out["frame"].to_numpy(), kind="stable")
    out = out.iloc[order].reset_index(drop=True)
    return out.astype({"frame": np.int64, "n_detections": np.int64}), bridged[order]
