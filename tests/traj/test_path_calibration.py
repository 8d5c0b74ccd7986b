"""The calibration stage's steps on paths: the validation paths cut into streams, the paths met
one after another, and each predictor's online ellipses chosen on those streams alone."""

from __future__ import annotations

import numpy as np
import pytest

from blindspot.traj.baselines import KalmanCV
from blindspot.traj.calibration import (CalibrationError, calibrate, calibration_scores,
                                        forecast_scores, path_pairs)
from blindspot.traj.conformal import AdaptiveConformal, select_on_held_out_streams
from blindspot.traj.path_calibration import online_scores, pair_times, path_streams
from blindspot.traj.scale_tracker import ScaleTracker

from tests.traj.test_calibration import cv_paths

LEVELS = (0.5, 0.9, 0.95)


def noisy_pairs(noise: float, seed: int, n: int = 200):
    truth, _ = cv_paths(n, 120, seed=seed)
    meas = truth + np.random.default_rng(seed + 100).normal(0, noise, truth.shape)
    return path_pairs(meas, truth, 20, 10, 5, with_index=True)


def kalman_on(val):
    return calibrate({"kalman": KalmanCV(dt=0.1, process_psd=0.3, meas_std=0.05)}, *val[:2],
                     scale_method="mixture")["kalman"]


def test_path_streams_are_runs_of_consecutive_paths():
    path = np.repeat([3, 5, 6, 9, 11, 12, 20], 2)           # the validation rows, in order
    stream = path_streams(path, 3)
    assert stream.tolist() == [0] * 6 + [1] * 4 + [2] * 4   # 7 paths: 3 + 2 + 2
    assert path_streams(path, 7).tolist() == np.repeat(np.arange(7), 2).tolist()
    for bad in (1, 8, 2.0, True):
        with pytest.raises(CalibrationError, match="calibration.online_val_streams.*found"):
            path_streams(path, bad)


def test_a_path_is_revealed_before_the_next_is_predicted():
    h, f, path, start = noisy_pairs(0.05, seed=1, n=3)
    t_pred, t_seen = pair_times(h, f, path, start)
    for k in range(2):
        assert t_seen[path == k].max() < t_pred[path == k + 1].min()
    np.testing.assert_array_equal(t_seen, t_pred[:, None] + 1 + np.arange(f.shape[1]))
    # pairs start every 5 frames within a path: the next pair is predicted once the first 5 of
    # this pair's 10 future points are known, and not one more
    for i in np.flatnonzero(path[1:] == path[:-1]):
        assert (t_seen[i] <= t_pred[i + 1]).sum() == 5
    assert np.all(np.diff(t_pred) > 0)                      # pairs in order within a path


def test_online_scores_follow_a_scene_the_val_calibration_misjudges():
    """Validation walks with 0.05 m radar noise, test walks with 0.25 m (another sensor): the
    val-calibrated Kalman ellipses under-cover the test paths, the adaptive conformal ones
    (the paths one stream, val scores first) come within 2 pp of every level."""
    tv, mv = cv_paths(200, 120, seed=11)
    tt, _ = cv_paths(200, 120, seed=12)
    mt = tt + np.random.default_rng(13).normal(0, 0.25, tt.shape)
    val = path_pairs(mv, tv, 20, 10, 5, with_index=True)
    test = path_pairs(mt, tt, 20, 10, 5, with_index=True)
    cal = kalman_on(val)
    assert calibration_scores(cal, *test[:2])["coverage_90"] < 0.8
    online, chosen = online_scores([AdaptiveConformal(LEVELS, 0.01, 100)], val,
                                   forecast_scores(cal, *val[:2]), test,
                                   forecast_scores(cal, *test[:2]), 4)
    assert chosen == AdaptiveConformal(LEVELS, 0.01, 100)
    assert "online_val_distance" not in online                  # one candidate: no choice
    assert {k for k in online if "coverage" in k} == {
        f"online_coverage_{p}{tail}" for p in (50, 90, 95) for tail in ("", "_ci95")}
    assert online["online_unbounded_95"] < 0.01
    for level in (50, 90, 95):
        assert online[f"online_coverage_{level}"] == pytest.approx(level / 100, abs=0.02), level
        lo, hi = online[f"online_coverage_{level}_ci95"]       # a bootstrap over the 200 paths
        assert lo < online[f"online_coverage_{level}"] < hi and hi - lo < 0.1, level


