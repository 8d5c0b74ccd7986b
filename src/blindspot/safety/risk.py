"""Collision risk of a predicted pedestrian path against the ego car's swept footprint.

The ego car drives straight along its heading at its current speed over the prediction horizon
(the risk asks "what if nobody brakes"). In the vehicle frame of the current ego pose (origin at
the front-bumper centre, +y along the heading, x to the right; :mod:`blindspot.radar.driving`)
the footprint at future step h (time ``h dt``) is the rectangle

    x in [-W/2 - r, W/2 + r],   y in [v h dt - L - r, v h dt + r]

(W, L the ego width and length, r the pedestrian radius: the pedestrian's reference point
collides when it lies inside the footprint grown by its own half size).

For each track and step the predicted position is Gaussian (a
:class:`~blindspot.traj.distribution.GaussianForecast`, rotated into the vehicle frame); its
mass over the rectangle, ``p_h``, is computed exactly up to quadrature error: conditioning y on
x, P = integral over [x0, x1] of phi(x; mu_x, s_x) [Phi((y1 - m(x)) / s) - Phi((y0 - m(x)) / s)]
dx with m(x) = mu_y + rho s_y / s_x (x - mu_x), s = s_y sqrt(1 - rho^2) (the bivariate normal's
conditional, e.g. Mardia, Kent & Bibby 1979, Thm 3.2.4), by Gauss-Legendre quadrature over the
part of [x0, x1] within 8 s_x of mu_x. Vectorised over tracks and steps.

The probability of a collision at any step is not determined by per-step marginals alone (the
steps are strongly dependent); it lies between max_h p_h and min(1, sum_h p_h) (Boole). The
``max_step`` method reports the lower bound (the most likely step), ``union`` the upper one.

Time to collision (TTC): the time of the first step whose predicted *mean* lies inside the
footprint (linear in the step, ``h dt``), NaN when none does within the horizon.

A multi-modal forecast (:class:`~blindspot.traj.mixture.MixtureForecast`, M Gaussian paths with
probabilities w_m): per step the mass over the rectangle is the mixture's, sum_m w_m p_mh (exact:
a mixture's mass is the weighted sum of its components'), then max or Boole over the steps as
above (:func:`mixture_collision_risk`); its TTC is that of the mixture's mean path.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr

from blindspot.arrays import check_array, check_count, check_number
from blindspot.traj.distribution import GaussianForecast
from blindspot.traj.mixture import MixtureForecast

__all__ = ["RiskError", "EgoShape", "RiskResult", "rectangle_mass", "to_vehicle_frame",
           "footprints", "collision_risk", "mixture_collision_risk"]

_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(48)


class RiskError(ValueError):
    """Malformed forecasts, ego states or footprint arguments."""


@dataclass(frozen=True)
class EgoShape:
    """The ego car's footprint: ``width_m`` x ``length_m`` behind the front-bumper centre (the
    radar position of the ego pose)."""

    width_m: float
    length_m: float

    def __post_init__(self) -> None:
        for name in ("width_m", "length_m"):
            check_number(getattr(self, name), name, gt=0.0, unit="m", error=RiskError,
                         who="EgoShape")


@dataclass(frozen=True)
class RiskResult:
    """p_collision (B,) in [0, 1]; p_step (B, H) per-step mass; ttc_s (B,) s (NaN: no step's
    mean inside the footprint)."""

    p_collision: np.ndarray
    p_step: np.ndarray
    ttc_s: np.ndarray


def rectangle_mass(mean: np.ndarray, cov: np.ndarray, lo: np.ndarray, hi: np.ndarray
                   ) -> np.ndarray:
    """Probability mass of 2-D Gaussians over axis-aligned rectangles.

    mean (..., 2) m, cov (..., 2, 2) m^2 (positive definite), lo / hi (..., 2) the rectangle's
    lower and upper corners (broadcast against ``mean``). Returns (...) in [0, 1]. Method: the
    conditional-normal integral of the module docstring, 48-point Gauss-Legendre.
    Raises RiskError for non-finite input or hi < lo.
    """
    mean = np.asarray(mean, float)
    cov = np.asarray(cov, float)
    lo = np.broadcast_to(np.asarray(lo, float), mean.shape)
    hi = np.broadcast_to(np.asarray(hi, float), mean.shape)
    if not (np.isfinite(mean).all() and np.isfinite(cov).all() and np.isfinite(lo).all()
            and np.isfinite(hi).all()):
        raise RiskError("rectangle_mass: mean, cov and the rectangle must be finite")
    if np.any(hi < lo):
        raise RiskError("rectangle_mass: every upper corner must be >= its lower corner")
    sx = np.sqrt(cov[..., 0, 0])
    sy = np.sqrt(cov[..., 1, 1])
    a = np.maximum(lo[..., 0], mean[..., 0] - 8 * sx)
    b = np.minimum(hi[..., 0], mean[..., 0] + 8 * sx)
    width = np.maximum(b - a, 0.0)
    # quadrature only where the rectangle reaches within 8 sigma of the mean on both axes:
    # elsewhere the mass is below 2 Phi(-8) = 1.2e-15 and is reported as 0 (most steps of most
    # tracks: the footprint is narrow and runs ahead of the pedestrian)
    near = (width > 0) & (hi[..., 1] >= mean[..., 1] - 8 * sy) & (lo[..., 1] <= mean[..., 1]
                                                                   + 8 * sy)
    out = np.zeros(mean.shape[:-1])
    if not near.any():
        return out
    sx, sy, a, b, w = sx[near], sy[near], a[near], b[near], width[near]
    mu, c01, y0, y1 = mean[near], cov[near][:, 0, 1], lo[near][:, 1], hi[near][:, 1]
    rho = np.clip(c01 / (sx * sy), -1 + 1e-12, 1 - 1e-12)
    x = (a + b)[:, None] / 2 + w[:, None] / 2 * _NODES                   # (N, n)
    zx = (x - mu[:, 0, None]) / sx[:, None]
    pdf = np.exp(-0.5 * zx**2) / (np.sqrt(2 * np.pi) * sx[:, None])
    m = mu[:, 1, None] + (rho * sy)[:, None] * zx
    s = (sy * np.sqrt(1 - rho**2))[:, None]
    inner = ndtr((y1[:, None] - m) / s) - ndtr((y0[:, None] - m) / s)
    out[near] = np.clip((pdf * inner) @ _WEIGHTS * w / 2, 0.0, 1.0)
    return out


def to_vehicle_frame(forecast: GaussianForecast, ego_xy: np.ndarray, yaw_rad: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """World-frame forecast -> vehicle frame of each track's current ego pose.

    ego_xy (B, 2) m, yaw_rad (B,) (counter-clockwise, 0 = heading +y). Returns mean (B, H, 2),
    cov (B, H, 2, 2); the rotation of :func:`blindspot.radar.driving.world_to_vehicle`.
    """
    B = forecast.mean.shape[0]
    xy = check_array(ego_xy, "ego_xy", (B, 2), error=RiskError, who="to_vehicle_frame")
    yaw = check_array(yaw_rad, "yaw_rad", (B,), error=RiskError, who="to_vehicle_frame")
    c, s = np.cos(yaw), np.sin(yaw)
    rot = np.stack([np.stack([c, s], -1), np.stack([-s, c], -1)], -2)     # (B, 2, 2)
    d = forecast.mean - xy[:, None, :]
    r = rot[:, None]                                                        # (B, 1, 2, 2)
    mean = (r @ d[..., None])[..., 0]
    cov = r @ forecast.cov @ r.swapaxes(-1, -2)
    return mean, cov


def _check_speeds(speed_mps, shape: tuple, who: str) -> np.ndarray:
    """The ego speeds (B,) m/s: finite and >= 0 (the footprint runs ahead along the heading)."""
    v = check_array(speed_mps, "speed_mps", shape, error=RiskError, who=who)
    if v.size and v.min() < 0:
        raise RiskError(f"{who}: speed_mps: expected speeds >= 0 m/s (the ego drives forward "
                        f"along its heading), found {v.min()!r} at index "
                        f"{int(np.argmin(v))}")
    return v


def footprints(speed_mps: np.ndarray, horizon: int, dt_s: float, ego: EgoShape,
               margin_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Vehicle-frame footprint rectangles of the ego driving straight at ``speed_mps`` (B,) at
    steps h = 1..horizon (times h dt_s). Returns lo, hi (B, H, 2) m (module docstring).
    Raises RiskError naming the argument for speeds that are not finite and >= 0, a horizon
    that is not an integer >= 1, a ``dt_s`` not > 0 or a ``margin_m`` not >= 0."""
    v = _check_speeds(speed_mps, ("B",), "footprints")
    check_count(horizon, "horizon", ge=1, error=RiskError, who="footprints")
    dt_s = check_number(dt_s, "dt_s", gt=0.0, unit="s", error=RiskError, who="footprints")
    margin_m = check_number(margin_m, "margin_m", ge=0.0, unit="m (the pedestrian radius)",
                            error=RiskError, who="footprints")
    if not isinstance(ego, EgoShape):
        raise RiskError(f"footprints: ego: expected an EgoShape, found {type(ego).__name__}")
    yb = v[:, None] * dt_s * np.arange(1, horizon + 1)[None, :]            # (B, H)
    half = ego.width_m / 2 + margin_m
    lo = np.stack([np.full_like(yb, -half), yb - ego.length_m - margin_m], -1)
    hi = np.stack([np.full_like(yb, half), yb + margin_m], -1)
    return lo, hi


