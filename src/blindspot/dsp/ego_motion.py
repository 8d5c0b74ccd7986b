"""Ego-motion from the radar's own detections, and ego-speed-aided Doppler unwrapping.

Static world seen from a moving radar (Kellner et al. 2013, "Instantaneous ego-motion
estimation using Doppler radar", IEEE ITSC): a radar moving with velocity (v_x, v_y) in its own
frame (boresight +y, x to the right, azimuth theta positive towards +x) sees a static scatterer
at azimuth theta with radial velocity

    v_r = -(v_x sin theta + v_y cos theta) = -v cos(theta - heading)

(v = |(v_x, v_y)|, heading = atan2(v_x, v_y); negative = approaching). For a radar moving along
its boresight (heading 0) this is ``v_r = -v cos(theta)``. Every static detection of a frame lies
on this curve; moving objects (pedestrians) do not, so a robust fit of the linear model
``v_r = a cos(theta) + b sin(theta)`` (no intercept) with scikit-learn's RANSACRegressor (Fischler
and Bolles 1981) gives ``(a, b) = (-v_y, -v_x)`` and the inlier mask of the static detections.
Elevation is neglected (scatterers near the radar's height; at elevation phi the curve scales by
cos phi).

Yaw rate (Kellner et al. 2013, single radar): with Ackermann steering and no side slip the rear
axle centre moves along the car's heading at speed v, and a radar mounted ``l`` ahead of it on
the centre line (boresight along the heading) moves at ``(v_x, v_y) = (-omega l, v)`` in its own
frame (omega positive = turning left, counter-clockwise seen from above; x to the right). So one
frame's fit gives ``v = v_y`` and ``omega = -v_x / l`` (:func:`estimate_ego_motion`). The
estimate's variance follows from the least-squares fit on the static detections
(:func:`ego_motion_std`): ``Cov(v_x, v_y) = sigma^2 (X^T X)^-1`` with rows
``X_i = (sin theta_i, cos theta_i)``, so ``sd(omega) ~ sigma / (l sqrt(sum sin^2 theta_i))``:
it shrinks with the static points' angular spread and the mounting lever arm.

Doppler unwrapping: a TDM-MIMO Doppler FFT measures radial velocity modulo ``2 v_max``
(``v_max = lambda / (4 T_loop)``; ``RadarConfig.max_velocity_mps``). Given the ego speed (from
odometry, with its noise and bias, see :func:`odometry_speed`), each wrapped measurement is moved
by the multiple of ``2 v_max`` that brings it nearest the static world's value at its azimuth.
Static detections then land on the curve; a moving one lands right as long as its radial
velocity differs from the static world's at its azimuth by less than ``v_max``.
"""

from __future__ import annotations

import numpy as np

from blindspot.arrays import check_same_shape, checked_array
from blindspot.dsp.config import EgoMotionConfig  # noqa: F401 - re-exported

__all__ = [
    "EgoMotionConfig", "EgoMotionError", "static_radial_velocity", "unwrap_doppler", "ambiguity_order",
    "estimate_ego_speed", "estimate_sensor_velocity", "estimate_ego_motion", "ego_motion_std",
    "static_mask", "odometry_speed",
]


class EgoMotionError(ValueError):
    """Per-detection arrays of the wrong shape or kind, not finite, or a bad speed/threshold."""


def _values(where: str, name: str, value) -> np.ndarray:
    return checked_array(value, name, EgoMotionError, where=where, kind="real", ndim=1,
                         axes=f"{name} (n,) one value per detection").astype(np.float64, copy=False)


def _scalar(where: str, name: str, value, *, positive: bool = False, nonnegative: bool = False) -> float:
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    if not ok or not np.isfinite(value) or (positive and value <= 0) or (nonnegative and value < 0):
        need = "a finite positive number" if positive else (
            "a finite non-negative number" if nonnegative else "a finite number")
        raise EgoMotionError(f"{where}: {name} must be {need}; found {value!r}")
    return float(value)


def static_radial_velocity(azimuth_deg: np.ndarray, speed_mps: float, heading_deg: float = 0.0
                           ) -> np.ndarray:
    """Radial velocity (m/s) of static scatterers at ``azimuth_deg`` (...) seen from a radar
    moving at ``speed_mps`` towards ``heading_deg`` (0 = boresight): ``-v cos(theta - heading)``
    (Kellner et al. 2013)."""
    return -speed_mps * np.cos(np.radians(np.asarray(azimuth_deg, float) - heading_deg))


def ambiguity_order(radial_velocity_mps: np.ndarray, azimuth_deg: np.ndarray,
                    ego_speed_mps: float, v_max_mps: float) -> np.ndarray:
    """(n,) int: the number k of ``2 v_max`` to add to each wrapped measurement so that it lands
    nearest the static world's value ``-v_ego cos(theta)`` (see :func:`unwrap_doppler`)."""
    where = "ambiguity_order"
    v = _values(where, "radial_velocity_mps", radial_velocity_mps)
    az = _values(where, "azimuth_deg", azimuth_deg)
    check_same_shape(EgoMotionError, where, "the per-detection arrays", radial_velocity_mps=v,
                     azimuth_deg=az)
    ego = _scalar(where, "ego_speed_mps", ego_speed_mps)
    vmax = _scalar(where, "v_max_mps", v_max_mps, positive=True)
    return np.rint((static_radial_velocity(az, ego) - v) / (2 * vmax)).astype(np.int64)


