"""Silent tracks of a sensor with a Doppler notch: coasting through it, or stopped in it.

A radar that drops its static clutter on the sensor (TI's people-counting demo removes the
zero-Doppler bin) or in the reader (a recording's ``static_speed_mps``) reports no point whose
radial speed over ground lies inside its notch, |u.v| < v_min. A person who stops there, or walks
across the line of sight, goes silent: a constant-velocity track coasts on with the radial speed
it last had, walks away from them and is deleted after ``tracker.max_misses``, and the person
gets a new track when they walk off.

Two answers, both used by :func:`blindspot.track.track_points` with ``min_detectable_speed_mps``:

* **Coasting through the notch.** A frame without a detection is negative information (Koch
  2007, "On exploiting 'negative' sensor evidence for target tracking and sensor data fusion",
  Information Fusion 8(1)). Its likelihood is 1 - P_D outside the notch and 1 inside it, so the
  predicted Gaussian becomes a mixture of itself (weight 1 - P_D) and its part inside the notch
  (weight P_D p_in); :func:`notch_update` collapses it to one Gaussian by moment matching (the
  radial speed's truncated-normal moments, carried to the state by its linear regression on
  it). The radial speed is drawn into the notch, the tangential one kept: a walker crossing the
  line of sight keeps walking.
* **Stopped in the notch.** The move-stop-move targets of GMTI tracking (Kirubarajan &
  Bar-Shalom 2003, "Tracking evasive move-stop-move targets with a GMTI radar using a VS-IMM
  estimator", IEEE Trans. AES 39(3)) have a stopped mode: zero velocity, no process noise. A
  track whose silence outlasts its coasting time is not deleted but stopped, held where it was
  last detected (:func:`held_state`), when what was last seen of it says it was stopping: its
  last object's radial speed inside the notch within its error (:func:`seen_slowing`) and its
  filtered velocity then consistent with standing (:func:`still`). An object last seen moving
  (one that vanished at speed, a walker crossing the line of sight faster than about 1 m/s) is
  deleted as before. A stopped track is held at most ``tracker.max_stop_s``; a detection ends
  its stop, and it walks off with the constant-velocity model's process noise.

The decisions are hard ones, without an IMM's mode probabilities. With 0.12-0.15 m of
measurement noise the filtered velocity across the line of sight is known to a few tenths of a
m/s, so a walker slower than about 0.7-0.9 m/s who vanishes there is taken for one who stopped,
and held. A sensor that reports its static points (the driving chain) has no notch.
"""

from __future__ import annotations

import numbers

import numpy as np
from scipy.stats import chi2, norm

from blindspot.arrays import check_number

__all__ = ["SLOWING_TEST_PROBABILITY", "held_state", "notch_split",
           "notch_update", "seen_slowing", "still"]

#: Probability of the stop tests (:func:`seen_slowing`, two-sided; :func:`still`): a track is
#: stopping unless what was last seen of it lies beyond this quantile.
SLOWING_TEST_PROBABILITY = 0.95


def _check_states(x: np.ndarray, P: np.ndarray, who: str) -> tuple[np.ndarray, np.ndarray]:
    x = np.asarray(x, float)
    P = np.asarray(P, float)
    if x.ndim != 2 or x.shape[1] != 4 or P.shape != (len(x), 4, 4):
        raise ValueError(f"{who}: states x (K, 4) and P (K, 4, 4) as [x, vx, y, vy]; found "
                         f"x {x.shape}, P {P.shape}")
    return x, P


def _check_speed(value: float, name: str, who: str) -> None:
    check_number(value, name, gt=0.0, unit="m/s", who=who)


def _check_probability(value: float, who: str, *, name: str = "probability") -> None:
    if not (isinstance(value, numbers.Real) and 0.0 < value < 1.0):
        raise ValueError(f"{who}: {name} must be a number in (0, 1); found {value!r}")


def notch_split(x: np.ndarray, P: np.ndarray, sensor_xy, min_speed_mps: float):
    """A Gaussian state conditioned on its radial speed over ground r = u.v lying inside the
    notch |r| < ``min_speed_mps`` (u the unit line of sight from ``sensor_xy`` to the state's
    position, held at the mean: the linearisation of
    :func:`blindspot.track.tracker._range_rate_update`).

    The radial speed's truncated-normal moments are exact; the rest of the state follows by its
    linear regression on r (exact for a Gaussian conditioned on a linear function of itself).

    Args:
        x, P: (K, 4), (K, 4, 4) states ``[x, vx, y, vy]`` (m, m/s).
        sensor_xy: the sensor's position (m, 2 values).
        min_speed_mps: the notch's half-width (m/s, > 0).

    Returns:
        ``(p_in, x_in, P_in)``: the prior probability of the notch (K,) and the conditioned
        states. Where the notch has (numerically) no mass, or the state sits at the sensor
        (p_in 0 there), the state is the prior.
    """
    x, P = _check_states(x, P, "notch_split")
    _check_speed(min_speed_mps, "min_speed_mps", "notch_split")
    sensor = np.asarray(sensor_xy, float)
    if sensor.shape != (2,) or not np.isfinite(sensor).all():
        raise ValueError(f"notch_split: sensor_xy must be a finite position (x, y) in m; found "
                         f"{sensor_xy!r}")
    los = x[:, [0, 2]] - sensor[None, :]
    rng = np.hypot(los[:, 0], los[:, 1])
    h = np.zeros((len(x), 4))
    h[:, 1], h[:, 3] = (los / np.where(rng > 0, rng, 1.0)[:, None]).T
    ph = np.einsum("kij,kj->ki", P, h)                       # P h
    s2 = np.einsum("ki,ki->k", h, ph)                        # variance of r
    ok = (rng > 0) & (s2 > 0)
    s = np.sqrt(np.where(ok, s2, 1.0))
    mu = np.einsum("ki,ki->k", h, x)
    a, b = (-min_speed_mps - mu) / s, (min_speed_mps - mu) / s
    p_in = np.where(ok, norm.cdf(b) - norm.cdf(a), 0.0)
    use = ok & (p_in > 1e-12)
    pi = np.where(use, p_in, 1.0)
    fa, fb = norm.pdf(a), norm.pdf(b)
    m_in = np.where(use, mu + s * (fa - fb) / pi, mu)
    v_in = np.where(use, s2 * (1.0 + (a * fa - b * fb) / pi - ((fa - fb) / pi) ** 2), s2)
    k = ph / np.where(ok, s2, 1.0)[:, None]
    x_in = x + k * np.where(use, m_in - mu, 0.0)[:, None]
    p_new = P - k[:, :, None] * k[:, None, :] * np.where(use, s2 - v_in, 0.0)[:, None, None]
    return p_in, x_in, 0.5 * (p_new + np.swapaxes(p_new, 1, 2))


