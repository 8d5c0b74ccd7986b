"""The multi-modal forecast (blindspot.traj.mixture) against truths computed independently."""

from __future__ import annotations

import numpy as np
import pytest

from blindspot.traj.distribution import DistributionError, GaussianForecast, gaussian_nll
from blindspot.traj.mixture import MixtureForecast, best_of, kmeans
from blindspot.traj.metrics import ade, fde


def _mixture(rng, b=6, m=3, h=4, sd=0.5):
    w = rng.random((b, m)) + 0.1
    means = rng.normal(size=(b, m, h, 2)) * 3
    covs = np.broadcast_to(np.eye(2) * sd**2, (b, m, h, 2, 2)).copy()
    return MixtureForecast(w / w.sum(1, keepdims=True), means, covs)


def test_most_probable_orders_by_probability():
    rng = np.random.default_rng(12)
    mix = _mixture(rng, b=3, m=5)
    top = mix.most_probable(2)
    for t in range(3):
        i, j = np.argsort(-mix.weights[t])[:2]
        assert np.array_equal(top[t], mix.means[t, [i, j]])
    assert np.array_equal(mix.most_probable(1)[:, 0], mix.most_likely())


def test_best_of_is_the_brute_force_minimum_over_hypotheses():
    rng = np.random.default_rng(0)
    means = rng.normal(size=(5, 20, 12, 2))
    truth = rng.normal(size=(5, 12, 2))
    a, f = best_of(means, truth)
    # each track's best hypothesis by ADE, and by FDE, found one at a time with metrics.ade/fde
    best_ade = np.mean([min(ade(means[b, k][None], truth[b][None]) for k in range(20))
                        for b in range(5)])
    best_fde = np.mean([min(fde(means[b, k][None], truth[b][None]) for k in range(20))
                        for b in range(5)])
    assert a == pytest.approx(best_ade) and f == pytest.approx(best_fde)
    # one hypothesis: best-of-1 is the plain ADE / FDE
    assert best_of(means[:, :1], truth) == pytest.approx((ade(means[:, 0], truth),
                                                          fde(means[:, 0], truth)))
    # the truth among the hypotheses: zero
    means[:, 7] = truth
    assert best_of(means, truth) == pytest.approx((0.0, 0.0))


def test_nll_of_one_component_is_the_gaussian_nll_and_of_a_known_point():
    rng = np.random.default_rng(1)
    mix = _mixture(rng, m=1)
    truth = rng.normal(size=(6, 4, 2))
    g = GaussianForecast(mix.means[:, 0], mix.covs[:, 0])
    assert mix.nll(truth) == pytest.approx(gaussian_nll(g, truth))
    # a standard 2-D Gaussian at its mean: -log(1 / (2 pi)) = log(2 pi)
    one = MixtureForecast(np.ones((1, 1)), np.zeros((1, 1, 1, 2)), np.eye(2)[None, None, None])
    assert one.nll(np.zeros((1, 1, 2))) == pytest.approx(np.log(2 * np.pi))
    # two equal far-apart components at one's mean: log(2 pi) + log 2
    two = MixtureForecast(np.full((1, 2), 0.5), np.array([[[[0.0, 0.0]], [[1e3, 0.0]]]]),
                          np.broadcast_to(np.eye(2), (1, 2, 1, 2, 2)))
    assert two.nll(np.zeros((1, 1, 2))) == pytest.approx(np.log(2 * np.pi) + np.log(2))