def unwrap_doppler(radial_velocity_mps: np.ndarray, azimuth_deg: np.ndarray,
                   ego_speed_mps: float, v_max_mps: float) -> np.ndarray:
    """Unwrapped radial velocities (n,), m/s.

    Args:
        radial_velocity_mps: (n,) wrapped measurements in [-v_max, v_max), m/s (negative =
            approaching).
        azimuth_deg: (n,) azimuth of each detection, 0 = boresight, positive towards +x.
        ego_speed_mps: forward speed of the radar along its boresight (odometry), m/s.
        v_max_mps: the profile's unambiguous speed ``lambda / (4 T_loop)``, m/s.

    Returns:
        each measurement moved by the multiple of ``2 v_max`` that brings it nearest the static
        world's ``-v_ego cos(theta)`` (ties: the nearest even rounding of numpy's ``rint``).

    Raises:
        EgoMotionError: arrays not (n,) of one length or not finite, or a speed not finite, or
        ``v_max_mps`` not positive.
    """
    k = ambiguity_order(radial_velocity_mps, azimuth_deg, ego_speed_mps, v_max_mps)
    return np.asarray(radial_velocity_mps, float) + 2.0 * float(v_max_mps) * k


def _ransac(where: str, v: np.ndarray, az: np.ndarray, threshold_mps: float, min_inliers: int,
            seed: int, max_trials: int):
    from sklearn.linear_model import LinearRegression, RANSACRegressor

    th = _scalar(where, "threshold_mps", threshold_mps, positive=True)
    if not (isinstance(min_inliers, (int, np.integer)) and min_inliers >= 2):
        raise EgoMotionError(f"{where}: min_inliers must be an integer >= 2; found {min_inliers!r}")
    if v.size < min_inliers:
        return None
    theta = np.radians(az)
    x = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    model = RANSACRegressor(LinearRegression(fit_intercept=False), min_samples=2,
                            residual_threshold=th, max_trials=max_trials, random_state=seed)
    try:
        model.fit(x, v)
    except ValueError:  # RANSAC found no consensus set (sklearn raises ValueError)
        return None
    inliers = model.inlier_mask_.copy()
    if inliers.sum() < min_inliers:
        return None
    a, b = model.estimator_.coef_
    return a, b, inliers


def estimate_sensor_velocity(radial_velocity_mps: np.ndarray, azimuth_deg: np.ndarray, *,
                             threshold_mps: float = 0.25, min_inliers: int = 4, seed: int = 0,
                             max_trials: int = 200) -> tuple[float, float, np.ndarray]:
    """The radar's velocity (v_x, v_y) in its own frame from one frame's detections (Kellner et
    al. 2013), robustly: RANSAC (scikit-learn) on ``v_r = -(v_x sin theta + v_y cos theta)``,
    then least squares on the consensus set.

    Args:
        radial_velocity_mps, azimuth_deg: (n,) unwrapped radial velocities (m/s) and azimuths
            (deg) of the frame's detections.
        threshold_mps: largest residual of a static detection (about the velocity resolution
            plus the angle error's effect ``v sin(theta) d_theta``).
        min_inliers: fewer static detections than this give NaN.
        seed: RANSAC's random state (the same input gives the same answer).

    Returns:
        (v_x, v_y) m/s and the (n,) bool inlier mask; NaN, NaN and all False when no
        consensus of ``min_inliers`` detections is found.

    Raises:
        EgoMotionError: bad arrays or settings.
    """
    where = "estimate_sensor_velocity"
    v = _values(where, "radial_velocity_mps", radial_velocity_mps)
    az = _values(where, "azimuth_deg", azimuth_deg)
    check_same_shape(EgoMotionError, where, "the per-detection arrays", radial_velocity_mps=v,
                     azimuth_deg=az)
    fit = _ransac(where, v, az, threshold_mps, min_inliers, seed, max_trials)
    if fit is None:
        return float("nan"), float("nan"), np.zeros(v.size, dtype=bool)
    a, b, inliers = fit
    return float(-b), float(-a), inliers


def estimate_ego_speed(radial_velocity_mps: np.ndarray, azimuth_deg: np.ndarray, *,
                       threshold_mps: float = 0.25, min_inliers: int = 4, seed: int = 0,
                       max_trials: int = 200) -> tuple[float, np.ndarray]:
    """Forward speed of a radar moving along its boresight, from one frame's detections.

    Args:
        radial_velocity_mps: (n,) unwrapped radial velocities, m/s (negative = approaching).
        azimuth_deg: (n,) azimuths, deg (0 = boresight).
        threshold_mps, min_inliers, seed, max_trials: see :func:`estimate_sensor_velocity`.

    Returns:
        (speed_mps, inliers): the forward speed ``-a`` of the RANSAC fit of
        ``v_r = a cos(theta) + b sin(theta)`` (Kellner et al. 2013; ``b`` absorbs a small
        misalignment of the boresight) and the (n,) bool mask of the static detections; NaN and
        all False without a consensus of ``min_inliers``.

    Raises:
        EgoMotionError: arrays not (n,) of one length or not finite, or bad settings.
    """
    vx, vy, inliers = estimate_sensor_velocity(radial_velocity_mps, azimuth_deg,
                                               threshold_mps=threshold_mps,
                                               min_inliers=min_inliers, seed=seed,
                                               max_trials=max_trials)
    return vy, inliers


