"""Detections -> Cartesian points: eq. 7, static clutter removal, grouping into one point."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from blindspot.dsp.points import (
    POINT_COLUMNS, cluster_labels, frame_points, group_point, pedestrian_point, to_cartesian,
)


def test_eq7_axes():
    x, y = to_cartesian(np.array([10.0, 10.0, 5.0]), np.array([0.0, 90.0, -30.0]))
    np.testing.assert_allclose(x, [0.0, 10.0, -2.5], atol=1e-12)
    np.testing.assert_allclose(y, [10.0, 0.0, 5 * np.cos(np.radians(30))], atol=1e-12)


def dets(frame, rows):
    """rows: (range_m, velocity_mps, angle_deg, snr_db)."""
    a = np.array(rows, dtype=float).reshape(-1, 4)
    return pd.DataFrame({"frame": frame, "range_bin": 0, "doppler_bin": 0, "range_m": a[:, 0],
                         "velocity_mps": a[:, 1], "power": 1.0, "snr_db": a[:, 3],
                         "angle_deg": a[:, 2]})


def test_static_clutter_is_removed_and_no_point_is_invented():
    car = [(5.0, 0.0, 17.0, 40.0), (8.5, 0.05, 10.0, 30.0), (5.0, -0.07, 17.0, 20.0)]
    assert pedestrian_point(dets(0, car), min_speed_mps=0.11, cluster_gap_m=1.0) is None
    # a moving detection without an angle (not given to MUSIC) cannot make a point either
    assert pedestrian_point(dets(0, car + [(12.0, -0.7, np.nan, 25.0)]), 0.11, 1.0) is None


def test_largest_cluster_snr_weighted_centroid():
    ped = [(12.0, -0.7, 30.0, 20.0), (12.5, -0.9, 31.0, 10.0), (12.2, -0.5, 29.0, 10.0)]
    stray = [(30.0, 1.5, -40.0, 35.0)]  # a single strong moving detection far away
    car = [(5.0, 0.0, 17.0, 50.0)]
    pt = pedestrian_point(dets(0, ped + stray + car), 0.11, 1.0)
    x, y = to_cartesian(np.array([r[0] for r in ped]), np.array([r[2] for r in ped]))
    w = 10 ** (np.array([r[3] for r in ped]) / 10)
    assert pt["n_detections"] == 3
    assert pt["x_m"] == pytest.approx(np.sum(w * x) / w.sum())
    assert pt["y_m"] == pytest.approx(np.sum(w * y) / w.sum())
    assert pt["range_m"] == pytest.approx(np.hypot(pt["x_m"], pt["y_m"]))
    assert pt["angle_deg"] == pytest.approx(np.degrees(np.arctan2(pt["x_m"], pt["y_m"])))
    assert pt["snr_db"] == 20.0


def test_single_linkage_chains_neighbours():
    x = np.array([0.0, 0.8, 1.6, 5.0])
    labels = cluster_labels(x, np.zeros(4), gap_m=1.0)
    assert labels[0] == labels[1] == labels[2] != labels[3]


def test_frame_points_skip_frames_without_pedestrian():
    d = pd.concat([dets(0, [(12.0, -0.7, 30.0, 20.0)]), dets(1, [(5.0, 0.0, 17.0, 40.0)]),
                   dets(2, [(11.0, -0.6, 25.0, 15.0)])])
    pts = frame_points(d, np.array([0.0, 0.1, 0.2]), 0.11, 1.0)
    assert list(pts.columns) == list(POINT_COLUMNS)
    assert pts["frame"].tolist() == [0, 2]
    np.testing.assert_allclose(pts["time_s"], [0.0, 0.2])
    assert group_point(np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0), 0.1, 1.0) is None