def collision_risk(forecast: GaussianForecast, ego_xy: np.ndarray, yaw_rad: np.ndarray,
                   speed_mps: np.ndarray, dt_s: float, ego: EgoShape, *, margin_m: float,
                   method: str = "max_step") -> RiskResult:
    """P(collision) and TTC of B predicted pedestrian paths against the ego's swept footprint.

    forecast: GaussianForecast (B, H) in the world frame, step h at time h dt_s after now;
    ego_xy (B, 2) m, yaw_rad (B,), speed_mps (B,) the ego state now (front-bumper centre).
    margin_m: the pedestrian radius the footprint grows by (>= 0). method: ``max_step`` |
    ``union``. Returns :class:`RiskResult`. Raises RiskError for malformed input (naming the
    argument and its value: a negative or non-finite ``margin_m``, a ``dt_s`` not > 0, a
    negative or non-finite speed, a forecast without steps) or an unknown method.
    """
    who = "collision_risk"
    if method not in ("max_step", "union"):
        raise RiskError(f"collision_risk: method must be 'max_step' or 'union', found {method!r}")
    dt_s = check_number(dt_s, "dt_s", gt=0.0, unit="s", error=RiskError, who=who)
    margin_m = check_number(margin_m, "margin_m", ge=0.0, unit="m (the pedestrian radius)",
                            error=RiskError, who=who)
    B, H = forecast.mean.shape[:2]
    if H < 1:
        raise RiskError(f"collision_risk: forecast: expected at least one step (a horizon "
                        f">= 1), found {H} steps")
    speed = _check_speeds(speed_mps, (B,), who)
    mean, cov = to_vehicle_frame(forecast, ego_xy, yaw_rad)
    lo, hi = footprints(speed, H, dt_s, ego, margin_m)
    p_step = rectangle_mass(mean, cov, lo, hi)                               # (B, H)
    p = p_step.max(axis=1) if method == "max_step" else np.minimum(1.0, p_step.sum(axis=1))
    inside = np.all((mean >= lo) & (mean <= hi), axis=-1)                    # (B, H)
    first = np.argmax(inside, axis=1)
    ttc = np.where(inside.any(axis=1), (first + 1) * dt_s, np.nan)
    return RiskResult(p, p_step, ttc)


