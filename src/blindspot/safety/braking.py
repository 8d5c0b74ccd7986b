"""The AEB braking model: latency, a jerk-limited ramp to full deceleration, then held.

Once requested (time 0 here) braking is committed. With initial speed v0, latency T, jerk j and
full deceleration a (ramp time t_r = a / j; the two-phase ramp-then-hold profile of production
pedestrian AEB, SAE 2020-01-0878, values in ``conf/warning/default.yaml``), with u = t - T:

* t < T:           v = v0,                          s = v0 t
* 0 <= u < t_r:    v = v0 - j u^2 / 2,              s = v0 T + v0 u - j u^3 / 6
* u >= t_r:        v = v1 - a w,  w = u - t_r,      s = s_r + v1 w - a w^2 / 2,  v1 = v0 - a t_r / 2

until v = 0 (the car then stays). If v0 <= a t_r / 2 it stops within the ramp, at
u = sqrt(2 v0 / j). The stopping distance (elementary kinematics) is

    d = v0 T + v0^2 / (2 a) + v0 t_r / 2 - a t_r^2 / 24        (v0 > a t_r / 2)
    d = v0 T + (2/3) v0 sqrt(2 v0 / j)                          (otherwise).

The last point to brake for a stationary obstacle (the "brake threat" of Brännström, Coelingh &
Sjöberg 2010, IEEE T-ITS 11(3) 658-669, Sec. III; the minimum-TTC criterion of ISO 22839:2013
FVCMS) is the time to collision at constant speed at which a request still stops the car at the
obstacle: TTC_stop = d / v0, i.e.

    TTC_stop = T + v0 / (2 a) + t_r / 2 - a t_r^2 / (24 v0)     (v0 > a t_r / 2)
    TTC_stop = T + (2/3) sqrt(2 v0 / j)                          (otherwise).

A request at a TTC above it stops short of the obstacle; below it, the car hits it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from blindspot.arrays import check_array, check_number

__all__ = ["BrakingModel"]


@dataclass(frozen=True)
class BrakingModel:
    """latency_s (s), jerk_mps3 (m/s^3), decel_mps2 (m/s^2): see the module docstring.
    Raises ValueError naming the field for a latency that is not finite and >= 0, or a jerk or
    deceleration that is not finite and > 0; each method raises ValueError naming its argument
    for a negative, NaN or infinite speed (or a NaN time)."""

    latency_s: float
    jerk_mps3: float
    decel_mps2: float

    def __post_init__(self) -> None:
        check_number(self.latency_s, "latency_s", ge=0.0, unit="s", who="BrakingModel")
        check_number(self.jerk_mps3, "jerk_mps3", gt=0.0, unit="m/s^3", who="BrakingModel")
        check_number(self.decel_mps2, "decel_mps2", gt=0.0, unit="m/s^2", who="BrakingModel")

    @staticmethod
    def _speeds(v0, who: str) -> np.ndarray:
        """v0 (...) m/s as float64: finite and >= 0 (a car's speed along its heading)."""
        v = check_array(v0, "v0", ("...",), who=f"BrakingModel.{who}")
        if v.size and v.min() < 0:
            raise ValueError(f"BrakingModel.{who}: v0: expected speeds >= 0 m/s, found "
                             f"{v.min()!r}")
        return v

    @classmethod
    def from_config(cls, cfg, decel_mps2: float | None = None) -> BrakingModel:
        """From a :class:`~blindspot.safety.config.BrakingConfig` (deceleration overridable)."""
        return cls(cfg.latency_s, cfg.jerk_mps3, cfg.decel_mps2 if decel_mps2 is None
                   else float(decel_mps2))

    @property
    def ramp_s(self) -> float:
        return self.decel_mps2 / self.jerk_mps3

    def stop_time(self, v0: np.ndarray) -> np.ndarray:
        """Time from the request to standstill, s, for speeds v0 (...) m/s (finite, >= 0)."""
        v0 = self._speeds(v0, "stop_time")
        a, j, tr = self.decel_mps2, self.jerk_mps3, self.ramp_s
        in_ramp = v0 <= a * tr / 2
        return self.latency_s + np.where(in_ramp, np.sqrt(2 * np.maximum(v0, 0) / j),
                                         tr + (v0 - a * tr / 2) / a)

    def motion(self, v0: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance travelled (m) and speed (m/s) at times t (...) s after the request
        (t < 0: not yet requested, constant speed), speeds v0 broadcast against t."""
        v0 = self._speeds(v0, "motion")
        t = check_array(t, "t", ("...",), who="BrakingModel.motion")
        v0, t = np.broadcast_arrays(v0, t)
        a, j, tr, T = self.decel_mps2, self.jerk_mps3, self.ramp_s, self.latency_s
        t_stop = self.stop_time(v0)
        tc = np.minimum(t, t_stop)
        u = np.maximum(tc - T, 0.0)
        ur = np.minimum(u, tr)
        w = np.maximum(u - tr, 0.0)
        v1 = v0 - a * tr / 2
        s_ramp = v0 * ur - j * ur**3 / 6
        s = v0 * np.minimum(tc, T) + np.where(t < 0, v0 * t - v0 * np.minimum(tc, T), 0.0) \
            + np.where(t < 0, 0.0, s_ramp + v1 * w - a * w**2 / 2)
        v = np.where(t >= t_stop, 0.0, np.where(u < tr, v0 - j * ur**2 / 2, v1 - a * w))
        return s, np.maximum(v, 0.0)

    def stop_ttc(self, v0: np.ndarray) -> np.ndarray:
        """TTC_stop (module docstring), s: the constant-speed time to collision with a
        stationary obstacle at which a request still stops the car at it, for speeds v0 (...)
        m/s > 0 (closed form; equals ``stopping_distance(v0) / v0``). Raises ValueError for a
        non-positive speed (no collision, no TTC)."""
        v0 = self._speeds(v0, "stop_ttc")
        if not np.all(v0 > 0):
            raise ValueError(f"BrakingModel.stop_ttc: speeds must be > 0 m/s, found "
                             f"min {np.min(v0)!r}")
        a, j, tr = self.decel_mps2, self.jerk_mps3, self.ramp_s
        in_ramp = v0 <= a * tr / 2
        full = self.latency_s + v0 / (2 * a) + tr / 2 - a * tr**2 / (24 * v0)
        ramp = self.latency_s + (2 / 3) * np.sqrt(2 * v0 / j)
        return np.where(in_ramp, ramp, full)

    def stopping_distance(self, v0: np.ndarray) -> np.ndarray:
        """Distance from the request to standstill, m (module docstring), for v0 (...) m/s
        (finite, >= 0)."""
        v0 = self._speeds(v0, "stopping_distance")
        s, _ = self.motion(v0, self.stop_time(v0))
        return s