def test_moments_match_samples_and_a_gaussian_is_its_own_moment_match():
    rng = np.random.default_rng(2)
    mix = _mixture(rng, b=2, m=3, h=2)
    draws = mix.sample(100_000, np.random.default_rng(3))
    assert np.allclose(draws.mean(0), mix.mean(), atol=0.05)
    d = draws - draws.mean(0)
    assert np.allclose(np.einsum("nbhi,nbhj->bhij", d, d) / len(d), mix.moment_cov(), rtol=0.05,
                       atol=0.05)
    g = MixtureForecast(np.ones((2, 1)), mix.means[:, :1], mix.covs[:, :1]).to_gaussian()
    assert np.allclose(g.mean, mix.means[:, 0]) and np.allclose(g.cov, mix.covs[:, 0])
    # the most likely hypothesis is the one with the largest weight
    k = np.argmax(mix.weights, axis=1)
    assert np.array_equal(mix.most_likely(), mix.means[np.arange(2), k])


def test_coverage_of_truth_drawn_from_the_mixture_is_nominal_and_of_a_narrow_one_is_not():
    rng = np.random.default_rng(4)
    mix = _mixture(rng, b=400, m=3, h=3, sd=0.5)
    truth = mix.sample(1, np.random.default_rng(5))[0]
    cov = mix.coverage(truth, (0.5, 0.9, 0.95), samples=200, seed=1)
    assert np.allclose(cov, [0.5, 0.9, 0.95], atol=0.03)
    narrow = MixtureForecast(mix.weights, mix.means, mix.covs * 0.05)
    assert narrow.coverage(truth, (0.5, 0.9), samples=200)[1] < 0.6
    # a single Gaussian: the highest-density region is its ellipse (chi-square(2) radius)
    g = MixtureForecast(np.ones((400, 1)), mix.means[:, :1], mix.covs[:, :1])
    t = g.sample(1, np.random.default_rng(6))[0]
    assert np.allclose(g.coverage(t, (0.5, 0.9), samples=200), [0.5, 0.9], atol=0.03)


def test_transformed_moves_means_and_covariances():
    rng = np.random.default_rng(7)
    mix = _mixture(rng, b=2, m=2, h=2)
    theta = np.array([0.3, -1.2])
    rot = np.stack([np.stack([np.cos(theta), -np.sin(theta)], -1),
                    np.stack([np.sin(theta), np.cos(theta)], -1)], -2)
    origin = np.array([[1.0, 2.0], [-3.0, 0.5]])
    moved = mix.transformed(rot, origin)
    assert np.allclose(moved.means[1, 0, 1], rot[1] @ mix.means[1, 0, 1] + origin[1])
    assert np.allclose(moved.covs[0, 1, 0], rot[0] @ mix.covs[0, 1, 0] @ rot[0].T)
    assert moved.nll(moved.mean()) == pytest.approx(mix.nll(mix.mean()))   # rotation: same


def test_kmeans_finds_separated_clusters():
    rng = np.random.default_rng(8)
    centres = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    x = np.concatenate([c + 0.1 * rng.normal(size=(50, 2)) for c in centres])
    found = kmeans(x, 3, seed=0)
    assert np.allclose(np.sort(found, axis=0), np.sort(centres, axis=0), atol=0.1)


def test_reduced_keeps_the_moments_and_merges_separated_groups():
    rng = np.random.default_rng(10)
    # per track 3 groups of 4 nearby paths: merged to 3, each hypothesis is its group's
    # probability-weighted mean, carrying the group's summed probability
    b, h = 5, 4
    centres = rng.normal(size=(b, 3, h, 2)) * 20
    means = np.repeat(centres, 4, axis=1) + 0.05 * rng.normal(size=(b, 12, h, 2))
    w = rng.random((b, 12)) + 0.1
    w /= w.sum(1, keepdims=True)
    covs = np.broadcast_to(np.eye(2) * 0.04, (b, 12, h, 2, 2)).copy()
    mix = MixtureForecast(w, means, covs)
    red = mix.reduced(3, seed=1)
    assert red.means.shape == (b, 3, h, 2)
    np.testing.assert_allclose(red.mean(), mix.mean(), atol=1e-12)
    np.testing.assert_allclose(red.moment_cov(), mix.moment_cov(), atol=1e-10)
    group_w = w.reshape(b, 3, 4).sum(2)
    group_mu = np.einsum("bgk,bgkhi->bghi", w.reshape(b, 3, 4) / group_w[..., None],
                         means.reshape(b, 3, 4, h, 2))
    for t in range(b):
        order = np.argsort(red.means[t, :, 0, 0])
        truth = np.argsort(group_mu[t, :, 0, 0])
        np.testing.assert_allclose(red.means[t, order], group_mu[t, truth], atol=1e-12)
        np.testing.assert_allclose(red.weights[t, order], group_w[t, truth], atol=1e-12)
    # n = M gives the same hypotheses (in another order); here (truth near one group's
    # members) the best of the merged hypotheses is no better than the best of all
    same = mix.reduced(12)
    key = lambda m: np.sort(m.means[:, :, 0, 0], axis=1)                 # noqa: E731
    np.testing.assert_allclose(key(same), key(mix), atol=1e-12)
    truth = means[:, 0] + 0.3
    assert best_of(red.means, truth)[0] >= best_of(mix.means, truth)[0]