def mixture_collision_risk(mixture: MixtureForecast, ego_xy: np.ndarray, yaw_rad: np.ndarray,
                           speed_mps: np.ndarray, dt_s: float, ego: EgoShape, *,
                           margin_m: float, method: str = "max_step") -> RiskResult:
    """:func:`collision_risk` of a multi-modal forecast (module docstring): per step the
    probability-weighted sum of each hypothesis' mass over the footprint; TTC from the
    mixture's mean path. Same arguments and errors as :func:`collision_risk` (``mixture``
    not a MixtureForecast: RiskError naming it)."""
    if not isinstance(mixture, MixtureForecast):
        raise RiskError(f"mixture_collision_risk: mixture: expected a MixtureForecast, found "
                        f"{type(mixture).__name__}")
    # the mean path's call checks every argument (and gives the TTC); then all B x M
    # hypotheses in one vectorised call, each with its track's ego state
    mean = collision_risk(mixture.to_gaussian(), ego_xy, yaw_rad, speed_mps, dt_s, ego,
                          margin_m=margin_m, method=method)
    b, m = mixture.weights.shape
    h = mixture.horizon
    flat = GaussianForecast(mixture.means.reshape(b * m, h, 2),
                            mixture.covs.reshape(b * m, h, 2, 2))
    each = [np.repeat(np.asarray(v, dtype=float), m, axis=0)
            for v in (ego_xy, yaw_rad, speed_mps)]
    part = collision_risk(flat, *each, dt_s, ego, margin_m=margin_m, method=method)
    p_step = np.einsum("bm,bmh->bh", mixture.weights, part.p_step.reshape(b, m, h))
    p = p_step.max(axis=1) if method == "max_step" else np.minimum(1.0, p_step.sum(axis=1))
    return RiskResult(p, p_step, mean.ttc_s)