def notch_update(x: np.ndarray, P: np.ndarray, sensor_xy, min_speed_mps: float,
                 detection_probability: float) -> tuple[np.ndarray, np.ndarray]:
    """The states after a frame without a detection from a sensor blind inside the notch: the
    prior (weight 1 - P_D) and its inside part (weight P_D p_in, :func:`notch_split`), moment
    matched to one Gaussian (module docstring).

    Args:
        x, P: (K, 4), (K, 4, 4) predicted states ``[x, vx, y, vy]`` (m, m/s).
        sensor_xy: the sensor's position (m, 2 values).
        min_speed_mps: the notch's half-width (m/s, > 0).
        detection_probability: P_D of the object outside the notch, in (0, 1).

    Returns:
        (x', P'): the posterior states.
    """
    _check_probability(detection_probability, "notch_update", name="detection_probability")
    x, P = _check_states(x, P, "notch_update")
    p_in, x_in, P_in = notch_split(x, P, sensor_xy, min_speed_mps)
    c1 = detection_probability * p_in
    w = c1 / (c1 + 1.0 - detection_probability)
    xm = (1 - w)[:, None] * x + w[:, None] * x_in
    da, db = x - xm, x_in - xm
    pm = ((1 - w)[:, None, None] * (P + da[:, :, None] * da[:, None, :])
          + w[:, None, None] * (P_in + db[:, :, None] * db[:, None, :]))
    return xm, 0.5 * (pm + np.swapaxes(pm, 1, 2))


def seen_slowing(n_points: int, doppler_mps: float, min_speed_mps: float, point_std_mps: float,
                 probability: float = SLOWING_TEST_PROBABILITY) -> bool:
    """Whether a track's last object (``n_points`` points, median radial speed over ground
    ``doppler_mps``) was slow enough to be entering the notch: |d| within ``min_speed_mps`` + z
    ``point_std_mps`` / sqrt(n), z the two-sided ``probability`` quantile of the normal (False
    without a speed or a point). The last object only: pooling 3 objects of a 20-frames/s
    sensor averages 0.15 s of a deceleration and lags it (the synthetic person braking at 1
    m/s^2 of tests/track/test_doppler_notch.py was not seen slowing with 3). The standard error
    treats an object's median speed as the mean of independent points: a person's points are
    correlated (one body), so it is optimistic."""
    _check_speed(min_speed_mps, "min_speed_mps", "seen_slowing")
    _check_speed(point_std_mps, "point_std_mps", "seen_slowing")
    _check_probability(probability, "seen_slowing")
    n, d = float(n_points), float(doppler_mps)
    if not (np.isfinite(d) and n > 0):
        return False
    z = norm.ppf(0.5 + probability / 2.0)
    return bool(abs(d) <= min_speed_mps + z * point_std_mps / np.sqrt(n))


def held_state(x: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The stopped mode's states of (K, 4) / (K, 4, 4) ones: velocity zero and certain (no
    covariance with the position), position and its covariance kept; held so, frame after
    frame, without process noise (Kirubarajan & Bar-Shalom 2003's stopped model; across a gap
    in the frames the tracker grants it one frame period's, blindspot.track.tracker._held_noise)."""
    x, P = _check_states(x, P, "held_state")
    x, P = x.copy(), P.copy()
    x[:, [1, 3]] = 0.0
    P[:, [1, 3], :] = 0.0
    P[:, :, [1, 3]] = 0.0
    return x, P


def still(x: np.ndarray, P: np.ndarray, probability: float = SLOWING_TEST_PROBABILITY) -> bool:
    """Whether a state's velocity (x (4,), P (4, 4)) is consistent with standing still: v' P_v^-1
    v at most the chi-square quantile of ``probability`` with 2 degrees of freedom (a walker
    crossing the line of sight keeps a tangential speed its positions measured: not still)."""
    x = np.asarray(x, float)
    P = np.asarray(P, float)
    if x.shape != (4,) or P.shape != (4, 4):
        raise ValueError(f"still: a state x (4,) and P (4, 4) as [x, vx, y, vy]; found x "
                         f"{x.shape}, P {P.shape}")
    _check_probability(probability, "still")
    v = x[[1, 3]]
    pv = P[np.ix_([1, 3], [1, 3])]
    try:
        d2 = float(v @ np.linalg.solve(pv, v))
    except np.linalg.LinAlgError:
        return bool(np.allclose(v, 0.0))
    return bool(d2 <= chi2.ppf(probability, 2))
