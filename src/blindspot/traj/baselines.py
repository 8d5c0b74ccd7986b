"""Physics baselines that follow the :class:`~blindspot.traj.predictor.PathPredictor` interface.

* :class:`ConstantVelocity` - the constant-velocity model (CVM) of Schöller et al. (2020): the
  velocity of the last two observed positions, ``v = x_t - x_{t-1}`` per frame, extrapolated
  linearly. Optionally a least-squares velocity over the last ``k`` valid observations.
* :class:`KalmanCV` - a Kalman filter on the constant-velocity state ``(x, y, vx, vy)`` with
  white-noise acceleration, which treats NaN rows as missing observations. Prediction uses a
  batched numpy filter (:func:`blindspot.kalman.kalman_filter`, checked against pykalman in the
  tests); gap
  filling uses pykalman's RTS smoother (:meth:`KalmanCV.smooth`). Noise levels can be fitted by
  maximum likelihood on training tracks (:meth:`KalmanCV.fit`).

Both give a predictive distribution (:class:`~blindspot.traj.distribution.GaussianForecast`,
``predict_distribution``): the Kalman filter its own propagated covariance ``F P F^T + Q`` (+ R);
constant velocity a noise model of its errors (:class:`CVNoise`) fitted on validation pairs
with :meth:`ConstantVelocity.fit`.

All arrays are (x, y) in metres; histories are (B, T, 2), NaN rows = missing frames.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from blindspot.arrays import check_array
from blindspot.kalman import FilterResult, check_positive, cv_model, kalman_filter
from blindspot.traj.distribution import GaussianForecast
from blindspot.traj.predictor import HistoryError, check_history

__all__ = [
    "ConstantVelocity",
    "CVNoise",
    "CV_FEATURE_FLOOR_M2",
    "cv_error_frame",
    "cv_noise_features",
    "KalmanCV",
    "kalman_baseline",
    "prediction_methods",
    "last_valid_index",
]


def last_valid_index(valid: np.ndarray) -> np.ndarray:
    """Index of the last True along the last axis of ``valid`` (B, T); -1 where none is True.

    Raises:
        HistoryError: ``valid`` not a boolean (B, T) array.
    """
    valid = check_array(valid, "valid", ("B", "T"), error=HistoryError, who="last_valid_index",
                        dtype=bool)
    T = valid.shape[-1]
    idx = T - 1 - np.argmax(valid[..., ::-1], axis=-1)
    return np.where(valid.any(axis=-1), idx, -1)


def _valid_rows(history: np.ndarray) -> np.ndarray:
    """(B, T) True where both coordinates of a history row are finite."""
    return np.isfinite(history).all(axis=-1)


# --------------------------------------------------------------------------------------------
# Constant velocity: noise model of its forecast errors
# --------------------------------------------------------------------------------------------

#: Floors (m^2 per frame^2) inside the logarithms of the noise model's features, so a standing
#: pedestrian (zero speed, zero acceleration) keeps a finite, non-zero spread: 0.03 m per frame
#: is about the annotation jitter of ETH/UCY positions.
CV_FEATURE_FLOOR_M2 = 1e-3


def cv_error_frame(velocity: np.ndarray) -> np.ndarray:
    """(B, 2, 2) rotations from world offsets to the (along-track, cross-track) frame of each
    velocity (B, 2); a zero velocity gets the world orientation."""
    theta = np.arctan2(velocity[:, 1], velocity[:, 0])
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([np.stack([c, s], axis=-1), np.stack([-s, c], axis=-1)], axis=-2)


def cv_noise_features(history: np.ndarray, velocity: np.ndarray) -> np.ndarray:
    """(B, 2) log features of how predictable each track is: ``log(|v|^2 + f)`` and
    ``log(mean |a|^2 + f)``, with v the CV velocity (m/frame), a the second differences of the
    valid consecutive history rows (m/frame^2; 0 where there are none) and f =
    :data:`CV_FEATURE_FLOOR_M2`."""
    d = np.diff(history, axis=1)                                          # (B, T-1, 2)
    acc = np.diff(d, axis=1)                                              # (B, T-2, 2)
    a2 = np.sum(acc**2, axis=-1)                                          # NaN across gaps
    seen = np.isfinite(a2)
    n = seen.sum(axis=1)
    mean_a2 = np.where(n > 0, np.where(seen, a2, 0.0).sum(axis=1) / np.maximum(n, 1), 0.0)
    speed2 = np.sum(velocity**2, axis=-1)
    return np.stack([np.log(speed2 + CV_FEATURE_FLOOR_M2),
                     np.log(mean_a2 + CV_FEATURE_FLOOR_M2)], axis=-1)


@dataclass(frozen=True, eq=False)
class CVNoise:
    """Gaussian model of the constant-velocity model's forecast errors.

    The error ``e_h = x_true(T-1+h) - x_cv(T-1+h)`` of track b at future step h is modelled as
    ``N(0, g_b * R_b^T S_h R_b)``, where

    * ``R_b`` rotates world offsets into the track's (along-track, cross-track) frame, given by
      the direction of its CV velocity (a pedestrian's error along the walk, a speed change, and
      across it, a turn, differ in size);
    * ``S_h`` (H, 2, 2) is the error covariance per step in that frame, m^2;
    * ``g_b = exp(beta . phi_b)`` scales it per track from the features ``phi_b`` of
      :func:`cv_noise_features` (log squared speed, log mean squared acceleration of the
      history): a fast or erratic walker's future is less certain than a slow, steady one's.
      ``beta = 0`` is one covariance per step for every track (``heteroscedastic=False``).

    This is a heteroscedastic regression of the error covariance (as in the GLM-for-variance
    literature, e.g. Aitkin 1987, "Modelling variance heterogeneity in normal regression using
    GLIM"); it is fitted by maximum likelihood on (history, future) pairs the CV model did not
    see being scored on (a validation split): for fixed ``beta`` the MLE of ``S_h`` is the
    ``1/g``-weighted mean of ``R e e^T R^T`` (closed form), and ``beta`` maximises the profile
    likelihood (Nelder-Mead).

    Attributes:
        step_cov: (H, 2, 2) ``S_h``, m^2 (along-track, cross-track).
        beta: (2,) exponents of the two features (zeros when homoscedastic).
        n_fit: windows it was fitted on.
    """

    step_cov: np.ndarray
    beta: np.ndarray
    n_fit: int = 0

    def __post_init__(self) -> None:
        who = "CVNoise"
        S = check_array(self.step_cov, "step_cov", ("H", 2, 2), error=HistoryError, who=who)
        b = check_array(self.beta, "beta", (2,), error=HistoryError, who=who)
        det = S[:, 0, 0] * S[:, 1, 1] - S[:, 0, 1] * S[:, 1, 0]
        if not np.all((S[:, 0, 0] > 0) & (det > 0)) or not np.allclose(S, np.swapaxes(S, 1, 2)):
            raise HistoryError(f"{who}: step_cov must hold symmetric positive definite 2x2 "
                               f"matrices, found {S.tolist()}")
        object.__setattr__(self, "step_cov", S)
        object.__setattr__(self, "beta", b)

    @property
    def horizon(self) -> int:
        return int(self.step_cov.shape[0])

    def covariance(self, features: np.ndarray, rot: np.ndarray, horizon: int) -> np.ndarray:
        """(B, horizon, 2, 2) world covariances for features (B, 2) and rotations (B, 2, 2).

        Raises HistoryError: ``horizon`` beyond the fitted one.
        """
        if horizon > self.horizon:
            raise HistoryError(f"CVNoise: the noise model was fitted for {self.horizon} steps, "
                               f"asked for horizon {horizon}; fit it on futures of that length")
        g = np.exp(features @ self.beta)                                   # (B,)
        S = self.step_cov[:horizon]
        return g[:, None, None, None] * np.einsum("bji,hjk,bkl->bhil", rot, S, rot)

    @classmethod
    def fit(cls, errors: np.ndarray, features: np.ndarray, rot: np.ndarray, *,
            heteroscedastic: bool = True, max_iter: int = 400) -> "CVNoise":
        """Maximum-likelihood fit on world errors (N, H, 2) (NaN rows left out), features
        (N, 2) and rotations (N, 2, 2). See the class docstring."""
        from scipy.optimize import minimize

        e = np.einsum("nij,nhj->nhi", rot, errors)                        # along/cross frame
        seen = np.isfinite(e).all(axis=-1)                                 # (N, H)
        if np.any(seen.sum(axis=0) < 3):
            raise HistoryError("CVNoise.fit: every future step needs at least 3 observed "
                               f"errors, found {seen.sum(axis=0).tolist()}")
        e = np.where(seen[..., None], e, 0.0)
        n_h = seen.sum(axis=0)                                             # (H,)
        outer = np.einsum("nhi,nhj->nhij", e, e)                           # (N, H, 2, 2)
        phi = features - features.mean(axis=0)          # centred: S_h keeps the typical scale

        def profile(beta: np.ndarray) -> tuple[float, np.ndarray]:
            lg = phi @ beta                                                # (N,) log g
            S = np.einsum("n,nhij->hij", np.exp(-lg), outer) / n_h[:, None, None]
            S = S + 1e-9 * np.eye(2)
            Si = np.linalg.inv(S)
            d2 = np.einsum("nhi,hij,nhj->nh", e, Si, e) * np.exp(-lg)[:, None]
            nll = 0.5 * (d2 + 2 * lg[:, None] + np.linalg.slogdet(S)[1][None, :])
            return float(np.sum(np.where(seen, nll, 0.0)) / seen.sum()), S

        beta = np.zeros(2)
        if heteroscedastic:
            res = minimize(lambda b: profile(b)[0], beta, method="Nelder-Mead",
                           options={"maxiter": max_iter, "xatol": 1e-4, "fatol": 1e-8})
            beta = np.asarray(res.x, float)
        S = profile(beta)[1]
        # g = exp(beta . (phi - mean)) = exp(beta . phi) * exp(-beta . mean): fold the constant
        return cls(S * np.exp(-features.mean(axis=0) @ beta), beta, int(errors.shape[0]))


# --------------------------------------------------------------------------------------------
# Constant velocity
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ConstantVelocity:
    """Constant-velocity extrapolation from the last valid observation.

    Attributes:
        k: number of most recent *valid* observations the velocity is estimated from. ``k = 2``
            (default) is the published CVM: ``v = (x_j - x_i) / (j - i)`` for the last two valid
            frames ``i < j`` (``x_t - x_{t-1}`` when none is missing). ``k > 2`` fits a
            least-squares line position-vs-frame over the last ``k`` valid observations and
            uses its slope (less sensitive to measurement noise).
        name: label used in reports.
        noise: the :class:`CVNoise` model of its errors, set by :meth:`fit` (None until then);
            needed by :meth:`predict_distribution` only.

    Tracks with a single valid observation are predicted to stand still; tracks with none give
    NaN predictions.
    """

    k: int = 2
    name: str = "cvm"
    noise: CVNoise | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        if int(self.k) != self.k or self.k < 2:
            raise ValueError(f"ConstantVelocity.k: expected an integer >= 2, found {self.k!r}")

    def velocity(self, history: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Velocity per frame and index of the last valid observation.

        Args:
            history: (B, T, 2) positions, NaN rows missing.

        Returns:
            ``(v, last)``: v (B, 2) metres per frame (0 where fewer than two valid rows), last
            (B,) index of the last valid row (-1 where none).
        """
        h = check_history(history, 1, who=f"{self.name}.velocity")
        valid = _valid_rows(h)
        T = h.shape[1]
        # number of valid rows at or after each frame -> keep the last k valid ones
        from_end = np.cumsum(valid[:, ::-1], axis=1)[:, ::-1]
        w = (valid & (from_end <= self.k)).astype(float)               # (B, T)
        n = w.sum(axis=1)                                                # (B,)
        t = np.arange(T, dtype=float)
        x = np.where(valid[..., None], h, 0.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            t_mean = (w * t).sum(axis=1) / n                             # (B,)
            x_mean = (w[..., None] * x).sum(axis=1) / n[:, None]         # (B, 2)
            dt = (t[None, :] - t_mean[:, None]) * w                      # (B, T)
            sxx = (dt * dt).sum(axis=1)
            sxy = (dt[..., None] * (x - x_mean[:, None, :])).sum(axis=1)
            v = sxy / sxx[:, None]
        v = np.where((n >= 2)[:, None], v, 0.0)
        return v, last_valid_index(valid)

    def predict(self, history: np.ndarray, horizon: int) -> np.ndarray:
        """Extrapolate each track at constant velocity.

        Args:
            history: (B, T, 2) positions in metres, NaN rows missing.
            horizon: number of future frames.

        Returns:
            (B, horizon, 2): ``x_last + v * (T - 1 - last + h)``, h = 1..horizon.
        """
        h = check_history(history, horizon, who=f"{self.name}.predict")
        v, last = self.velocity(h)
        B, T, _ = h.shape
        x_last = h[np.arange(B), np.maximum(last, 0)]                   # (B, 2)
        x_last = np.where((last >= 0)[:, None], x_last, np.nan)
        steps = (T - 1 - last)[:, None] + np.arange(1, horizon + 1)[None, :]   # (B, horizon)
        return x_last[:, None, :] + steps[..., None] * v[:, None, :]

    # -- predictive distribution ---------------------------------------------------------------
    def fit(self, history: np.ndarray, future: np.ndarray, *,
            heteroscedastic: bool = True) -> "ConstantVelocity":
        """Fit the noise model of the forecast errors on (history, future) pairs.

        Use data the model will not be scored on (e.g. a validation split): the fitted
        covariances are what :meth:`predict_distribution` reports for new tracks.

        Args:
            history: (N, T, 2) observed positions in metres, NaN rows missing.
            future: (N, H, 2) the true next H positions (NaN rows are left out).
            heteroscedastic: scale each track's covariance by its speed and acceleration
                (:class:`CVNoise`); False fits one covariance per step for every track.

        Returns:
            A new :class:`ConstantVelocity` (same ``k``, ``name``) carrying the fitted
            :class:`CVNoise`; it predicts up to H steps ahead.

        Raises:
            HistoryError: malformed arrays, N differing, or a step with fewer than 3 truths.
        """
        who = f"{self.name}.fit"
        fut = check_array(future, "future", ("N", "H", 2), error=HistoryError, who=who,
                          allow_nan=True)
        h = check_history(history, fut.shape[1], who=who)
        if h.shape[0] != fut.shape[0]:
            raise HistoryError(f"{who}: history has {h.shape[0]} tracks, future {fut.shape[0]}")
        v, last = self.velocity(h)
        keep = last >= 0
        errors = fut[keep] - self.predict(h[keep], fut.shape[1])
        noise = CVNoise.fit(errors, cv_noise_features(h[keep], v[keep]), cv_error_frame(v[keep]),
                            heteroscedastic=heteroscedastic)
        return replace(self, noise=noise)

    def predict_distribution(self, history: np.ndarray, horizon: int) -> GaussianForecast:
        """Per-step Gaussian of the next ``horizon`` positions: mean :meth:`predict`,
        covariance from the fitted :class:`CVNoise` (rotated into each track's heading, scaled
        by its speed and acceleration).

        Args:
            history: (B, T, 2) positions in metres, NaN rows missing (each track needs at least
                one valid row).
            horizon: future steps, at most the horizon the noise model was fitted for.

        Returns:
            :class:`~blindspot.traj.distribution.GaussianForecast`, mean (B, horizon, 2) m,
            cov (B, horizon, 2, 2) m^2.

        Raises:
            HistoryError: not fitted (call :meth:`fit`), horizon beyond the fitted one, a track
                without a valid row, or malformed input.
        """
        who = f"{self.name}.predict_distribution"
        if self.noise is None:
            raise HistoryError(f"{who}: no noise model; fit it first with "
                               "ConstantVelocity.fit(history, future) on validation data")
        h = check_history(history, horizon, who=who)
        v, last = self.velocity(h)
        if np.any(last < 0):
            raise HistoryError(f"{who}: {int(np.sum(last < 0))} tracks have no valid row")
        cov = self.noise.covariance(cv_noise_features(h, v), cv_error_frame(v), horizon)
        return GaussianForecast(self.predict(h, horizon), cov)


@dataclass(frozen=True)
class KalmanCV:
    """Constant-velocity Kalman filter (prediction) and RTS smoother (gap filling).

    Attributes:
        dt: frame period in s (ETH/UCY: 0.4 s).
        process_psd: white-acceleration noise density q, m^2/s^3 (see :func:`cv_model`).
        meas_std: position measurement noise standard deviation, m.
        init_pos_std: prior std of the position around the first valid observation, m.
        init_vel_std: prior std of the velocity around 0, m/s (a pedestrian walks ~1.3 m/s).
        name: label used in reports.

    The prior of each track is centred on its first valid observation with zero velocity.
    """

    dt: float = 0.4
    process_psd: float = 0.5
    meas_std: float = 0.05
    init_pos_std: float = 1.0
    init_vel_std: float = 2.0
    name: str = "kalman"

    def __post_init__(self) -> None:
        cv_model(self.dt, self.process_psd, self.meas_std)   # validates the three values
        for key in ("init_pos_std", "init_vel_std"):
            check_positive(f"KalmanCV.{key}", getattr(self, key), "m" if "pos" in key else "m/s")

    # -- model --------------------------------------------------------------------------------
    def matrices(self) -> tuple[np.ndarray, ...]:
        """``(F, Q, H, R)`` of this model (see :func:`cv_model`)."""
        return cv_model(self.dt, self.process_psd, self.meas_std)

    def prior(self, tracks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Prior ``(m0 (B, 4), P0 (4, 4))``: first valid position, zero velocity.

        Tracks without any valid row get a NaN prior (their output is NaN).
        """
        valid = _valid_rows(tracks)
        first = np.argmax(valid, axis=1)
        pos = tracks[np.arange(tracks.shape[0]), first]
        pos = np.where(valid.any(axis=1)[:, None], pos, np.nan)
        m0 = np.hstack([pos, np.zeros_like(pos)])
        P0 = np.diag([self.init_pos_std**2] * 2 + [self.init_vel_std**2] * 2)
        return m0, P0

    def filter(self, history: np.ndarray) -> FilterResult:
        """Run the batched filter over (B, T, 2) tracks (NaN rows missing)."""
        h = check_history(history, 1, who=f"{self.name}.filter")
        F, Q, H, R = self.matrices()
        m0, P0 = self.prior(h)
        return kalman_filter(h, F, Q, H, R, m0, P0, error=HistoryError)

    # -- PathPredictor -------------------------------------------------------------------------
    def predict(self, history: np.ndarray, horizon: int) -> np.ndarray:
        """Filter the history, then propagate the last state mean ``horizon`` frames ahead.

        Args:
            history: (B, T, 2) positions in metres, NaN rows missing.
            horizon: number of future frames.

        Returns:
            (B, horizon, 2): ``p_T-1 + h dt v_T-1`` for h = 1..horizon (the mean of F^h s).
        """
        h = check_history(history, horizon, who=f"{self.name}.predict")
        state = self.filter(h).means[:, -1]                                  # (B, 4)
        lead = self.dt * np.arange(1, horizon + 1)[None, :, None]            # (1, horizon, 1)
        return state[:, None, :2] + lead * state[:, None, 2:]

    def predict_distribution(self, history: np.ndarray, horizon: int, *,
                             measured: bool = True) -> GaussianForecast:
        """The filter's own predictive distribution of the next ``horizon`` positions.

        From the last filtered state ``(m, P)`` the standard prediction step is applied h times
        (Bar-Shalom, Li & Kirubarajan 2001, *Estimation with Applications to Tracking and
        Navigation*, eq. 5.2.3-5): ``m_h = F^h m``, ``P_h = F P_(h-1) F^T + Q``; the position
        covariance is ``H P_h H^T``, plus ``R`` when ``measured`` (the truth compared against is
        itself a measured position, e.g. an annotation; False = the true position).

        Args:
            history: (B, T, 2) positions in metres, NaN rows missing.
            horizon: number of future frames.
            measured: add the measurement noise ``R`` (see above).

        Returns:
            :class:`~blindspot.traj.distribution.GaussianForecast`: mean (B, horizon, 2) in m
            (equal to :meth:`predict`), cov (B, horizon, 2, 2) in m^2.

        Raises:
            HistoryError: malformed history, or a track without any valid row (its state is
                undefined).
        """
        who = f"{self.name}.predict_distribution"
        h = check_history(history, horizon, who=who)
        res = self.filter(h)
        m, P = res.means[:, -1], res.covs[:, -1]                              # (B, 4), (B, 4, 4)
        if not np.isfinite(m).all():
            raise HistoryError(f"{who}: {int(np.sum(~np.isfinite(m).all(axis=1)))} tracks "
                               "have no valid row")
        return self.forecast_from_state(m, P, horizon, measured=measured)

    def forecast_from_state(self, m: np.ndarray, P: np.ndarray, horizon: int, *,
                            measured: bool = True) -> GaussianForecast:
        """The predictive distribution of the next ``horizon`` positions from filtered states
        ``m`` (B, 4) (x, y, vx, vy; m, m/s) and ``P`` (B, 4, 4) (the recursion of
        :meth:`predict_distribution`). Lets a caller that keeps each track's filtered state
        frame by frame (:meth:`filter` over the whole track once) predict from every frame
        without re-filtering its history."""
        F, Q, H, R = self.matrices()
        means = np.empty((m.shape[0], horizon, 2))
        covs = np.empty((m.shape[0], horizon, 2, 2))
        for k in range(horizon):                           # loop over the horizon only
            m = m @ F.T
            P = F @ P @ F.T + Q
            means[:, k] = m @ H.T
            covs[:, k] = H @ P @ H.T + (R if measured else 0.0)
        return GaussianForecast(means, covs)

    # -- gap filling ---------------------------------------------------------------------------
    def smooth(self, track: np.ndarray) -> np.ndarray:
        """Fill the gaps of one track with the Rauch-Tung-Striebel smoother (pykalman).

        Args:
            track: (T, 2) positions in metres, NaN rows missing (at least one valid row).

        Returns:
            (T, 2) smoothed positions at every frame, missing frames included.

        Raises:
            HistoryError: ``track`` not real (T, 2), an inf value, or no valid row.
        """
        from pykalman import KalmanFilter

        x = check_array(track, "track", ("T", 2), error=HistoryError, who=f"{self.name}.smooth",
                        allow_nan=True)
        valid = _valid_rows(x[None])[0]
        if not valid.any():
            raise HistoryError(f"{self.name}.smooth: the track has no valid (non-NaN) row to "
                               f"smooth from (T = {x.shape[0]})")
        F, Q, H, R = self.matrices()
        m0, P0 = self.prior(x[None])
        kf = KalmanFilter(transition_matrices=F, observation_matrices=H,
                          transition_covariance=Q, observation_covariance=R,
                          initial_state_mean=m0[0], initial_state_covariance=P0)
        masked = np.ma.masked_array(np.where(valid[:, None], x, 0.0),
                                    mask=np.repeat(~valid[:, None], 2, axis=1))
        means, _ = kf.smooth(masked)
        return np.asarray(means[:, :2])

    def smooth_batch(self, tracks: np.ndarray) -> np.ndarray:
        """The Rauch-Tung-Striebel smoother of :meth:`smooth` for B tracks at once (numpy).

        Forward pass :func:`kalman_filter`; backward pass (Rauch, Tung & Striebel 1965)
        ``m_s[t] = m_f[t] + C_t (m_s[t+1] - F m_f[t])``, ``C_t = P_f[t] F^T (F P_f[t] F^T +
        Q)^-1``, vectorised over tracks, a loop over frames only.

        Args:
            tracks: (B, T, 2) positions in metres, NaN rows missing.

        Returns:
            (B, T, 2) smoothed positions at every frame (NaN for a track with no valid row).
        """
        h = check_history(tracks, 1, who=f"{self.name}.smooth_batch")
        F, Q, _, _ = self.matrices()
        res = self.filter(h)
        m, P = res.means, res.covs                                       # (B, T, 4), (B, T, 4, 4)
        out = np.empty_like(m)
        out[:, -1] = m[:, -1]
        for t in range(h.shape[1] - 2, -1, -1):
            pred_P = F @ P[:, t] @ F.T + Q
            C = P[:, t] @ F.T @ np.linalg.inv(pred_P)
            out[:, t] = m[:, t] + np.einsum("bij,bj->bi", C, out[:, t + 1] - m[:, t] @ F.T)
        return out[..., :2]

    # -- fitting -------------------------------------------------------------------------------
    def log_likelihood(self, tracks: np.ndarray) -> float:
        """Total log-likelihood of (B, T, 2) tracks under this model (NaN rows missing)."""
        ll = self.filter(tracks).loglik
        return float(ll[np.isfinite(ll)].sum())

    def fit(self, tracks: np.ndarray, *, objective: str = "likelihood", obs_len: int = 8,
            max_tracks: int | None = 5000, seed: int = 0, max_iter: int = 300) -> "KalmanCV":
        """Fit ``process_psd`` and ``meas_std`` on training tracks.

        Args:
            tracks: (B, T, 2) training tracks, NaN rows missing.
            objective: ``"likelihood"`` - maximise the innovation log-likelihood of the whole
                tracks (the statistically proper fit); ``"forecast"`` - minimise the mean
                time-aligned error (ADE) of predicting ``tracks[:, obs_len:]`` from
                ``tracks[:, :obs_len]`` (the fit that serves prediction; on data whose
                annotations are nearly noise-free the likelihood fit drives ``meas_std`` to
                its floor and the filter's endpoint velocity overshoots).
            obs_len: observed frames per track for ``objective="forecast"``.
            max_tracks: fit on at most this many tracks, drawn with ``seed`` (None = all).
            seed: seed of that draw.
            max_iter: optimiser iterations.

        ``"likelihood"`` searches both noise levels (Nelder-Mead in log space); ``"forecast"``
        holds ``meas_std`` and searches ``process_psd`` alone (bounded scalar search), because
        the predicted mean depends on them only through ``process_psd / meas_std**2`` and the
        prior. Values are clipped to ``process_psd`` in [1e-4, 1e2] m^2/s^3 and ``meas_std`` in
        [1e-3, 1] m. Deterministic for a seed.

        Returns:
            A new :class:`KalmanCV` with the fitted values (dt and priors unchanged).
        """
        from scipy.optimize import minimize, minimize_scalar

        from blindspot.traj.metrics import ade

        if objective not in ("likelihood", "forecast"):
            raise ValueError(f"KalmanCV.fit objective: expected 'likelihood' or 'forecast', "
                             f"found {objective!r}")
        h = check_history(tracks, 1, who=f"{self.name}.fit")
        if objective == "forecast" and not 2 <= obs_len < h.shape[1]:
            raise HistoryError(f"{self.name}.fit: obs_len must be in [2, T-1] = [2, "
                               f"{h.shape[1] - 1}], found {obs_len}")
        min_rows = 2 if objective == "likelihood" else 1
        keep = _valid_rows(h[:, :obs_len] if objective == "forecast" else h).sum(axis=1)
        h = h[keep >= min_rows]
        if h.shape[0] == 0:
            raise HistoryError(f"{self.name}.fit: no track has enough valid rows to fit on")
        if max_tracks is not None and h.shape[0] > max_tracks:
            pick = np.random.default_rng(seed).choice(h.shape[0], size=max_tracks, replace=False)
            h = h[np.sort(pick)]
        n_obs = max(int(_valid_rows(h).sum()), 1)
        lo, hi = np.log([1e-4, 1e-3]), np.log([1e2, 1.0])

        def model_at(theta: np.ndarray) -> "KalmanCV":
            q, r = np.exp(np.clip(theta, lo, hi))
            return replace(self, process_psd=float(q), meas_std=float(r))

        def loss(theta: np.ndarray) -> float:
            model = model_at(theta)
            if objective == "likelihood":
                return -model.log_likelihood(h) / n_obs
            pred = model.predict(h[:, :obs_len], h.shape[1] - obs_len)
            return ade(pred, h[:, obs_len:])

        if objective == "forecast":
            # the predicted mean depends on the noise levels only through q / r^2 (and the
            # prior): hold meas_std, search process_psd on a bounded log scale
            res1 = minimize_scalar(lambda lq: loss(np.array([lq, np.log(self.meas_std)])),
                                   bounds=(lo[0], hi[0]), method="bounded",
                                   options={"xatol": 1e-3, "maxiter": max_iter})
            q = float(np.exp(np.clip(res1.x, lo[0], hi[0])))
            return replace(self, process_psd=q)
        x0 = np.clip(np.log([self.process_psd, self.meas_std]), lo, hi)
        res = minimize(loss, x0, method="Nelder-Mead",
                       options={"maxiter": max_iter, "xatol": 1e-3, "fatol": 1e-7})
        return model_at(res.x)


def kalman_baseline(ev, dt: float) -> KalmanCV:
    """The constant-velocity Kalman baseline of ``eval.kalman`` (``ev``: an
    :class:`~blindspot.traj.config.EvalConfig`) at the frame period ``dt`` (s)."""
    k = ev.kalman
    return KalmanCV(dt=dt, process_psd=k.process_psd, meas_std=k.meas_std)


def prediction_methods(ev, dt: float, lstm=None) -> dict:
    """The prediction methods of ``eval.prediction_methods`` by name (``ev``: an
    :class:`~blindspot.traj.config.EvalConfig`, ``dt`` the frame period in s, ``lstm`` the scene
    LSTM or None). Raises ValueError naming the key for a method that is not available."""
    made = {
        "lstm": lstm,
        "constant_velocity": ConstantVelocity(k=ev.cv_fit_points, name="constant_velocity"),
        "kalman": kalman_baseline(ev, dt),
    }
    out = {}
    for name in ev.prediction_methods:
        if name not in made or made[name] is None:
            raise ValueError(f"config key 'eval.prediction_methods' lists {name!r}: expected names "
                             f"from {sorted(k for k, v in made.items() if v is not None)}")
        out[name] = made[name]
    return out
