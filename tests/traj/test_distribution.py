"""GaussianForecast and its scores against theory: chi-square(2) coverage, scipy's density."""

import numpy as np
import pytest
from scipy import stats

from blindspot.traj.distribution import (
    DistributionError,
    GaussianForecast,
    chi2_2dof_radius_sq,
    ellipse_coverage,
    fit_step_scale,
    gaussian_nll,
    mahalanobis_sq,
)


def _random_forecast(rng, B=4000, H=3):
    mean = rng.normal(size=(B, H, 2))
    a = rng.normal(size=(B, H, 2, 2)) * 0.5
    cov = a @ np.swapaxes(a, -1, -2) + 0.05 * np.eye(2)
    return GaussianForecast(mean, cov)


def _draw(rng, f, scale=1.0):
    L = np.linalg.cholesky(f.cov * scale)
    return f.mean + np.einsum("bhij,bhj->bhi", L, rng.normal(size=f.mean.shape))


def test_radius_is_the_chi2_quantile():
    levels = np.array([0.5, 0.9, 0.95, 0.99])
    assert np.allclose(chi2_2dof_radius_sq(levels), stats.chi2.ppf(levels, df=2))


def test_coverage_of_truth_drawn_from_the_forecast_is_nominal():
    rng = np.random.default_rng(0)
    f = _random_forecast(rng)
    cov = ellipse_coverage(f, _draw(rng, f))
    # 12,000 points: binomial std at 0.5 is 0.0046; 4 sigma
    assert np.allclose(cov, [0.5, 0.9, 0.95], atol=0.02)


def test_nll_matches_scipy_density():
    rng = np.random.default_rng(1)
    f = _random_forecast(rng, B=20, H=2)
    truth = _draw(rng, f)
    ref = -np.mean([stats.multivariate_normal(f.mean[b, h], f.cov[b, h]).logpdf(truth[b, h])
                    for b in range(20) for h in range(2)])
    assert gaussian_nll(f, truth) == pytest.approx(ref, rel=1e-10)


def test_missing_truth_is_left_out():
    rng = np.random.default_rng(2)
    f = _random_forecast(rng, B=10, H=2)
    truth = _draw(rng, f)
    truth[3, 1] = np.nan
    assert np.isnan(mahalanobis_sq(f, truth)[3, 1])
    assert np.isfinite(gaussian_nll(f, truth))
    assert np.all(np.isfinite(ellipse_coverage(f, truth)))


@pytest.mark.parametrize("method", ["mle", "quantile"])
def test_step_scale_recovers_a_known_over_confidence(method):
    rng = np.random.default_rng(3)
    f = _random_forecast(rng, B=20000, H=2)
    truth = _draw(rng, f, scale=4.0)          # the truth spreads twice as wide (4x variance)
    s = fit_step_scale(f, truth, method=method)
    assert np.allclose(s, 4.0, rtol=0.06)
    fresh = _draw(rng, f, scale=4.0)
    assert np.allclose(ellipse_coverage(f.scaled(s), fresh), [0.5, 0.9, 0.95], atol=0.02)


def test_from_samples_moment_matches():
    rng = np.random.default_rng(4)
    true_cov = np.array([[0.4, 0.1], [0.1, 0.2]])
    samples = rng.multivariate_normal([1.0, -2.0], true_cov, size=(50000, 1, 1))
    f = GaussianForecast.from_samples(samples)
    assert np.allclose(f.mean[0, 0], [1.0, -2.0], atol=0.01)
    assert np.allclose(f.cov[0, 0], true_cov, atol=0.01)


def test_ellipse_axes_of_a_diagonal_covariance():
    f = GaussianForecast(np.zeros((1, 1, 2)), np.diag([4.0, 1.0])[None, None])
    major, minor, angle = f.ellipses(0.95)
    r = np.sqrt(chi2_2dof_radius_sq(0.95))
    assert major[0, 0] == pytest.approx(2 * r) and minor[0, 0] == pytest.approx(r)
    assert abs(np.sin(angle[0, 0])) == pytest.approx(0, abs=1e-12)


@pytest.mark.parametrize("cov, match", [
    (np.array([[1.0, 0.5], [0.0, 1.0]]), "symmetric"),
    (np.array([[1.0, 2.0], [2.0, 1.0]]), "positive definite"),
    (np.array([[np.nan, 0.0], [0.0, 1.0]]), "NaN|finite|nan"),
])
def test_bad_covariance_is_refused(cov, match):
    with pytest.raises(DistributionError, match=match):
        GaussianForecast(np.zeros((1, 1, 2)), cov[None, None])