def estimate_ego_motion(radial_velocity_mps: np.ndarray, azimuth_deg: np.ndarray,
                        rear_axle_to_radar_m: float, *, threshold_mps: float = 0.25,
                        min_inliers: int = 4, seed: int = 0, max_trials: int = 200
                        ) -> tuple[float, float, np.ndarray]:
    """Ego speed and yaw rate from one radar's detections of one frame (Kellner et al. 2013).

    Args:
        radial_velocity_mps, azimuth_deg: (n,) unwrapped radial velocities (m/s, negative =
            approaching) and azimuths (deg, 0 = boresight = the car's heading).
        rear_axle_to_radar_m: the radar's distance ahead of the rear axle centre on the centre
            line, m (> 0).
        threshold_mps, min_inliers, seed, max_trials: see :func:`estimate_sensor_velocity`.

    Returns:
        (speed_mps, yaw_rate_rad_s, inliers): ``v = v_y`` and ``omega = -v_x / l`` of the
        RANSAC fit (module docstring; positive = turning left), the (n,) bool mask of the
        static detections; NaN, NaN and all False without a consensus.

    Raises:
        EgoMotionError: bad arrays or settings (``rear_axle_to_radar_m`` not positive).
    """
    el = _scalar("estimate_ego_motion", "rear_axle_to_radar_m", rear_axle_to_radar_m,
                 positive=True)
    vx, vy, inliers = estimate_sensor_velocity(radial_velocity_mps, azimuth_deg,
                                               threshold_mps=threshold_mps,
                                               min_inliers=min_inliers, seed=seed,
                                               max_trials=max_trials)
    return vy, -vx / el, inliers


def ego_motion_std(azimuth_deg: np.ndarray, residual_sd_mps: float, rear_axle_to_radar_m: float
                   ) -> tuple[float, float]:
    """Standard deviations of the speed (m/s) and yaw rate (rad/s) that the least-squares fit
    of :func:`estimate_ego_motion` on static detections at ``azimuth_deg`` (n,) has when their
    radial velocities scatter with ``residual_sd_mps``: the diagonal of
    ``sigma^2 (X^T X)^-1``, ``X_i = (sin theta_i, cos theta_i)`` (ordinary least squares; the
    yaw rate's is the lateral velocity's divided by the lever arm ``l``). (inf, inf) with
    fewer than two distinct angles."""
    where = "ego_motion_std"
    th = np.radians(_values(where, "azimuth_deg", azimuth_deg))
    sd = _scalar(where, "residual_sd_mps", residual_sd_mps, nonnegative=True)
    el = _scalar(where, "rear_axle_to_radar_m", rear_axle_to_radar_m, positive=True)
    x = np.stack([np.sin(th), np.cos(th)], axis=1)
    g = x.T @ x
    if th.size < 2 or np.linalg.cond(g) > 1e12:
        return float("inf"), float("inf")
    cov = sd**2 * np.linalg.inv(g)
    return float(np.sqrt(cov[1, 1])), float(np.sqrt(cov[0, 0]) / el)


def static_mask(radial_velocity_mps: np.ndarray, azimuth_deg: np.ndarray, ego_speed_mps: float,
                tolerance_mps: float) -> np.ndarray:
    """(n,) bool: detections on the static world's Doppler curve ``-v_ego cos(theta)`` within
    ``tolerance_mps`` (static clutter on a moving car: not zero Doppler)."""
    where = "static_mask"
    v = _values(where, "radial_velocity_mps", radial_velocity_mps)
    az = _values(where, "azimuth_deg", azimuth_deg)
    check_same_shape(EgoMotionError, where, "the per-detection arrays", radial_velocity_mps=v,
                     azimuth_deg=az)
    tol = _scalar(where, "tolerance_mps", tolerance_mps, nonnegative=True)
    ego = _scalar(where, "ego_speed_mps", ego_speed_mps)
    return np.abs(v - static_radial_velocity(az, ego)) <= tol


def odometry_speed(true_speed_mps: np.ndarray, noise_std_mps: float, bias_mps: float,
                   rng: np.random.Generator) -> np.ndarray:
    """Wheel-odometry speed readings (...) m/s: truth + bias + N(0, noise_std^2) per reading."""
    t = np.asarray(true_speed_mps, dtype=float)
    sd = _scalar("odometry_speed", "noise_std_mps", noise_std_mps, nonnegative=True)
    bias = _scalar("odometry_speed", "bias_mps", bias_mps)
    return t + bias + sd * rng.standard_normal(t.shape)
