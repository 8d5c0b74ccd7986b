"""Metrics against hand-checkable geometry."""

import numpy as np
import pytest

from blindspot.traj.metrics import ade, displacement, fde, path_error, per_step_error


def line(n, start=(0.0, 0.0), step=(1.0, 0.0)):
    return np.asarray(start) + np.arange(n)[:, None] * np.asarray(step)


def test_path_error_is_distance_to_nearest_actual_point():
    actual = line(3)                                   # (0,0) (1,0) (2,0)
    pred = np.array([[0.5, 1.0], [2.0, 3.0], [1.0, 0.0], [-3.0, -4.0]])
    # (0.5, 1): equidistant to (0,0) and (1,0): sqrt(0.25 + 1); (2, 3) above (2,0): 3;
    # (1, 0) on a point: 0; (-3, -4) to (0, 0): 5 (3-4-5 triangle)
    np.testing.assert_allclose(path_error(pred, actual), [np.sqrt(1.25), 3.0, 0.0, 5.0])


def test_path_error_ignores_timing_unlike_ade():
    actual = line(10)
    late = actual[:5]                                  # on the path but 5 steps behind
    assert np.all(path_error(late, actual[5:10]) == np.array([5, 4, 3, 2, 1]))
    assert path_error(late, actual).max() == 0.0
    assert ade(late, actual[5:10]) == pytest.approx(5.0)


def test_path_error_skips_missing_actual_points_and_propagates_nan_predictions():
    actual = line(4)
    actual[1] = np.nan                                 # the nearest point to (1, 0.5) is gone
    pred = np.array([[1.0, 0.5], [np.nan, np.nan]])
    out = path_error(pred, actual)
    assert out[0] == pytest.approx(np.hypot(1.0, 0.5))
    assert np.isnan(out[1])
    assert np.isnan(path_error(pred[:1], np.full((3, 2), np.nan))).all()


def test_path_error_batched_equals_per_path_and_never_exceeds_aligned_error():
    rng = np.random.default_rng(0)
    pred, actual = rng.normal(size=(4, 6, 2)), rng.normal(size=(4, 9, 2))
    batched = path_error(pred, actual)
    assert batched.shape == (4, 6)
    for b in range(4):
        np.testing.assert_allclose(batched[b], path_error(pred[b], actual[b]))
    # the nearest point is never farther than the time-aligned one
    assert np.all(path_error(pred, actual[:, :6]) <= displacement(pred, actual[:, :6]) + 1e-12)


def test_ade_fde_on_a_three_four_five_offset_and_a_growing_error():
    truth = line(12)[None]
    assert ade(truth + [3.0, 4.0], truth) == pytest.approx(5.0)
    assert fde(truth + [3.0, 4.0], truth) == pytest.approx(5.0)
    growing = truth.copy()
    growing[..., 1] += np.arange(12)                   # error t at step t
    assert ade(growing, truth) == pytest.approx(5.5)
    assert fde(growing, truth) == pytest.approx(11.0)
    np.testing.assert_allclose(per_step_error(growing, truth), np.arange(12))


def test_means_over_all_leading_dims_and_per_step_mean_is_ade():
    rng = np.random.default_rng(1)
    pred, truth = rng.normal(size=(3, 5, 12, 2)), rng.normal(size=(3, 5, 12, 2))
    err = np.linalg.norm(pred - truth, axis=-1)
    assert ade(pred, truth) == pytest.approx(err.mean())
    assert fde(pred, truth) == pytest.approx(err[..., -1].mean())
    np.testing.assert_allclose(per_step_error(pred, truth), err.reshape(-1, 12).mean(axis=0))
    assert per_step_error(pred, truth).mean() == pytest.approx(ade(pred, truth))


def test_missing_truth_is_left_out_and_nan_prediction_is_not_hidden():
    truth = np.zeros((2, 3, 2))
    pred = np.ones((2, 3, 2)) * [3.0, 4.0]
    pred[1] = [6.0, 8.0]                               # error 10 on window 1
    truth[1, :] = np.nan                               # ... which has no truth at all
    assert ade(pred, truth) == pytest.approx(5.0)
    assert fde(pred, truth) == pytest.approx(5.0)
    pred[0, 0] = np.nan
    assert np.isnan(ade(pred, truth))


def test_shape_errors_are_clear():
    with pytest.raises(ValueError, match="differs"):
        ade(np.zeros((2, 3, 2)), np.zeros((2, 4, 2)))
    with pytest.raises(ValueError, match=r"\(\.\.\., T, 2\)"):
        path_error(np.zeros((3, 3)), np.zeros((3, 2)))