def test_the_setting_is_chosen_on_the_validation_streams_alone():
    """A one-score window can say nothing at 90 % (its ellipse is unbounded), so the streams
    refuse it wherever it is listed; the choice is the bounded candidate nearest nominal on the
    streams (select_on_held_out_streams' table, whatever the order), its val distance is
    recorded, and the test scores never enter it (the same choice whatever the test paths)."""
    val = noisy_pairs(0.05, seed=21, n=60)
    cal = kalman_on(val)
    d2_val = forecast_scores(cal, *val[:2])
    useless = AdaptiveConformal(LEVELS, 0.0, 1)
    good = [AdaptiveConformal(LEVELS, 0.005, 100), ScaleTracker(LEVELS, 0.02, 20),
            ScaleTracker(LEVELS, 0.05, 100)]
    streams = path_streams(val[2], 3)
    _, table = select_on_held_out_streams([useless, *good], d2_val, *pair_times(*val), streams)
    assert table[0].unbounded > 0 and all(t.unbounded == 0 for t in table[1:])
    nearest = 1 + int(np.argmin([t.distance_mean for t in table[1:]]))
    expect = [useless, *good][nearest]
    for order in ([useless, *good], [*good[::-1], useless], [good[1], useless, good[0], good[2]]):
        for noise, seed in ((0.05, 22), (0.5, 23)):
            test = noisy_pairs(noise, seed=seed, n=20)
            online, chosen = online_scores(order, val, d2_val, test,
                                           forecast_scores(cal, *test[:2]), 3)
            assert chosen == expect and online["online_method"] == expect.setting["online_method"]
            assert online["online_val_distance"] == table[nearest].distance_mean


def test_bad_arguments_are_named():
    val = noisy_pairs(0.05, seed=31, n=6)
    d2 = np.ones((len(val[0]), 10))
    one = [AdaptiveConformal(LEVELS)]
    with pytest.raises(CalibrationError, match="candidates: expected a non-empty sequence"):
        online_scores([], val, d2, val, d2, 3)
    with pytest.raises(CalibrationError, match="val: expected \\(history, future, path, start\\)"
                                               ".*found 2 items"):
        online_scores(one, val[:2], d2, val, d2, 3)
    n = len(val[0])
    with pytest.raises(CalibrationError,
                       match=f"test_scores: expected shape \\({n}, 10\\), found shape \\({n}, 5\\)"):
        online_scores(one, val, d2, val, d2[:, :5], 3)
    with pytest.raises(CalibrationError, match="calibration.online_val_streams.*\\[2, 6\\].*found 7"):
        online_scores(one, val, d2, val, d2, 7)
    with pytest.raises(CalibrationError, match=f"pair_times: pairs path: expected shape \\({n}\\)"):
        pair_times(*val[:2], val[2][:-1], val[3])
    with pytest.raises(CalibrationError, match="pairs start: expected indices >= 0, found -1"):
        pair_times(*val[:3], val[3] - val[3].min() - 1)
    with pytest.raises(CalibrationError, match="candidates: expected a non-empty sequence"):
        online_scores(["aci"], val, d2, val, d2, 3)
    with pytest.raises(CalibrationError, match="candidates: expected one set of levels"):
        online_scores([*one, AdaptiveConformal((0.5,))], val, d2, val, d2, 3)
    with pytest.raises(CalibrationError, match="path_streams: path: expected"):
        path_streams(np.zeros((2, 2), int), 2)