def test_reduced_by_count_keeps_the_moments_and_takes_hypotheses_of_probability_zero():
    rng = np.random.default_rng(11)
    mix = _mixture(rng, b=4, m=9, h=3)
    for weighted in (True, False):
        red = mix.reduced(3, seed=2, weighted=weighted)
        np.testing.assert_allclose(red.mean(), mix.mean(), atol=1e-12)
        np.testing.assert_allclose(red.moment_cov(), mix.moment_cov(), atol=1e-10)
    # a hypothesis of probability 0 (valid input, and what an empty cluster becomes) is kept
    # apart or merged without harm, and a merged mixture merges again
    w = mix.weights.copy()
    w[:, 0] = 0.0
    zero = MixtureForecast(w / w.sum(1, keepdims=True), mix.means, mix.covs)
    for weighted in (True, False):
        red = zero.reduced(5, seed=3, weighted=weighted)
        np.testing.assert_allclose(red.mean(), zero.mean(), atol=1e-12)
        twice = red.reduced(2, seed=4, weighted=weighted)
        np.testing.assert_allclose(twice.moment_cov(), zero.moment_cov(), atol=1e-10)
    same = np.repeat(mix.means[:, :1], 4, axis=1)            # four copies of one path
    copies = MixtureForecast(np.full((4, 4), 0.25), same, mix.covs[:, :4])
    red = copies.reduced(2)
    assert np.allclose(np.sort(red.weights, axis=1), [[0.0, 1.0]] * 4)
    assert np.allclose(red.reduced(2).mean(), copies.mean())


def test_bad_arguments_are_named():
    rng = np.random.default_rng(9)
    mix = _mixture(rng)
    with pytest.raises(DistributionError, match="weights"):
        MixtureForecast(mix.weights * 2, mix.means, mix.covs)
    with pytest.raises(DistributionError, match="covs"):
        MixtureForecast(mix.weights, mix.means, -mix.covs)
    with pytest.raises(DistributionError, match="truth"):
        mix.nll(np.zeros((6, 5, 2)))
    with pytest.raises(DistributionError, match="n: expected an integer in"):
        best_of(mix.means, np.zeros((6, 4, 2)), n=4)
    with pytest.raises(DistributionError, match="levels"):
        mix.coverage(np.zeros((6, 4, 2)), (0.5, 1.0))
    with pytest.raises(DistributionError, match="k: expected"):
        kmeans(np.zeros((3, 2)), 4)
    with pytest.raises(DistributionError, match="reduced: n: expected"):
        mix.reduced(4)
    with pytest.raises(DistributionError, match="iterations"):
        mix.reduced(2, iterations=-1)
    with pytest.raises(DistributionError, match="seed"):
        mix.reduced(2, seed=1.5)
    with pytest.raises(DistributionError, match="weighted"):
        mix.reduced(2, weighted="no")
    with pytest.raises(DistributionError, match="most_probable: n"):
        mix.most_probable(0)
