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


def _one_frame_reference(r, v, a, s, min_speed, gap):
    """The grouping rule written out for one frame, loop by loop (the oracle of the batched
    group_points): single linkage by breadth-first search, most detections then largest summed
    linear SNR (then the later cluster), SNR-weighted centroid."""
    keep = [i for i in range(len(r)) if abs(v[i]) > min_speed and np.isfinite(a[i])]
    if not keep:
        return None
    x = {i: r[i] * np.sin(np.radians(a[i])) for i in keep}
    y = {i: r[i] * np.cos(np.radians(a[i])) for i in keep}
    label, clusters = {}, []
    for i in keep:
        if i in label:
            continue
        label[i], todo, members = len(clusters), [i], []
        while todo:
            j = todo.pop()
            members.append(j)
            for k in keep:
                if k not in label and (x[j] - x[k]) ** 2 + (y[j] - y[k]) ** 2 < gap ** 2:
                    label[k] = label[i]
                    todo.append(k)
        clusters.append(sorted(members))
    key = [(len(c), sum(10 ** (s[i] / 10) for i in c), n) for n, c in enumerate(clusters)]
    best = clusters[max(key)[2]]
    w = np.array([10 ** (s[i] / 10) for i in best])
    w = w / w.sum()
    cx, cy = float(w @ [x[i] for i in best]), float(w @ [y[i] for i in best])
    return {"x_m": cx, "y_m": cy, "n_detections": len(best), "snr_db": max(s[i] for i in best),
            "velocity_mps": float(w @ [v[i] for i in best])}


def test_batched_grouping_equals_the_one_frame_rule_on_random_frames():
    """group_points over 300 random frames at once gives, frame by frame, the rule of the
    module docstring (checked against a loop-by-loop oracle), with no point where none exists."""
    from blindspot.dsp.points import group_points

    rng = np.random.default_rng(11)
    n = rng.integers(0, 9, size=300)                       # detections per frame, some empty
    frame = np.repeat(np.arange(300), n)
    perm = rng.permutation(frame.size)                     # any input order
    r = rng.uniform(2, 20, frame.size)
    v = rng.choice([0.0, 0.05, -0.8, 1.1], frame.size)
    a = np.where(rng.random(frame.size) < 0.1, np.nan, rng.uniform(-60, 60, frame.size))
    s = rng.uniform(5, 40, frame.size)
    got = group_points(frame[perm], r[perm], v[perm], a[perm], s[perm], 0.11, 1.0)
    seen = 0
    for f in range(300):
        sel = frame == f
        ref = _one_frame_reference(r[sel], v[sel], a[sel], s[sel], 0.11, 1.0)
        row = np.flatnonzero(got["frame"] == f)
        if ref is None:
            assert row.size == 0
            continue
        seen += 1
        assert row.size == 1
        for k, val in ref.items():
            assert got[k][row[0]] == pytest.approx(val, rel=1e-12, abs=1e-12), (f, k)
    assert seen == got["frame"].size > 100
    assert np.all(np.diff(got["frame"]) > 0)


# ------------------------------------------------------------------ the body's point estimators
from hypothesis import given, settings, strategies as st  # noqa: E402

from blindspot.dsp.points import PointError, weighted_medians  # noqa: E402


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 3), st.floats(-50, 50), st.floats(0.01, 100)),
                min_size=1, max_size=30))
def test_weighted_median_minimises_the_weighted_absolute_deviation(rows):
    """Per group, the result is a value of the group whose sum_i w_i |v_i - m| is the least
    over all the group's values (the L1 definition of the weighted median)."""
    g = np.array([r[0] for r in rows])
    _, g = np.unique(g, return_inverse=True)
    v, w = np.array([r[1] for r in rows]), np.array([r[2] for r in rows])
    med = weighted_medians(g, v, w, g.max() + 1)
    for k in range(g.max() + 1):
        vk, wk = v[g == k], w[g == k]
        cost = lambda m: np.sum(wk * np.abs(vk - m))  # noqa: E731
        assert med[k] in vk
        assert cost(med[k]) <= min(cost(m) for m in vk) * (1 + 1e-9) + 1e-9


def test_median_estimator_is_robust_to_one_limb_and_strongest_takes_the_peak():
    """Torso at 12.0 m / 30 deg and two limb detections on either side in range, one far off
    in angle: the weighted median keeps the torso's range and angle, the centroid is pulled
    by the stray limb; 'strongest' is the strongest detection."""
    ped = [(12.0, -0.7, 30.0, 25.0), (12.3, -1.4, 30.2, 20.0), (11.8, 0.3, 33.0, 20.0)]
    med = pedestrian_point(dets(0, ped), 0.11, 1.0, estimator="median")
    cen = pedestrian_point(dets(0, ped), 0.11, 1.0, estimator="centroid")
    top = pedestrian_point(dets(0, ped), 0.11, 1.0, estimator="strongest")
    assert med["range_m"] == pytest.approx(12.0) and med["angle_deg"] == pytest.approx(30.0)
    assert med["velocity_mps"] == pytest.approx(-0.7)
    assert abs(cen["angle_deg"] - 30.0) > 0.5
    assert (top["range_m"], top["angle_deg"], top["velocity_mps"]) == pytest.approx((12.0, 30.0, -0.7))
    assert med["n_detections"] == cen["n_detections"] == 3
    with pytest.raises(PointError, match="estimator"):
        pedestrian_point(dets(0, ped), 0.11, 1.0, estimator="mean")
