"""Per-walk scores, bootstrap intervals and paired differences of the many-walk benchmark."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from blindspot.traj.bootstrap import (BenchmarkError, bootstrap_means, hidden_gap_error,
                                      paired_differences, prediction_scores, resample_weights)
from blindspot.traj.evaluation import score_interpolation, score_prediction


def test_prediction_scores_are_score_prediction_walk_by_walk():
    rng = np.random.default_rng(0)
    truth = np.cumsum(rng.normal(0.1, 0.05, (7, 25, 2)), axis=1)
    pred = truth + rng.normal(0, 0.2, truth.shape)
    got = prediction_scores(pred, truth, 0.1, (0.5, 1.0, 2.0))
    for i in range(7):
        ref = score_prediction(pred[i], truth[i], None, 0.1, (0.5, 1.0, 2.0))
        for k, v in got.items():
            assert v[i] == pytest.approx(ref[k], rel=1e-12), k


def test_hidden_gap_error_is_score_interpolation_walk_by_walk():
    rng = np.random.default_rng(1)
    truth = rng.normal(size=(5, 40, 2))
    filled = truth + rng.normal(0, 0.1, truth.shape)
    observed = rng.random((5, 40)) > 0.4
    observed[:, [0, -1]] = True
    hidden = np.zeros((5, 40), bool)
    hidden[:, 10:25] = True
    got = hidden_gap_error(filled, truth, observed, hidden)
    for i in range(5):
        ref = score_interpolation(filled[i], truth[i], observed[i], hidden[i])["hidden_mean_m"]
        assert got[i] == pytest.approx(ref, rel=1e-12)
    observed[0, 10:25] = True                      # nothing hidden inside a gap: NaN, not an error
    assert np.isnan(hidden_gap_error(filled, truth, observed, hidden)[0])


def test_resampling_draws_every_walk_once_on_average():
    w = resample_weights(40, 3000, seed=2)
    assert np.all(w.sum(axis=1) == 40)
    np.testing.assert_allclose(w.mean(axis=0), 1.0, atol=0.1)


def test_interval_matches_scipy_and_covers_the_true_mean_at_its_level():
    """The percentile interval agrees with scipy.stats.bootstrap's on one sample; over 300
    samples of 60 normal values it holds the true mean about 95 % of the time (the percentile
    bootstrap of a mean under-covers slightly at this n: 0.93-0.95 expected)."""
    rng = np.random.default_rng(3)
    x = rng.normal(2.0, 1.0, 60)
    ours = bootstrap_means({"m": {"e": x}}, n_boot=4000, seed=4)["m"]["e"]
    ref = stats.bootstrap((x,), np.mean, n_resamples=4000, method="percentile",
                          random_state=5).confidence_interval
    assert ours["mean"] == pytest.approx(x.mean())
    assert ours["ci95"][0] == pytest.approx(ref.low, abs=0.03)
    assert ours["ci95"][1] == pytest.approx(ref.high, abs=0.03)
    samples = rng.normal(2.0, 1.0, (300, 60))
    w = resample_weights(60, 1000, seed=6)
    means = samples @ w.T / 60                                            # (300, 1000)
    lo, hi = np.quantile(means, [0.025, 0.975], axis=1)
    cover = np.mean((lo <= 2.0) & (2.0 <= hi))
    assert 0.90 <= cover <= 0.98


def test_paired_difference_sees_what_two_separate_intervals_cannot():
    """Two methods with errors dominated by the walk (a hard walk is hard for both) and a small
    consistent gap: their intervals overlap, the paired interval of the difference excludes 0."""
    rng = np.random.default_rng(7)
    walk = rng.gamma(2.0, 0.3, 200)
    scores = {"a": {"ade": walk + 0.02 + rng.normal(0, 0.01, 200)},
              "b": {"ade": walk + rng.normal(0, 0.01, 200)}}
    single = bootstrap_means(scores, n_boot=2000, seed=0)
    assert single["a"]["ade"]["ci95"][0] < single["b"]["ade"]["ci95"][1]     # overlap
    diff = paired_differences(scores, [("a", "b")], n_boot=2000, seed=0)["a - b"]["ade"]
    assert diff["mean"] == pytest.approx(0.02, abs=0.005)
    assert diff["ci95"][0] > 0


def test_nan_walks_are_left_out_and_bad_input_is_named():
    x = np.array([1.0, np.nan, 3.0, 5.0])
    r = bootstrap_means({"m": {"e": x}}, n_boot=200, seed=0)["m"]["e"]
    assert r["mean"] == pytest.approx(3.0) and r["n"] == 3
    with pytest.raises(BenchmarkError, match="same walks"):
        bootstrap_means({"m": {"e": x, "f": x[:3]}}, n_boot=200)
    with pytest.raises(BenchmarkError, match="names a method"):
        paired_differences({"m": {"e": x}}, [("m", "z")], n_boot=200)
