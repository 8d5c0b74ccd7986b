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
* :func:`fit_scale_mixture` - a per-step scale mixture of the forecast's Gaussians
  (:class:`ScaleMixture`) fitted on validation data, for errors heavier-tailed than a Gaussian;
* :func:`fit_conditional_scale_mixture` - one such mixture per class of what the history shows
  (:class:`ConditionalScaleMixture`; e.g. the observed speed: standing, slow, walking, fast), so
  the calibration transfers to a scene with another share of each class;
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
    "ScaleMixture",
    "fit_scale_mixture",
    "observed_speed",
    "ConditionalScaleMixture",
    "fit_conditional_scale_mixture",
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


# --------------------------------------------------------------------------------------------
# Heavy tails: a scale mixture of the forecast's Gaussian, fitted on validation data
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ScaleMixture:
    """Per-step scale mixture of a forecast's Gaussians: the error of step h is modelled as
    ``sum_k w_hk N(0, s_hk C)``, C the forecast's covariance of that point.

    Real pedestrian errors are heavier-tailed than one Gaussian (most walkers go on, a few turn
    or stop): no single scale gets the 50 % and the 95 % ellipse right at once (the 50 % one
    over-covers when the 95 % one is right). A scale mixture of normals keeps the forecast's
    shape and orientation and gives the radial distribution the data have (Andrews & Mallows
    1974, "Scale mixtures of normal distributions"); with one component it is the "mle" step
    scale of :func:`fit_step_scale`. Fitted with :func:`fit_scale_mixture` on validation data.

    Under the mixture, d^2 (the Mahalanobis distance under C) has the CDF
    ``F_h(r^2) = sum_k w_hk (1 - exp(-r^2 / (2 s_hk)))``; the ``level`` ellipse is
    ``d^2 <= F_h^-1(level)`` and the mixture's covariance is ``(sum_k w_hk s_hk) C``.

    Attributes:
        weights: (H, K) mixture weights per step, rows summing to 1.
        scales: (H, K) covariance multipliers per step, > 0.
    """

    weights: np.ndarray
    scales: np.ndarray

    def __post_init__(self) -> None:
        who = "ScaleMixture"
        w = check_array(self.weights, "weights", ("H", "K"), error=DistributionError, who=who)
        s = check_array(self.scales, "scales", w.shape, error=DistributionError, who=who)
        if np.any(w < 0) or not np.allclose(w.sum(axis=1), 1.0) or np.any(s <= 0):
            raise DistributionError(f"{who}: weights must be >= 0 and sum to 1 per step, scales "
                                    f"> 0; found weights {w.tolist()}, scales {s.tolist()}")
        object.__setattr__(self, "weights", w)
        object.__setattr__(self, "scales", s)

    @property
    def horizon(self) -> int:
        return int(self.weights.shape[0])

    def _check(self, forecast: GaussianForecast, who: str) -> None:
        if forecast.horizon > self.horizon:
            raise DistributionError(f"{who}: the mixture was fitted for {self.horizon} steps, "
                                    f"the forecast has {forecast.horizon}")

    def radius_sq(self, level: float | np.ndarray) -> np.ndarray:
        """(L, H) squared Mahalanobis radius (under C) of the ``level`` ellipses per step
        (bisection on the mixture CDF, vectorised; 1e-10 relative precision)."""
        p = np.atleast_1d(np.asarray(level, dtype=float))
        chi2_2dof_radius_sq(p)                                               # validates levels
        w, s = self.weights[None], self.scales[None]                         # (1, H, K)
        lo = np.zeros((p.size, self.horizon))
        hi = np.broadcast_to(chi2_2dof_radius_sq(p)[:, None] * self.scales.max(axis=1)[None],
                             lo.shape).copy() * 1.0001
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            cdf = np.sum(w * (1 - np.exp(-mid[..., None] / (2 * s))), axis=-1)
            below = cdf < p[:, None]
            lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
        return 0.5 * (lo + hi)

    def coverage(self, forecast: GaussianForecast, truth: np.ndarray,
                 levels: tuple[float, ...] = (0.5, 0.9, 0.95)) -> np.ndarray:
        """(L,) fraction of true positions inside the mixture's ``levels`` ellipses."""
        self._check(forecast, "ScaleMixture.coverage")
        d2 = mahalanobis_sq(forecast, truth)                                 # (B, H)
        r2 = self.radius_sq(np.asarray(levels, float))[:, :forecast.horizon]  # (L, H)
        seen = ~np.isnan(d2)
        inside = (d2[None] <= r2[:, None, :]) & seen[None]
        return inside.sum(axis=(1, 2)) / seen.sum()

    def nll(self, forecast: GaussianForecast, truth: np.ndarray) -> float:
        """Mean negative log-likelihood (nats per point) of the truth under the mixture."""
        self._check(forecast, "ScaleMixture.nll")
        d2 = mahalanobis_sq(forecast, truth)                                 # (B, H)
        c = forecast.cov
        logdet = np.log(c[..., 0, 0] * c[..., 1, 1] - c[..., 0, 1] ** 2)
        H = forecast.horizon
        w, s = self.weights[None, :H], self.scales[None, :H]                 # (1, H, K)
        log_k = np.log(w) - np.log(2 * np.pi * s) - d2[..., None] / (2 * s)   # (B, H, K)
        m = log_k.max(axis=-1, keepdims=True)
        ll = (m[..., 0] + np.log(np.exp(log_k - m).sum(axis=-1))) - 0.5 * logdet
        return float(-np.nanmean(ll))

    def moment_matched(self, forecast: GaussianForecast) -> GaussianForecast:
        """The Gaussian with the mixture's mean and covariance, ``(sum_k w s) C`` per step."""
        self._check(forecast, "ScaleMixture.moment_matched")
        return forecast.scaled(np.sum(self.weights * self.scales, axis=1)[:forecast.horizon])


