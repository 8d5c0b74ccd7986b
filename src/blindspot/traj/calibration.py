"""Calibrated predictive distributions of the scene predictors, fitted on validation paths.

Every prediction method gets a :class:`~blindspot.traj.distribution.GaussianForecast`:

* ``kalman``: the filter's own propagated covariance (``KalmanCV.predict_distribution`` with
  ``measured=False``: the simulated paths are scored against the true position);
* ``constant_velocity``: its :class:`~blindspot.traj.baselines.CVNoise` error model fitted on the
  validation pairs (``ConstantVelocity.fit``);
* ``lstm_direct`` (:class:`~blindspot.traj.seq2seq.Seq2SeqEnsemble`, the direct multi-step
  predictor): its own Gaussian head mixed over the ensemble's members;
* ``lstm`` (a next-point rollout, no likelihood of its own): the same kind of error model,
  fitted on the LSTM's own validation errors: a covariance per future step in the walker's
  (along-track, cross-track) frame, scaled per track by its speed and acceleration
  (:class:`ErrorModelPredictor`).

Then a per-step scale ``s_h`` (:func:`blindspot.traj.distribution.fit_step_scale`) is fitted on
the same validation pairs, so the covariances cover what they claim at the step's own horizon,
or (``scale_method="mixture"``) a per-step scale mixture
(:func:`blindspot.traj.distribution.fit_scale_mixture`): errors heavier-tailed than a Gaussian
(most walks go on, some turn) cannot get the 50 % and the 95 % ellipse right with one scale.
The predictor then gives the mixture's moment-matched Gaussian (:meth:`ScaledPredictor.
predict_distribution`) and the mixture's ellipse radii (:meth:`ScaledPredictor.radius_sq`).
The test paths (and the benchmark's walks) are never used to fit anything.

Pairs (:func:`path_pairs`): from each measured path, windows of ``window`` measured points
(interior misses linearly interpolated, as the windows stage does; none ending in a miss) and
the next ``horizon`` true positions, one every ``stride`` points.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from blindspot.arrays import check_array
from blindspot.traj.baselines import ConstantVelocity, CVNoise, KalmanCV, cv_error_frame, \
    cv_noise_features
from blindspot.traj.distribution import (DistributionError, GaussianForecast, ScaleMixture,
                                         chi2_2dof_radius_sq, ellipse_coverage,
                                         fit_scale_mixture, fit_step_scale, gaussian_nll,
                                         mahalanobis_sq)
from blindspot.traj.windows import interpolate_gaps

__all__ = ["CalibrationError", "path_pairs", "ErrorModelPredictor", "ScaledPredictor",
           "calibrate", "calibration_scores", "forecast_scores", "to_record", "from_record",
           "calibrated_distributions"]

LEVELS = (0.5, 0.9, 0.95)


class CalibrationError(ValueError):
    """Pairs, a method name or a stored calibration record is malformed."""


def path_pairs(measured: np.ndarray, truth: np.ndarray, window: int, horizon: int,
               stride: int, *, with_index: bool = False) -> tuple[np.ndarray, ...]:
    """(history (N, window, 2), future (N, horizon, 2)) pairs of measured paths.

    measured, truth: (P, T, 2), m; measured NaN where the radar gave no point. History windows
    start every ``stride`` points; interior misses are linearly interpolated. A window is
    dropped when it still holds a miss (path start / end) or its last point is a miss (filled
    from the next measurement, which lies in the pair's future). Vectorised (sliding windows). With
    ``with_index`` also each pair's path (N,) (row of ``measured``) and first frame (N,).
    """
    who = "path_pairs"
    m = check_array(measured, "measured", ("P", "T", 2), error=CalibrationError, who=who,
                    allow_nan=True)
    t = check_array(truth, "truth", m.shape, error=CalibrationError, who=who)
    if not (window >= 2 and horizon >= 1 and stride >= 1 and window + horizon <= m.shape[1]):
        raise CalibrationError(f"{who}: window {window} + horizon {horizon} must fit in paths "
                               f"of {m.shape[1]} points (window >= 2, stride {stride} >= 1)")
    filled = interpolate_gaps(m)
    starts = np.arange(0, m.shape[1] - window - horizon + 1, stride)
    idx = starts[:, None] + np.arange(window)[None, :]                       # (S, W)
    fut = starts[:, None] + window + np.arange(horizon)[None, :]             # (S, H)
    hist = filled[:, idx].reshape(-1, window, 2)
    future = t[:, fut].reshape(-1, horizon, 2)
    # and the window's last point must be measured: a gap filled there was interpolated toward
    # the next measurement, after the window (windows.last_point_measured)
    keep = (np.isfinite(hist).all(axis=(1, 2))
            & np.isfinite(m[:, idx[:, -1]]).all(axis=-1).reshape(-1))
    if not with_index:
        return hist[keep], future[keep]
    path, start = np.divmod(np.arange(m.shape[0] * starts.size), starts.size)
    return hist[keep], future[keep], path[keep], starts[start][keep]


@dataclass(frozen=True, eq=False)
class ErrorModelPredictor:
    """A point predictor with a Gaussian model of its own errors (:class:`CVNoise`): the error
    covariance per step in the (along-track, cross-track) frame of the history's
    constant-velocity velocity (least squares over the last ``k`` points), scaled per track by
    its speed and acceleration.

    Attributes:
        predictor: any PathPredictor (the scene LSTM). noise: the fitted CVNoise.
        k: points of the velocity that sets the frame. name: label.
    """

    predictor: Any
    noise: CVNoise
    k: int = 5
    name: str = "lstm"

    @property
    def window(self):
        return getattr(self.predictor, "window", None)

    def predict(self, history: np.ndarray, horizon: int) -> np.ndarray:
        return np.asarray(self.predictor.predict(history, horizon))

    def predict_distribution(self, history: np.ndarray, horizon: int) -> GaussianForecast:
        """Mean = the predictor's rollout (B, horizon, 2); covariance (B, horizon, 2, 2) from
        the error model."""
        v, _ = ConstantVelocity(k=self.k).velocity(history)
        cov = self.noise.covariance(cv_noise_features(history, v), cv_error_frame(v), horizon)
        return GaussianForecast(self.predict(history, horizon), cov)

    @classmethod
    def fit(cls, predictor, history: np.ndarray, future: np.ndarray, *, k: int = 5,
            name: str = "lstm") -> ErrorModelPredictor:
        """Fit the error model on the predictor's errors on (history, future) pairs."""
        pred = np.asarray(predictor.predict(history, future.shape[1]))
        v, _ = ConstantVelocity(k=k).velocity(history)
        noise = CVNoise.fit(future - pred, cv_noise_features(history, v), cv_error_frame(v))
        return cls(predictor, noise, k, name)


@dataclass(frozen=True, eq=False)
class ScaledPredictor:
    """A probabilistic predictor whose covariances are multiplied by a per-step scale (H,)
    fitted on validation data (:func:`fit_step_scale`), or calibrated by a per-step scale
    mixture (``mixture``, :func:`fit_scale_mixture`; ``scale`` is then its moment-matched
    scale ``sum_k w_hk s_hk``); ``options`` go to its ``predict_distribution`` (e.g.
    ``measured=False`` for the Kalman filter)."""

    base: Any
    scale: np.ndarray
    options: tuple = ()
    name: str = ""
    mixture: ScaleMixture | None = None

    def radius_sq(self, levels: tuple[float, ...] | np.ndarray, horizon: int) -> np.ndarray:
        """(L, horizon) squared Mahalanobis radius, under :meth:`predict_distribution`'s
        covariance, of the ``levels`` ellipses: the chi-square(2) quantile for a Gaussian, the
        mixture's quantile (:meth:`ScaleMixture.radius_sq`) divided by the moment-matched
        scale for a mixture."""
        lv = np.asarray(levels, float)
        if self.mixture is None:
            return np.broadcast_to(chi2_2dof_radius_sq(lv)[:, None], (lv.size, horizon)).copy()
        return self.mixture.radius_sq(lv)[:, :horizon] / self.scale[None, :horizon]

    @property
    def window(self):
        return getattr(self.base, "window", None)

    @property
    def horizon(self) -> int:
        """Steps the distribution is calibrated for."""
        return int(len(self.scale))

    def predict(self, history: np.ndarray, horizon: int) -> np.ndarray:
        return np.asarray(self.base.predict(history, horizon))

    def predict_distribution(self, history: np.ndarray, horizon: int) -> GaussianForecast:
        if horizon > len(self.scale):
            raise DistributionError(f"{self.name}: calibrated for {len(self.scale)} steps, asked "
                                    f"for {horizon}")
        fc = self.base.predict_distribution(history, horizon, **dict(self.options))
        return fc.scaled(self.scale[:horizon])


def calibrate(predictors: dict[str, Any], history: np.ndarray, future: np.ndarray, *,
              scale_method: str = "quantile", scale_level: float = 0.9,
              cv_fit_points: int = 5) -> dict[str, ScaledPredictor]:
    """Give every predictor (``lstm``, ``constant_velocity``, ``kalman``, ``lstm_direct``) a
    distribution fitted on the validation pairs (history (N, W, 2), future (N, H, 2)) and a
    per-step scale (``scale_method`` "mle" / "quantile") or scale mixture ("mixture")."""
    out = {}
    for name, p in predictors.items():
        options: tuple = ()
        if isinstance(p, KalmanCV):
            base, options = p, (("measured", False),)
        elif isinstance(p, ConstantVelocity):
            base = p.fit(history, future)
        elif hasattr(p, "predict_distribution"):   # a distribution of its own (lstm_direct)
            base = p
        else:
            base = ErrorModelPredictor.fit(p, history, future, k=cv_fit_points, name=name)
        fc = base.predict_distribution(history, future.shape[1], **dict(options))
        if scale_method == "mixture":
            mix = fit_scale_mixture(fc, future)
            scale = np.sum(mix.weights * mix.scales, axis=1)
            out[name] = ScaledPredictor(base, scale, options, name, mix)
        else:
            scale = fit_step_scale(fc, future, method=scale_method, level=scale_level)
            out[name] = ScaledPredictor(base, scale, options, name)
    return out


def calibration_scores(predictor, history: np.ndarray, future: np.ndarray,
                       forecast: GaussianForecast | None = None) -> dict[str, float]:
    """``coverage_50``, ``coverage_90``, ``coverage_95`` (share of true positions inside the
    ellipses) and ``nll`` (nats per point) of a predictor's forecast on (history, future); a
    mixture-calibrated :class:`ScaledPredictor` is scored by its mixture (ellipses and
    likelihood). ``forecast``: that forecast when the caller has made it already (not made
    again; its mean must have ``future``'s shape)."""
    if forecast is None:
        fc = predictor.predict_distribution(history, future.shape[1])
    elif isinstance(forecast, GaussianForecast) and forecast.mean.shape == np.shape(future):
        fc = forecast
    else:
        found = (f"a forecast of mean shape {forecast.mean.shape}"
                 if isinstance(forecast, GaussianForecast) else type(forecast).__name__)
        raise CalibrationError(f"calibration_scores: forecast: expected the predictor's "
                               f"GaussianForecast of mean shape {np.shape(future)} (future's), "
                               f"found {found}")
    mix = getattr(predictor, "mixture", None)
    if mix is not None:
        base = GaussianForecast(fc.mean, fc.cov / predictor.scale[None, :fc.horizon, None, None])
        cov, nll = mix.coverage(base, future, LEVELS), mix.nll(base, future)
    else:
        cov, nll = ellipse_coverage(fc, future, LEVELS), gaussian_nll(fc, future)
    return {"coverage_50": float(cov[0]), "coverage_90": float(cov[1]),
            "coverage_95": float(cov[2]), "nll": float(nll),
            "n_points": int(np.isfinite(future).all(axis=-1).sum())}


def forecast_scores(predictor, history: np.ndarray, future: np.ndarray) -> np.ndarray:
    """(N, H) squared Mahalanobis distance of each true future point (N, H, 2) under the
    predictor's forecast from ``history`` (N, W, 2): the scores the online ellipses
    (:mod:`blindspot.traj.online`) rank (those of the validation pairs are the prior they
    start from)."""
    return mahalanobis_sq(predictor.predict_distribution(history, future.shape[1]), future)


def to_record(p: ScaledPredictor) -> dict:
    """A calibrated predictor's fitted numbers as plain JSON (the point model is not stored)."""
    noise = p.base.noise if isinstance(p.base, (ErrorModelPredictor, ConstantVelocity)) else None
    return {"scale": p.scale.tolist(), "options": dict(p.options),
            "mixture": None if p.mixture is None else {"weights": p.mixture.weights.tolist(),
                                                       "scales": p.mixture.scales.tolist()},
            "noise": None if noise is None else {"step_cov": noise.step_cov.tolist(),
                                                 "beta": noise.beta.tolist(),
                                                 "n_fit": noise.n_fit},
            "k": getattr(p.base, "k", None)}


def from_record(record: dict, predictor, name: str) -> ScaledPredictor:
    """Rebuild :func:`to_record`'s calibrated predictor around the same point ``predictor``."""
    try:
        noise = record["noise"]
        scale = np.asarray(record["scale"], float)
        options = tuple(record.get("options", {}).items())
        if isinstance(predictor, KalmanCV) or (noise is None
                                               and hasattr(predictor, "predict_distribution")):
            base = predictor                 # its own distribution (Kalman, lstm_direct)
        elif isinstance(predictor, ConstantVelocity):
            base = replace(predictor, noise=CVNoise(np.asarray(noise["step_cov"]),
                                                    np.asarray(noise["beta"]), noise["n_fit"]))
        else:
            base = ErrorModelPredictor(predictor, CVNoise(np.asarray(noise["step_cov"]),
                                                          np.asarray(noise["beta"]),
                                                          noise["n_fit"]), int(record["k"]), name)
        mix = record.get("mixture")
        mixture = (None if mix is None else
                   ScaleMixture(np.asarray(mix["weights"], float), np.asarray(mix["scales"], float)))
    except (KeyError, TypeError) as e:
        raise CalibrationError(f"calibration record of {name!r}: missing or malformed field "
                               f"{e}") from None
    return ScaledPredictor(base, scale, options, name, mixture)


def calibrated_distributions(records: dict, predictors: dict, val_scores) -> tuple[dict, dict]:
    """(distributions, priors): each predictor's calibrated distribution from the calibration
    stage's records (models.json), and its validation scores from ``val_scores`` (the stage's
    val_scores.npz: where the online ellipses start)."""
    distributions = {n: from_record(records[n], p, n) for n, p in predictors.items()
                     if n in records}
    with np.load(val_scores) as z:
        priors = {n: z[n] for n in distributions if n in z.files}
    return distributions, priors
