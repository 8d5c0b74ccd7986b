"""Silent tracks of a sensor with a Doppler notch: a stop, a miss, or gone.

A radar that drops its static clutter on the sensor (TI's people-counting demo removes the
zero-Doppler bin) or in the reader (a recording's ``static_speed_mps``) reports no point whose
radial speed over ground lies inside its notch, |u.v| < v_min. A person who stops there, or walks
across the line of sight, goes silent: a constant-velocity track coasts on with the radial speed
it last had, walks away from them and is deleted after ``tracker.max_misses``, and the person
gets a new track when they walk off.

A frame without a detection is negative information (Koch 2007, "On exploiting 'negative'
sensor evidence for target tracking and sensor data fusion", Information Fusion 8(1); behind a
Doppler notch, the move-stop-move targets of GMTI tracking, Kirubarajan & Bar-Shalom 2003). Its
likelihood is 1 - P_D outside the notch and 1 inside it, so the predicted Gaussian becomes a
mixture of itself (weight 1 - P_D) and its part inside the notch (weight P_D p_in);
:func:`notch_update` collapses it to one Gaussian by moment matching (:func:`notch_split`: the
radial speed's truncated-normal moments, carried to the state by its linear regression on it).
The radial speed is pulled into the notch, the tangential one kept: a walker crossing the line
of sight keeps walking, a person who stopped stays put.

Repeated, that update erodes any velocity: an object that vanished at 0.8 m/s, missed frame after
frame, ends up "in the notch" because the model has no hypothesis that it is gone. So a silence
counts as a stop, not toward deletion, only when the track's last object was seen slowing into
the notch (:func:`seen_slowing`: its radial speed consistent with it), and while the
notch is the likelier reason for the silence (its posterior probability at least one half). A
sensor that reports its static points (the driving chain) has no notch.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import norm

__all__ = ["SLOWING_OBJECTS", "SLOWING_TEST_PROBABILITY", "notch_split", "notch_update",
           "seen_slowing"]

#: The last objects of a track whose pooled radial speed :func:`seen_slowing` tests: the last
#: one (pooling 3 objects of a 20-frames/s sensor averages 0.15 s of the deceleration and lags
#: it: a person braking at 1 m/s^2 was not seen slowing).
SLOWING_OBJECTS = 1
#: Two-sided probability of that test: the silence is a stop unless the last objects' radial
#: speed lies outside the notch by more than this quantile of its standard error.
SLOWING_TEST_PROBABILITY = 0.95


def _check_states(x: np.ndarray, P: np.ndarray, who: str) -> tuple[np.ndarray, np.ndarray]:
    x = np.asarray(x, float)
    P = np.asarray(P, float)
    if x.ndim != 2 or x.shape[1] != 4 or P.shape != (len(x), 4, 4):
        raise ValueError(f"{who}: states x (K, 4) and P (K, 4, 4) as [x, vx, y, vy]; found "
                         f"x {x.shape}, P {P.shape}")
    return x, P


def _check_speed(value: float, name: str, who: str) -> None:
    if (isinstance(value, bool) or not isinstance(value, (int, float))
            or not (np.isfinite(value) and value > 0)):
        raise ValueError(f"{who}: {name} must be a positive finite speed (m/s); found {value!r}")


def notch_split(x: np.ndarray, P: np.ndarray, sensor_xy, min_speed_mps: float):
    """A Gaussian state conditioned on its radial speed over ground r = u.v (u the unit line of
    sight from ``sensor_xy`` to the state's position, held at the mean: the linearisation of
    :func:`blindspot.track.tracker._range_rate_update`) lying inside the notch |r| <
    ``min_speed_mps`` or outside it.

    The radial speed's truncated-normal moments are exact; the rest of the state follows by its
    linear regression on r (exact for a Gaussian conditioned on a linear function of itself).

    Args:
        x, P: (K, 4), (K, 4, 4) states ``[x, vx, y, vy]`` (m, m/s).
        sensor_xy: the sensor's position (m, 2 values).
        min_speed_mps: the notch's half-width (m/s, > 0).

    Returns:
        ``(p_in, (x_in, P_in), (x_out, P_out))``: the prior probability of the notch (K,) and
        the two conditional states. Where a side has (numerically) no mass, or the state sits
        at the sensor (p_in 0 there), that side's state is the prior.
    """
    x, P = _check_states(x, P, "notch_split")
    _check_speed(min_speed_mps, "min_speed_mps", "notch_split")
    los = x[:, [0, 2]] - np.asarray(sensor_xy, float).reshape(1, 2)
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
    has_in = ok & (p_in > 1e-12)
    has_out = ok & (p_in < 1.0 - 1e-12)
    pi = np.where(has_in, p_in, 1.0)
    fa, fb = norm.pdf(a), norm.pdf(b)
    m_in = np.where(has_in, mu + s * (fa - fb) / pi, mu)
    v_in = np.where(has_in, s2 * (1.0 + (a * fa - b * fb) / pi - ((fa - fb) / pi) ** 2), s2)
    # outside: what the prior holds beyond the inside part (the mixture identity)
    po = np.where(has_out, 1.0 - p_in, 1.0)
    m_out = np.where(has_out, (mu - p_in * m_in) / po, mu)
    second = np.where(has_out, (s2 + mu ** 2 - p_in * (v_in + m_in ** 2)) / po, s2 + mu ** 2)
    v_out = np.where(has_out, np.maximum(second - m_out ** 2, 0.0), s2)
    k = ph / np.where(ok, s2, 1.0)[:, None]

    def conditioned(m, v, use):
        xc = x + k * np.where(use, m - mu, 0.0)[:, None]
        pc = P - k[:, :, None] * k[:, None, :] * np.where(use, s2 - v, 0.0)[:, None, None]
        return xc, 0.5 * (pc + np.swapaxes(pc, 1, 2))

    return p_in, conditioned(m_in, v_in, has_in), conditioned(m_out, v_out, has_out)


def notch_update(x: np.ndarray, P: np.ndarray, sensor_xy, min_speed_mps: float,
                 detection_probability: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The states after a frame without a detection from a sensor blind inside the notch: the
    prior (weight 1 - P_D) and its inside part (weight P_D p_in, :func:`notch_split`), moment
    matched to one Gaussian (module docstring).

    Args:
        x, P: (K, 4), (K, 4, 4) predicted states ``[x, vx, y, vy]`` (m, m/s).
        sensor_xy: the sensor's position (m, 2 values).
        min_speed_mps: the notch's half-width (m/s, > 0).
        detection_probability: P_D of the object outside the notch, in (0, 1).

    Returns:
        (x', P', q): the posterior states and the posterior probability q (K,) that the radial
        speed lies inside the notch, p_in / (p_in + (1 - P_D)(1 - p_in)).
    """
    if not 0.0 < detection_probability < 1.0:
        raise ValueError(f"notch_update: detection_probability must lie in (0, 1); found "
                         f"{detection_probability!r}")
    x, P = _check_states(x, P, "notch_update")
    p_in, (x_in, P_in), _ = notch_split(x, P, sensor_xy, min_speed_mps)
    c1 = detection_probability * p_in
    w = c1 / (c1 + 1.0 - detection_probability)
    xm = (1 - w)[:, None] * x + w[:, None] * x_in
    da, db = x - xm, x_in - xm
    pm = ((1 - w)[:, None, None] * (P + da[:, :, None] * da[:, None, :])
          + w[:, None, None] * (P_in + db[:, :, None] * db[:, None, :]))
    q = p_in / (p_in + (1.0 - detection_probability) * (1.0 - p_in))
    return xm, 0.5 * (pm + np.swapaxes(pm, 1, 2)), q


def seen_slowing(n_points, doppler_mps, min_speed_mps: float, point_std_mps: float,
                 probability: float = SLOWING_TEST_PROBABILITY) -> bool:
    """Whether a track's last objects (``n_points`` (k,) points each, median radial speeds over
    ground ``doppler_mps`` (k,)) were slow enough to be entering the notch: their pooled radial
    speed d = sum n d_k / sum n lies within ``min_speed_mps`` + z ``point_std_mps`` /
    sqrt(sum n), z the two-sided ``probability`` quantile of the normal (NaN speeds and empty
    objects left out; False without any)."""
    _check_speed(min_speed_mps, "min_speed_mps", "seen_slowing")
    _check_speed(point_std_mps, "point_std_mps", "seen_slowing")
    n = np.asarray(n_points, float)
    d = np.asarray(doppler_mps, float)
    ok = np.isfinite(d) & (n > 0)
    if not ok.any():
        return False
    pooled = (n[ok] * d[ok]).sum() / n[ok].sum()
    z = norm.ppf(0.5 + probability / 2.0)
    return bool(abs(pooled) <= min_speed_mps + z * point_std_mps / np.sqrt(n[ok].sum()))
