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
