"""The one Kalman filter of blindspot, below every room (``.importlinter``): the path
baselines (traj.baselines.KalmanCV), the oracle tracks (safety.oracle) and the tracker's hot path
(track.tracker._numpy_kalman, these steps in Stone Soup's types) all use it.

:func:`kalman_filter` runs batches over time with missing rows; :func:`predict`,
:func:`measurement_moments` and :func:`update` step one state. Both share the prediction
(:func:`predict_covariance`); their corrections are the same equations (K = P H^T S^-1) in the
two arithmetic orders the outputs' bytes were made with: the batch inverts S and takes
``(I - K H) P``, the step solves for K and takes ``P - K S K^T``, symmetrised. pykalman's RTS
smoother stays for gap filling (``KalmanCV.smooth``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from blindspot.arrays import check_array

__all__ = ["KalmanError", "FilterResult", "cv_model", "check_positive", "kalman_filter",
           "predict", "predict_covariance", "measurement_moments", "update"]


class KalmanError(ValueError):
    """An argument handed to the Kalman filter is malformed."""


def predict_covariance(P: np.ndarray, F: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """``F P F^T + Q``: the predicted covariance; P (..., n, n)."""
    return F @ P @ F.T + Q


def predict(x: np.ndarray, P: np.ndarray, F: np.ndarray,
            Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One prediction step of a state (x (n, 1), P (n, n)): ``(F x, F P F^T + Q)``."""
    return F @ x, predict_covariance(P, F, Q)


def measurement_moments(x: np.ndarray, P: np.ndarray, H: np.ndarray,
                        R: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(H x (d, 1), S = H P H^T + R (d, d), P H^T (n, d))`` of a predicted state (R = 0.0:
    the predicted true position, without measurement noise)."""
    PHt = P @ H.T
    return H @ x, H @ PHt + R, PHt


def update(x: np.ndarray, P: np.ndarray, z: np.ndarray, zhat: np.ndarray, S: np.ndarray,
           PHt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One correction of a predicted state (x (n, 1), P (n, n)) by the measurement z (d, 1),
    given its moments (:func:`measurement_moments`): ``K = P H^T S^-1``, ``x + K (z - zhat)``,
    ``P - K S K^T`` made symmetric. Stacks of states (leading axes on every argument) are
    corrected together, each with the same bytes as alone (tests/test_kalman.py)."""
    K = np.swapaxes(np.linalg.solve(S, np.swapaxes(PHt, -1, -2)), -1, -2)  # P H^T S^-1
    x = x + K @ (z - zhat)
    P = P - K @ S @ np.swapaxes(K, -1, -2)
    return x, (P + np.swapaxes(P, -1, -2)) / 2


def cv_model(dt: float, process_psd: float, meas_std: float) -> tuple[np.ndarray, ...]:
    """Matrices of the 2-D constant-velocity model with continuous white-noise acceleration.

    State ``s = (x, y, vx, vy)`` in m and m/s; observation ``z = (x, y)`` in m.

    Args:
        dt: frame period in seconds.
        process_psd: power spectral density ``q`` of the white acceleration noise, m^2/s^3
            (per axis); ``Q = q [[dt^3/3, dt^2/2], [dt^2/2, dt]]`` per axis.
        meas_std: standard deviation of each position coordinate's measurement noise, m.

    Returns:
        ``(F (4, 4), Q (4, 4), H (2, 4), R (2, 2))``.
    """
    for key, value, unit in (("dt", dt, "s"), ("process_psd", process_psd, "m^2/s^3"),
                             ("meas_std", meas_std, "m")):
        check_positive(f"KalmanCV.{key}", value, unit)
    I2 = np.eye(2)
    F = np.block([[I2, dt * I2], [np.zeros((2, 2)), I2]])
    Q = process_psd * np.block([[dt**3 / 3 * I2, dt**2 / 2 * I2], [dt**2 / 2 * I2, dt * I2]])
    H = np.hstack([I2, np.zeros((2, 2))])
    R = meas_std**2 * I2
    return F, Q, H, R


def check_positive(key: str, value, unit: str) -> None:
    """A finite real number > 0 (not a bool, string or complex), else ValueError naming key."""
    if (isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer,
                                                                     np.floating))
            or not np.isfinite(value) or not value > 0):
        raise ValueError(f"{key}: expected a finite number > 0 ({unit}), found {value!r}")