def fit_scale_mixture(forecast: GaussianForecast, truth: np.ndarray, *, n_components: int = 3,
                      max_iter: int = 300, tol: float = 1e-8) -> ScaleMixture:
    """Maximum-likelihood :class:`ScaleMixture` of a forecast's errors on (validation) data.

    Under component k, d^2 / s_k is chi-square(2), i.e. d^2 is exponential with mean 2 s_k, so
    the fit is EM for a mixture of exponentials on each step's d^2 (Dempster, Laird & Rubin
    1977), all steps at once: E-step responsibilities, M-step ``w_k = mean(r_k)``,
    ``s_k = sum(r_k d^2) / (2 sum r_k)``. Initial scales spread over the d^2 quantiles.
    ``n_components = 1`` gives ``fit_step_scale(..., method="mle")``. Fitting on test is a leak.

    Raises DistributionError: a step with fewer than ``4 * n_components`` truth points, or
    ``n_components`` < 1.
    """
    if int(n_components) != n_components or n_components < 1:
        raise DistributionError(f"fit_scale_mixture: n_components must be an integer >= 1, "
                                f"found {n_components!r}")
    d2 = mahalanobis_sq(forecast, truth)                                     # (B, H)
    seen = ~np.isnan(d2)
    n = seen.sum(axis=0)
    K = int(n_components)
    if np.any(n < 4 * K):
        raise DistributionError(f"fit_scale_mixture: every step needs at least {4 * K} truth "
                                f"points, found {n.tolist()}")
    x = np.where(seen, d2, 0.0)                                              # (B, H)
    q = np.nanquantile(d2, (np.arange(K) + 0.5) / K, axis=0).T               # (H, K)
    s = np.maximum(q / 2.0, 1e-6)
    w = np.full(s.shape, 1.0 / K)
    # The arrays of the E-step are held per component, (K, B, H): the sums over the components
    # are then K - 1 elementwise additions, left to right as numpy's reduction over a short
    # last axis adds them, and the sums over the tracks run down contiguous (B, H) blocks,
    # row after row as its reduction over a leading axis does; so the fit keeps the bits of the
    # (B, H, K) formulation (tests/traj/test_distribution.py checks them) at about half its CPU
    # time (benchmarks/bench_stage_cpu.py ethucy).
    log_k = np.empty((K, *x.shape))
    r = np.empty_like(log_k)                   # exp(log_k - m), then the responsibilities
    prev = -np.inf
    for _ in range(max_iter):
        c = np.log(w) - np.log(2 * s)                                        # (H, K)
        for k in range(K):                                                   # K components
            np.subtract(c[:, k], x / (2 * s[:, k]), out=log_k[k])
        m = np.maximum.reduce(log_k)                                         # (B, H)
        np.exp(np.subtract(log_k, m, out=r), out=r)
        acc = r[0].copy()
        for k in range(1, K):
            acc += r[k]
        tot = m + np.log(acc)                                                # (B, H)
        np.exp(np.subtract(log_k, tot, out=r), out=r)
        r *= seen                                                            # (K, B, H)
        ll = float(np.sum(tot * seen) / seen.sum())
        nk = np.stack([r[k].sum(axis=0) for k in range(K)], axis=1)          # (H, K)
        rx = np.stack([(r[k] * x).sum(axis=0) for k in range(K)], axis=1)    # (H, K)
        w = np.maximum(nk / n[:, None], 1e-12)
        w = w / w.sum(axis=1, keepdims=True)
        s = np.maximum(rx / (2 * np.maximum(nk, 1e-12)), 1e-9)
        if abs(ll - prev) < tol:
            break
        prev = ll
    order = np.argsort(s, axis=1)
    return ScaleMixture(np.take_along_axis(w, order, 1), np.take_along_axis(s, order, 1))


