"""Predictive distributions of future positions: a Gaussian per future step, and its scores.

Every predictor that says how sure it is returns a :class:`GaussianForecast`: for each of B
tracks and each of H future steps, the mean position (x, y) in metres and its 2x2 covariance in
m^2. A mixture or a sample set (an ensemble, a sampling model) is reduced to this form by
:meth:`GaussianForecast.from_samples` (moment matching), so one set of scores serves every method.

Scores on held-out truth (NaN truth rows are left out of every mean, as in
:mod:`blindspot.traj.metrics`):

* :func:`mahalanobis_sq` - squared Mahalanobis distance d^2 = e^T S^-1 e of the error e;
* :func:`ellipse_coverage` - the fraction of true positions inside the ``level`` confidence
  ellipse. For a 2-D Gaussian, d^2 is chi-square with 2 degrees of freedom, whose CDF is
  1 - exp(-d^2/2); so the ellipse holding probability p is d^2 <= -2 ln(1 - p) (closed form, no
  table: Mardia, Kent & Bibby, *Multivariate Analysis*, 1979, Thm 2.5.2);
* :func:`gaussian_nll` - mean negative log-likelihood per point,
  0.5 d^2 + 0.5 ln det(2 pi S), in nats;
* :func:`fit_step_scale` - per-step variance scale s_h fitted on *validation* data, so that
  ``forecast.scaled(s)`` is calibrated. ``"mle"`` is the likelihood-optimal scale
  s_h = mean(d^2) / 2; ``"quantile"`` matches the ``level`` ellipse's empirical coverage
  exactly (s_h = q_level(d^2) / (-2 ln(1 - level))).

A predictor offering this implements :class:`ProbabilisticPredictor`: the ``predict`` of
:class:`~blindspot.traj.predictor.PathPredictor` plus ``predict_distribution``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from blindspot.arrays import check_array

__all__ = [
    "DistributionError",
    "GaussianForecast",
    "ProbabilisticPredictor",
    "chi2_2dof_radius_sq",
    "mahalanobis_sq",
    "ellipse_coverage",
    "gaussian_nll",
    "fit_step_scale",
]


class DistributionError(ValueError):
    """A forecast, truth array or calibration argument is malformed."""


def chi2_2dof_radius_sq(level: float | np.ndarray) -> np.ndarray:
    """Squared Mahalanobis radius of the ellipse that holds probability ``level`` in 2-D.

    r^2 = -2 ln(1 - level) (the chi-square(2) quantile). level in (0, 1); e.g. 0.95 -> 5.991.
    Raises DistributionError for a level outside (0, 1).
    """
    p = np.asarray(level, dtype=float)
    if not np.all((p > 0) & (p < 1)):
        raise DistributionError(f"ellipse level: expected probabilities in (0, 1), found {level!r}")
    return -2.0 * np.log1p(-p)


@dataclass(frozen=True)
class GaussianForecast:
    """Per-step Gaussian predictive distribution of B tracks over H future steps.

    Attributes:
        mean: (B, H, 2) predicted positions (x, y) in metres.
        cov: (B, H, 2, 2) covariance of each predicted position in m^2, symmetric positive
            definite.

    Raises DistributionError (at construction): wrong shapes, non-finite values, a covariance
    that is not symmetric or not positive definite.
    """

    mean: np.ndarray
    cov: np.ndarray

    def __post_init__(self) -> None:
        who = "GaussianForecast"
        mean = check_array(self.mean, "mean", ("B", "H", 2), error=DistributionError, who=who)
        cov = check_array(self.cov, "cov", ("B", "H", 2, 2), error=DistributionError, who=who)
        if mean.shape[:2] != cov.shape[:2]:
            raise DistributionError(f"{who}: mean {mean.shape} and cov {cov.shape} must share "
                                    f"(B, H)")
        if not np.allclose(cov, np.swapaxes(cov, -1, -2), rtol=1e-9, atol=1e-12):
            raise DistributionError(f"{who}: cov must be symmetric (cov[..., 0, 1] == "
                                    f"cov[..., 1, 0])")
        det = cov[..., 0, 0] * cov[..., 1, 1] - cov[..., 0, 1] * cov[..., 1, 0]
        if not np.all((cov[..., 0, 0] > 0) & (det > 0)):
            n = int(np.count_nonzero(~((cov[..., 0, 0] > 0) & (det > 0))))
            raise DistributionError(f"{who}: cov must be positive definite; {n} of "
                                    f"{det.size} matrices are not")
        object.__setattr__(self, "mean", mean)
        object.__setattr__(self, "cov", cov)

    @property
    def horizon(self) -> int:
        return int(self.mean.shape[1])

    @classmethod
    def from_samples(cls, samples: np.ndarray, *, min_var: float = 1e-6) -> GaussianForecast:
        """Moment-matched Gaussian of a sample set or an ensemble.

        samples: (S, B, H, 2) positions in metres, S >= 2 draws (or ensemble members).
        min_var: m^2 added to the diagonal so a degenerate sample set (all members equal)
            still gives a positive definite covariance.
        """
        s = check_array(samples, "samples", ("S", "B", "H", 2), error=DistributionError,
                        who="GaussianForecast.from_samples")
        if s.shape[0] < 2:
            raise DistributionError(f"GaussianForecast.from_samples: need at least 2 samples, "
                                    f"found {s.shape[0]}")
        mean = s.mean(axis=0)
        d = s - mean
        cov = np.einsum("sbhi,sbhj->bhij", d, d) / (s.shape[0] - 1)
        return cls(mean, cov + min_var * np.eye(2))

    def scaled(self, scale: np.ndarray | float) -> GaussianForecast:
        """The same means with covariances multiplied by ``scale`` (scalar or (H,) per step)."""
        s = np.broadcast_to(np.asarray(scale, dtype=float), (self.horizon,))
        if not np.all(np.isfinite(s) & (s > 0)):
            raise DistributionError(f"GaussianForecast.scaled: scale must be finite and > 0, "
                                    f"found {scale!r}")
        return GaussianForecast(self.mean, self.cov * s[None, :, None, None])

    def ellipses(self, level: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Axes of the ``level`` confidence ellipse of every point, for drawing.

        Returns ``(major_m, minor_m, angle_rad)``, each (B, H): semi-axes in metres and the
        major axis's angle from +x (counter-clockwise).
        """
        r2 = chi2_2dof_radius_sq(level)
        w, v = np.linalg.eigh(self.cov)                                   # ascending
        major = np.sqrt(r2 * w[..., 1])
        minor = np.sqrt(r2 * w[..., 0])
        angle = np.arctan2(v[..., 1, 1], v[..., 0, 1])
        return major, minor, angle