def test_truth_of_another_shape_is_refused():
    f = GaussianForecast(np.zeros((2, 3, 2)), np.broadcast_to(np.eye(2), (2, 3, 2, 2)).copy())
    with pytest.raises(DistributionError, match="truth"):
        ellipse_coverage(f, np.zeros((2, 4, 2)))
    with pytest.raises(DistributionError, match="level"):
        ellipse_coverage(f, np.zeros((2, 3, 2)), levels=(1.0,))


def test_scale_mixture_recovers_a_heavy_tailed_truth_and_covers_it_at_nominal_rate():
    """Truth drawn from 0.8 N(0, 0.5 C) + 0.2 N(0, 6 C): one scale cannot cover it at 50 % and
    95 % together; the fitted mixture recovers weights and scales and covers new draws at
    nominal rate at every level."""
    from blindspot.traj.distribution import fit_scale_mixture

    rng = np.random.default_rng(7)

    def draws(f):
        heavy = rng.random(f.mean.shape[:2]) < 0.2
        scale = np.where(heavy, 6.0, 0.5)[..., None, None]
        L = np.linalg.cholesky(f.cov * scale)
        return f.mean + np.einsum("bhij,bhj->bhi", L, rng.normal(size=f.mean.shape))

    f_val, f_test = _random_forecast(rng, B=6000, H=2), _random_forecast(rng, B=6000, H=2)
    val, test = draws(f_val), draws(f_test)
    mix = fit_scale_mixture(f_val, val, n_components=2)
    assert np.allclose(mix.weights, [[0.8, 0.2]] * 2, atol=0.03), mix.weights
    assert np.allclose(mix.scales, [[0.5, 6.0]] * 2, rtol=0.1), mix.scales
    levels = (0.5, 0.9, 0.95)
    assert np.allclose(mix.coverage(f_test, test, levels), levels, atol=0.015)
    one = f_test.scaled(fit_step_scale(f_val, val))
    single = ellipse_coverage(one, test, levels)
    assert single[0] > 0.5 + 0.1 and single[2] < 0.95 - 0.01, single
    assert mix.nll(f_test, test) < gaussian_nll(one, test) - 0.05
    # the moment-matched Gaussian has the mixture's covariance 0.8 * 0.5 + 0.2 * 6 = 1.6 C
    np.testing.assert_allclose(mix.moment_matched(f_test).cov / f_test.cov,
                               np.broadcast_to(np.sum(mix.weights * mix.scales, axis=1)
                                               [None, :, None, None], f_test.cov.shape))


def test_one_component_is_the_mle_step_scale_and_its_nll_the_gaussian_one():
    from blindspot.traj.distribution import fit_scale_mixture

    rng = np.random.default_rng(8)
    f = _random_forecast(rng, B=500, H=3)
    truth = _draw(rng, f, scale=2.5)
    mix = fit_scale_mixture(f, truth, n_components=1)
    np.testing.assert_allclose(mix.scales[:, 0], fit_step_scale(f, truth), rtol=1e-9)
    scaled = f.scaled(mix.scales[:, 0])
    assert mix.nll(f, truth) == pytest.approx(gaussian_nll(scaled, truth), rel=1e-9)
    np.testing.assert_allclose(mix.radius_sq(0.9)[0], chi2_2dof_radius_sq(0.9) * mix.scales[:, 0],
                               rtol=1e-8)
    with pytest.raises(DistributionError, match="n_components"):
        fit_scale_mixture(f, truth, n_components=0)


def _em_reference(forecast, truth, K, max_iter=300, tol=1e-8):
    """EM for a mixture of exponentials on d^2, written plainly on (B, H, K) arrays (Dempster,
    Laird & Rubin 1977): the formulation fit_scale_mixture computes in (K, B, H) layout."""
    d2 = mahalanobis_sq(forecast, truth)
    seen = ~np.isnan(d2)
    n = seen.sum(axis=0)
    x = np.where(seen, d2, 0.0)[..., None]
    q = np.nanquantile(d2, (np.arange(K) + 0.5) / K, axis=0).T
    s = np.maximum(q / 2.0, 1e-6)
    w = np.full(s.shape, 1.0 / K)
    prev = -np.inf
    for _ in range(max_iter):
        log_k = np.log(w)[None] - np.log(2 * s)[None] - x / (2 * s)[None]
        m = log_k.max(axis=-1, keepdims=True)
        tot = m + np.log(np.exp(log_k - m).sum(axis=-1, keepdims=True))
        r = np.exp(log_k - tot) * seen[..., None]
        ll = float(np.sum(tot[..., 0] * seen) / seen.sum())
        nk = r.sum(axis=0)
        w = np.maximum(nk / n[:, None], 1e-12)
        w = w / w.sum(axis=1, keepdims=True)
        s = np.maximum((r * x).sum(axis=0) / (2 * np.maximum(nk, 1e-12)), 1e-9)
        if abs(ll - prev) < tol:
            break
        prev = ll
    order = np.argsort(s, axis=1)
    return np.take_along_axis(w, order, 1), np.take_along_axis(s, order, 1)