# --------------------------------------------------------------------------------------------
# Calibration conditional on the history: one scale mixture per class of observed speed
# --------------------------------------------------------------------------------------------


def observed_speed(history: np.ndarray, frame_period_s: float, steps: int = 2) -> np.ndarray:
    """(B,) mean speed over the last ``steps`` steps of each history (B, T, 2), m/s.

    Raises DistributionError: a history shorter than ``steps + 1`` rows, NaN in those rows, or a
    period <= 0.
    """
    h = check_array(history, "history", ("B", "T", 2), error=DistributionError,
                    who="observed_speed", allow_nan=True)
    if not frame_period_s > 0 or int(steps) != steps or steps < 1 or h.shape[1] < steps + 1:
        raise DistributionError(f"observed_speed: needs frame_period_s > 0 and a history of at "
                                f"least steps + 1 = {steps + 1} rows, found {frame_period_s!r} "
                                f"and {h.shape[1]} rows")
    d = np.linalg.norm(np.diff(h[:, -(steps + 1):], axis=1), axis=-1)     # (B, steps)
    if not np.isfinite(d).all():
        raise DistributionError("observed_speed: the last rows of a history hold NaN; fill "
                                "gaps first")
    return d.mean(axis=1) / frame_period_s


@dataclass(frozen=True)
class ConditionalScaleMixture:
    """A :class:`ScaleMixture` per class of a scalar feature of the history (e.g. the observed
    speed, :func:`observed_speed`): track b of class c has the error model
    ``sum_k w_chk N(0, s_chk C_bh)``.

    Why: a per-step scale (or one mixture) fitted on one set of scenes encodes *their* share of
    standing and walking pedestrians; a standing walker's error is tiny unless they set off
    (heavy tail), a walker's is near Gaussian. On a scene with another share (ETH/UCY's
    leave-one-scene-out folds) one mixture mis-covers the 50 % ellipse. Classes by what the
    history shows carry over to the other scene as long as each class behaves alike there (a
    mixture of experts gated by the history, piecewise constant; Jacobs et al. 1991).

    Attributes:
        edges: (C - 1,) increasing class boundaries of the feature (class c holds
            ``edges[c-1] <= f < edges[c]``).
        mixtures: C fitted :class:`ScaleMixture` s, all over the same steps.
        feature: what the feature is (for reports), e.g. ``"observed speed, m/s"``.
    """

    edges: np.ndarray
    mixtures: tuple[ScaleMixture, ...]
    feature: str = "observed speed, m/s"

    def __post_init__(self) -> None:
        who = "ConditionalScaleMixture"
        e = check_array(self.edges, "edges", ("C",), error=DistributionError, who=who)
        if np.any(np.diff(e) <= 0) or len(self.mixtures) != e.size + 1:
            raise DistributionError(f"{who}: edges must increase and there must be one mixture "
                                    f"more than edges; found edges {e.tolist()} and "
                                    f"{len(self.mixtures)} mixtures")
        if len({m.horizon for m in self.mixtures}) != 1:
            raise DistributionError(f"{who}: every mixture must cover the same steps, found "
                                    f"{[m.horizon for m in self.mixtures]}")
        object.__setattr__(self, "edges", e)
        object.__setattr__(self, "mixtures", tuple(self.mixtures))

    @property
    def horizon(self) -> int:
        return self.mixtures[0].horizon

    def classes(self, feature: np.ndarray) -> np.ndarray:
        """(B,) class index of each track's feature (B,)."""
        f = check_array(feature, "feature", ("B",), error=DistributionError,
                        who="ConditionalScaleMixture")
        return np.searchsorted(self.edges, f, side="right")

    def _check(self, forecast: GaussianForecast, feature: np.ndarray, who: str) -> np.ndarray:
        if forecast.horizon > self.horizon:
            raise DistributionError(f"{who}: fitted for {self.horizon} steps, the forecast has "
                                    f"{forecast.horizon}")
        c = self.classes(feature)
        if c.size != forecast.mean.shape[0]:
            raise DistributionError(f"{who}: feature ({c.size},) must match the forecast's "
                                    f"{forecast.mean.shape[0]} tracks")
        return c

    def radius_sq(self, level: float | np.ndarray, feature: np.ndarray) -> np.ndarray:
        """(L, B, H) squared Mahalanobis radius (under C) of the ``level`` ellipses of every
        track and step."""
        r = np.stack([m.radius_sq(level) for m in self.mixtures])            # (C, L, H)
        return np.moveaxis(r[self.classes(feature)], 0, 1)                   # (L, B, H)

    def coverage(self, forecast: GaussianForecast, truth: np.ndarray, feature: np.ndarray,
                 levels: tuple[float, ...] = (0.5, 0.9, 0.95)) -> np.ndarray:
        """(L,) fraction of true positions inside the ``levels`` ellipses."""
        self._check(forecast, feature, "ConditionalScaleMixture.coverage")
        d2 = mahalanobis_sq(forecast, truth)                                 # (B, H)
        r2 = self.radius_sq(np.asarray(levels, float), feature)[..., :forecast.horizon]
        seen = ~np.isnan(d2)
        return ((d2[None] <= r2) & seen[None]).sum(axis=(1, 2)) / seen.sum()

    def nll(self, forecast: GaussianForecast, truth: np.ndarray, feature: np.ndarray) -> float:
        """Mean negative log-likelihood (nats per point) of the truth under each track's
        class mixture."""
        c = self._check(forecast, feature, "ConditionalScaleMixture.nll")
        H = forecast.horizon
        w = np.stack([m.weights[:H] for m in self.mixtures])[c]              # (B, H, K)
        s = np.stack([m.scales[:H] for m in self.mixtures])[c]
        d2 = mahalanobis_sq(forecast, truth)
        cv = forecast.cov
        logdet = np.log(cv[..., 0, 0] * cv[..., 1, 1] - cv[..., 0, 1] ** 2)
        log_k = np.log(w) - np.log(2 * np.pi * s) - d2[..., None] / (2 * s)
        m = log_k.max(axis=-1, keepdims=True)
        ll = (m[..., 0] + np.log(np.exp(log_k - m).sum(axis=-1))) - 0.5 * logdet
        return float(-np.nanmean(ll))

    def moment_matched(self, forecast: GaussianForecast, feature: np.ndarray
                       ) -> GaussianForecast:
        """The Gaussian with each track's mixture covariance ``(sum_k w s) C`` per step."""
        c = self._check(forecast, feature, "ConditionalScaleMixture.moment_matched")
        g = np.stack([np.sum(m.weights * m.scales, axis=1) for m in self.mixtures])[c]
        return GaussianForecast(forecast.mean,
                                forecast.cov * g[:, :forecast.horizon, None, None])

    def to_dict(self) -> dict:
        """Plain JSON: the edges, the feature and each class's weights and scales."""
        return {"feature": self.feature, "edges": self.edges.tolist(),
                "classes": [{"weights": m.weights.tolist(), "scales": m.scales.tolist()}
                            for m in self.mixtures]}

    @classmethod
    def from_dict(cls, record: dict) -> ConditionalScaleMixture:
        """Inverse of :meth:`to_dict` (DistributionError naming the missing field)."""
        try:
            return cls(np.asarray(record["edges"], float),
                       tuple(ScaleMixture(np.asarray(c["weights"], float),
                                          np.asarray(c["scales"], float))
                             for c in record["classes"]), record.get("feature", ""))
        except (KeyError, TypeError) as e:
            raise DistributionError(f"ConditionalScaleMixture record: missing or malformed "
                                    f"field {e}") from None


