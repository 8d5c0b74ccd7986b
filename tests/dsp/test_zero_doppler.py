"""The zero-Doppler bridge: a walker crossing the line of sight keeps its points; clutter does
not become one."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from blindspot.dsp.config import BridgeConfig
from blindspot.dsp.points import frame_points
from blindspot.dsp.zero_doppler import bridge_zero_doppler

BRIDGE = BridgeConfig(method="track_gate", history_s=1.0, max_gap_s=2.0, gate_m=0.6,
                      margin_mps=0.1)
DT, MIN_SPEED = 0.1, 0.11


def crossing_walk(n=60, y=10.0, speed=1.25, x0=3.5):
    """Detections of a walker along y = const in -x, crossing boresight: its true radial speed
    (v . u, the physics that hides it) sets the Doppler it is detected at; one parked-car
    clutter detection per frame at 1.2 m from the line. Returns (detections, truth x, y, the
    walker's detected velocity)."""
    t = np.arange(n) * DT
    x = x0 - speed * t
    r = np.hypot(x, y)
    v_r = -speed * x / r
    ang = np.degrees(np.arctan2(x, y))
    bins = np.round(v_r / 0.0726) * 0.0726                 # the Doppler bin's velocity
    walker = pd.DataFrame({"frame": np.arange(n), "range_m": r, "velocity_mps": bins,
                           "angle_deg": ang, "snr_db": 25.0})
    car = pd.DataFrame({"frame": np.arange(n), "range_m": np.hypot(1.5, y - 1.2),
                        "velocity_mps": 0.0, "angle_deg": np.degrees(np.arctan2(1.5, y - 1.2)),
                        "snr_db": 40.0})
    return pd.concat([walker, car], ignore_index=True), x, np.full(n, y), bins


def test_the_crossing_is_bridged_with_measured_points_only():
    det, x, y, v_r = crossing_walk()
    times = pd.Series(np.arange(60) * DT, index=np.arange(60))
    before = frame_points(det, times, MIN_SPEED, 1.0, estimator="median")
    hidden = np.abs(v_r) <= MIN_SPEED
    assert hidden.sum() >= 10 and not np.isin(np.flatnonzero(hidden), before.frame).any()
    after, bridged = bridge_zero_doppler(det, before, times, MIN_SPEED, BRIDGE, "median")
    assert sorted(after.frame[bridged]) == list(np.flatnonzero(hidden))
    assert len(after) == 60 and after.frame.is_monotonic_increasing
    f = after.frame.to_numpy()
    # the bridged points are the walker's detections (measured), not the clutter's
    np.testing.assert_allclose(after.x_m[bridged], x[f[bridged]], atol=1e-9)
    np.testing.assert_allclose(after.y_m[bridged], y[f[bridged]], atol=1e-9)


def test_clutter_outside_the_gate_or_a_visible_doppler_is_never_taken():
    det, *_ = crossing_walk()
    walker_static = (det.snr_db == 25.0) & (det.velocity_mps.abs() <= MIN_SPEED)
    only_car = det[~walker_static]                 # the walker vanishes at zero Doppler
    times = pd.Series(np.arange(60) * DT, index=np.arange(60))
    pts = frame_points(only_car, times, MIN_SPEED, 1.0)
    after, bridged = bridge_zero_doppler(only_car, pts, times, MIN_SPEED, BRIDGE, "median")
    assert not bridged.any() and len(after) == len(pts)
    # a target whose Doppler is visible (fast radial walker) is never bridged: drop a few of
    # its frames and put clutter right on its path
    t = np.arange(40) * DT
    r = 12.0 - 1.2 * t
    walker = pd.DataFrame({"frame": np.arange(40), "range_m": r, "velocity_mps": -1.2,
                           "angle_deg": 0.0, "snr_db": 25.0})
    walker = walker[~walker.frame.between(20, 24)]
    clutter = pd.DataFrame({"frame": np.arange(20, 25), "range_m": r[20:25], "velocity_mps": 0.0,
                            "angle_deg": 0.0, "snr_db": 30.0})
    d = pd.concat([walker, clutter], ignore_index=True)
    times = pd.Series(t, index=np.arange(40))
    pts = frame_points(d, times, MIN_SPEED, 1.0)
    after, bridged = bridge_zero_doppler(d, pts, times, MIN_SPEED, BRIDGE, "median")
    assert not bridged.any()


def test_method_none_and_long_gaps():
    det, *_ = crossing_walk()
    times = pd.Series(np.arange(60) * DT, index=np.arange(60))
    pts = frame_points(det, times, MIN_SPEED, 1.0)
    off = BridgeConfig(method="none", history_s=1.0, max_gap_s=2.0, gate_m=0.6, margin_mps=0.1)
    after, bridged = bridge_zero_doppler(det, pts, times, MIN_SPEED, off, "median")
    assert not bridged.any() and len(after) == len(pts)
    short = BridgeConfig(method="track_gate", history_s=1.0, max_gap_s=0.3, gate_m=0.6,
                         margin_mps=0.1)
    after, bridged = bridge_zero_doppler(det, pts, times, MIN_SPEED, short, "median")
    assert 1 <= bridged.sum() <= 3          # only the first 0.3 s after the last point


def test_bad_config_names_the_key():
    from blindspot.typed_config import ConfigError

    with pytest.raises(ConfigError, match="bridge.gate_m"):
        BridgeConfig.from_mapping({"method": "track_gate", "history_s": 1.0, "max_gap_s": 2.0,
                                   "gate_m": -1.0, "margin_mps": 0.1})