@pytest.mark.parametrize("K", [1, 2, 3, 4])
def test_scale_mixture_fit_has_the_bits_of_the_plain_em(K):
    """The (K, B, H) layout of fit_scale_mixture (for speed) sums in the order the plain
    (B, H, K) EM does: the same weights and scales to the bit, missing truth points included
    (the ETH/UCY and calibration outputs depend on it)."""
    from blindspot.traj.distribution import fit_scale_mixture

    rng = np.random.default_rng(20 + K)
    f = _random_forecast(rng, B=700, H=5)
    heavy = rng.random(f.mean.shape[:2]) < 0.25
    truth = _draw(rng, f) * np.where(heavy, 3.0, 1.0)[..., None]
    truth[rng.random(heavy.shape) < 0.05] = np.nan
    mix = fit_scale_mixture(f, truth, n_components=K)
    w, s = _em_reference(f, truth, K)
    assert np.array_equal(mix.weights, w) and np.array_equal(mix.scales, s)


def test_conditional_mixture_carries_over_to_a_scene_with_another_share_of_each_class():
    """Two kinds of track told apart by a feature of the history (say standing, f < 0.2, and
    walking): errors 0.2 C vs 3 C. Validation holds 70 % standing, test 20 % (the ETH/UCY
    folds' situation). One mixture fitted on the pooled validation errors learns the 70/30
    share and mis-covers the test scene's 50 % ellipse; one mixture per class covers it at
    the nominal rate (theory: each class's d^2 is exponential with mean 2 s)."""
    from blindspot.traj.distribution import (ConditionalScaleMixture,
                                             fit_conditional_scale_mixture, fit_scale_mixture)

    rng = np.random.default_rng(9)

    def scene(share_standing, B=8000):
        f = _random_forecast(rng, B=B, H=2)
        standing = rng.random(B) < share_standing
        feature = np.where(standing, rng.uniform(0.0, 0.2, B), rng.uniform(0.2, 2.0, B))
        scale = np.where(standing, 0.2, 3.0)[:, None, None, None]
        L = np.linalg.cholesky(f.cov * scale)
        return f, f.mean + np.einsum("bhij,bhj->bhi", L, rng.normal(size=f.mean.shape)), feature

    f_val, t_val, x_val = scene(0.7)
    f_test, t_test, x_test = scene(0.2)
    levels = (0.5, 0.9, 0.95)
    pooled = fit_scale_mixture(f_val, t_val, n_components=2).coverage(f_test, t_test, levels)
    assert abs(pooled[0] - 0.5) > 0.05, pooled
    cond = fit_conditional_scale_mixture(f_val, t_val, x_val, [0.2], n_components=1)
    np.testing.assert_allclose(cond.mixtures[0].scales, 0.2, rtol=0.08)
    np.testing.assert_allclose(cond.mixtures[1].scales, 3.0, rtol=0.08)
    np.testing.assert_allclose(cond.coverage(f_test, t_test, x_test, levels), levels, atol=0.015)
    # stored and read back: the same ellipses and likelihood
    back = ConditionalScaleMixture.from_dict(cond.to_dict())
    np.testing.assert_allclose(back.radius_sq(0.9, x_test), cond.radius_sq(0.9, x_test))
    assert back.nll(f_test, t_test, x_test) == cond.nll(f_test, t_test, x_test)
    # a class with too few tracks falls back to the pooled fit
    few = fit_conditional_scale_mixture(f_val, t_val, x_val, [0.2, 1.99], n_components=1)
    np.testing.assert_allclose(few.mixtures[2].scales,
                               fit_scale_mixture(f_val, t_val, n_components=1).scales)
    with pytest.raises(DistributionError, match="edges"):
        fit_conditional_scale_mixture(f_val, t_val, x_val, [1.0, 0.5])