def fit_conditional_scale_mixture(forecast: GaussianForecast, truth: np.ndarray,
                                  feature: np.ndarray, edges: np.ndarray | tuple[float, ...], *,
                                  n_components: int = 3, min_tracks: int = 50,
                                  feature_name: str = "observed speed, m/s"
                                  ) -> ConditionalScaleMixture:
    """Fit a :class:`ScaleMixture` (:func:`fit_scale_mixture`) on the (validation) tracks of
    each class of ``feature`` (B,) cut at ``edges``; a class with fewer than ``min_tracks``
    tracks (or too few points for ``n_components``) gets the mixture of all tracks. Fitting on
    test is a leak.

    Raises DistributionError: ``feature`` not (B,) finite, ``edges`` not increasing, too few
    tracks in all.
    """
    f = check_array(feature, "feature", (forecast.mean.shape[0],), error=DistributionError,
                    who="fit_conditional_scale_mixture")
    e = np.asarray(edges, float)
    if e.ndim != 1 or np.any(np.diff(e) <= 0):
        raise DistributionError(f"fit_conditional_scale_mixture: edges must be an increasing "
                                f"1-D sequence, found {edges!r}")
    t = _truth(forecast, truth, "fit_conditional_scale_mixture")
    pooled = fit_scale_mixture(forecast, t, n_components=n_components)
    cls_of = np.searchsorted(e, f, side="right")
    mixtures = []
    for c in range(e.size + 1):                   # one fit per class (a handful), not per track
        sel = cls_of == c
        n_seen = np.isfinite(t[sel]).all(axis=-1).sum(axis=0) if sel.any() else np.zeros(1)
        if sel.sum() < min_tracks or np.any(n_seen < 4 * n_components):
            mixtures.append(pooled)
            continue
        sub = GaussianForecast(forecast.mean[sel], forecast.cov[sel])
        mixtures.append(fit_scale_mixture(sub, t[sel], n_components=n_components))
    return ConditionalScaleMixture(e, tuple(mixtures), feature_name)