def _unique_rows(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct rows of a boolean (B, T) mask and each row's index into them."""
    packed = np.ascontiguousarray(np.packbits(mask, axis=1))            # (B, ceil(T/8)) uint8
    keys = packed.view(np.dtype((np.void, packed.shape[1]))).reshape(-1)
    _, first, which = np.unique(keys, return_index=True, return_inverse=True)
    return mask[first], which.reshape(-1)


class FilterResult(NamedTuple):
    """Output of :func:`kalman_filter`.

    means: (B, T, n) filtered state means; covs: (B, T, n, n) filtered covariances;
    loglik: (B,) log-likelihood of each sequence's observed rows.
    """

    means: np.ndarray
    covs: np.ndarray
    loglik: np.ndarray


def kalman_filter(obs: np.ndarray, F: np.ndarray, Q: np.ndarray, H: np.ndarray, R: np.ndarray,
                  m0: np.ndarray, P0: np.ndarray, *,
                  error: type[Exception] = KalmanError) -> FilterResult:
    """Batched linear Kalman filter with missing observations (same recursion as pykalman).

    At t = 0 the prior is ``(m0, P0)``; each step then predicts with ``F, Q`` and corrects with
    the observation unless the row holds a NaN (missing: the prediction is kept). The loop runs
    over time only. The covariances and gains depend only on *which* frames are observed, not on
    the values, so they are computed once per distinct missing-frame pattern (one pattern for
    fully observed windows) and shared by all sequences with that pattern.

    Args:
        obs: (B, T, d) observations, NaN rows missing.
        F: (n, n) transition; Q: (n, n) process covariance; H: (d, n) observation matrix;
            R: (d, d) measurement covariance.
        m0: (B, n) or (n,) prior mean at t = 0; P0: (n, n) prior covariance (shared).

    Returns:
        :class:`FilterResult` with filtered means (B, T, n), covariances (B, T, n, n) and the
        per-sequence log-likelihood (B,) (sum over observed rows of log N(z_t; H m_t|t-1, S_t)).

    Raises:
        error (default :class:`KalmanError`): an argument not real, of the wrong shape, or not
            finite (``obs`` and ``m0`` may hold NaN: missing rows, tracks without a valid row).
    """
    who = "kalman_filter"
    F = check_array(F, "F", ("n", "n"), error=error, who=who)
    n = F.shape[0]
    Q = check_array(Q, "Q", (n, n), error=error, who=who)
    H = check_array(H, "H", ("d", n), error=error, who=who)
    z = check_array(obs, "obs", ("B", "T", H.shape[0]), error=error, who=who,
                    allow_nan=True)
    B, T, d = z.shape
    R = check_array(R, "R", (d, d), error=error, who=who)
    m0 = check_array(m0, "m0", ("...", n), error=error, who=who, allow_nan=True)
    P0 = check_array(P0, "P0", (n, n), error=error, who=who)
    if m0.shape not in ((n,), (B, n)):
        raise error(f"{who}: m0 must be ({n},) or ({B}, {n}), found {m0.shape}")
    observed = np.isfinite(z).all(axis=-1)                               # (B, T)
    patterns, which = _unique_rows(observed)                             # (U, T), (B,)
    U = patterns.shape[0]
    eye = np.eye(n)

    # covariance recursion, once per observation pattern
    P = np.broadcast_to(P0, (U, n, n)).copy()
    gains = np.zeros((T, U, n, d))
    S_inv_all = np.empty((T, U, d, d))
    logdet_all = np.empty((T, U))
    covs_u = np.empty((T, U, n, n))
    for t in range(T):
        if t > 0:
            P = predict_covariance(P, F, Q)
        S = H @ P @ H.T + R                                              # (U, d, d)
        S_inv = np.linalg.inv(S)
        K = P @ H.T @ S_inv                                              # (U, n, d)
        upd = patterns[:, t]
        P = np.where(upd[:, None, None], (eye - K @ H) @ P, P)
        gains[t] = np.where(upd[:, None, None], K, 0.0)
        S_inv_all[t] = S_inv
        logdet_all[t] = np.linalg.slogdet(S)[1]
        covs_u[t] = P

    # mean recursion, all sequences together
    m = np.broadcast_to(np.asarray(m0, float), (B, n)).copy()
    means = np.empty((B, T, n))
    loglik = np.zeros(B)
    for t in range(T):
        if t > 0:
            m = m @ F.T
        innov = np.where(observed[:, t, None], z[:, t], 0.0) - m @ H.T   # (B, d)
        m = m + np.einsum("bij,bj->bi", gains[t][which], innov)
        maha = np.einsum("bi,bij,bj->b", innov, S_inv_all[t][which], innov)
        ll = -0.5 * (maha + logdet_all[t][which] + d * np.log(2 * np.pi))
        loglik += np.where(observed[:, t], ll, 0.0)
        means[:, t] = m
    covs = np.moveaxis(covs_u, 0, 1)[which]                              # (B, T, n, n)
    return FilterResult(means, covs, loglik)