@runtime_checkable
class ProbabilisticPredictor(Protocol):
    """A path predictor that also gives a :class:`GaussianForecast` of its prediction."""

    name: str

    def predict(self, history: np.ndarray, horizon: int) -> np.ndarray:
        """(B, T, 2) history (NaN rows missing) -> (B, horizon, 2) mean positions in metres."""
        ...

    def predict_distribution(self, history: np.ndarray, horizon: int) -> GaussianForecast:
        """(B, T, 2) history -> per-step Gaussian over the next ``horizon`` positions."""
        ...


def _truth(forecast: GaussianForecast, truth: np.ndarray, who: str) -> np.ndarray:
    t = check_array(truth, "truth", ("B", "H", 2), error=DistributionError, who=who,
                    allow_nan=True)
    if t.shape != forecast.mean.shape:
        raise DistributionError(f"{who}: truth {t.shape} must match the forecast's mean "
                                f"{forecast.mean.shape}")
    return t


def mahalanobis_sq(forecast: GaussianForecast, truth: np.ndarray) -> np.ndarray:
    """(B, H) squared Mahalanobis distance of each true position; NaN where truth is missing."""
    t = _truth(forecast, truth, "mahalanobis_sq")
    e = t - forecast.mean
    c = forecast.cov
    det = c[..., 0, 0] * c[..., 1, 1] - c[..., 0, 1] ** 2
    # e^T C^-1 e for a 2x2 C without a solve: C^-1 = [[d, -b], [-b, a]] / det
    return (c[..., 1, 1] * e[..., 0] ** 2 - 2 * c[..., 0, 1] * e[..., 0] * e[..., 1]
            + c[..., 0, 0] * e[..., 1] ** 2) / det


def ellipse_coverage(forecast: GaussianForecast, truth: np.ndarray,
                     levels: tuple[float, ...] = (0.5, 0.9, 0.95), *,
                     per_step: bool = False) -> np.ndarray:
    """Empirical coverage of the ``levels`` ellipses over the points with truth.

    Returns (L,) fractions in [0, 1], or (L, H) with ``per_step=True``. A calibrated forecast
    gives ``levels`` back (within sampling error).
    """
    d2 = mahalanobis_sq(forecast, truth)                                   # (B, H)
    r2 = chi2_2dof_radius_sq(np.asarray(levels, dtype=float))              # (L,)
    seen = ~np.isnan(d2)
    inside = (d2[None] <= r2[:, None, None]) & seen[None]                  # (L, B, H)
    axis = 1 if per_step else (1, 2)
    with np.errstate(invalid="ignore"):
        return inside.sum(axis=axis) / seen.sum(axis=0 if per_step else None)


def gaussian_nll(forecast: GaussianForecast, truth: np.ndarray, *,
                 per_step: bool = False) -> float | np.ndarray:
    """Mean negative log-likelihood of the true positions, nats per point ((H,) per step)."""
    d2 = mahalanobis_sq(forecast, truth)
    c = forecast.cov
    logdet = np.log(c[..., 0, 0] * c[..., 1, 1] - c[..., 0, 1] ** 2)
    nll = 0.5 * d2 + 0.5 * logdet + np.log(2 * np.pi)
    return np.nanmean(nll, axis=0) if per_step else float(np.nanmean(nll))


def fit_step_scale(forecast: GaussianForecast, truth: np.ndarray, *, method: str = "mle",
                   level: float = 0.9) -> np.ndarray:
    """Per-step covariance scale (H,) that calibrates ``forecast`` on this (validation) data.

    method: ``"mle"`` (s_h = mean d^2 / 2, the likelihood-optimal scale of a 2-D Gaussian) or
        ``"quantile"`` (the ``level`` ellipse covers exactly ``level`` of these points).
    Apply with ``forecast.scaled(s)`` to forecasts of *other* data; fitting on test is a leak.
    Raises DistributionError: unknown method, or a step without any truth point.
    """
    d2 = mahalanobis_sq(forecast, truth)
    n = np.sum(~np.isnan(d2), axis=0)
    if np.any(n == 0):
        raise DistributionError(f"fit_step_scale: steps {np.flatnonzero(n == 0).tolist()} have "
                                f"no truth point to fit on")
    if method == "mle":
        return np.nanmean(d2, axis=0) / 2.0
    if method == "quantile":
        return np.nanquantile(d2, level, axis=0) / chi2_2dof_radius_sq(level)
    raise DistributionError(f"fit_step_scale: method must be 'mle' or 'quantile', found {method!r}")
