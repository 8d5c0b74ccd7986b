"""FMCW radar configuration: the chirp profile and the quantities derived from it.

``RadarConfig`` holds what a TI chirp profile holds (start frequency, swept bandwidth, ramp and
idle time, ADC rate, samples, chirp loops, TX firing order) plus the link-budget numbers the
simulator needs (noise figure, TX power, antenna gains). Everything is SI. Build it from a Hydra
node with :meth:`RadarConfig.from_mapping`, which validates every key and names the offending key,
the value found and the allowed range in its error.

Conventions
-----------
* ``bandwidth_hz`` is the bandwidth swept while the ADC samples (``slope * n_samples / adc_rate``);
  the range resolution ``c / (2 B)`` follows from it (0.5 m for the paper's 300 MHz).
* ``n_chirps`` counts chirp *loops* per frame; each loop fires every TX in ``tx_order`` once
  (TDM-MIMO), so a frame holds ``n_chirps * n_tx`` chirps.
* The Doppler axis is zero-centred (fftshift order), velocity positive = moving away from the radar.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

SPEED_OF_LIGHT = 299_792_458.0
BOLTZMANN = 1.380_649e-23
T0_KELVIN = 290.0


class ConfigError(ValueError):
    """A configuration value is missing or outside its allowed range."""

    def __init__(self, key: str, value: Any, allowed: str):
        self.key, self.value, self.allowed = key, value, allowed
        super().__init__(f"config key '{key}' = {value!r} is invalid: expected {allowed}")


@dataclass(frozen=True)
class RadarConfig:
    """An FMCW TDM-MIMO chirp profile (all SI units)."""

    name: str
    start_freq_hz: float
    bandwidth_hz: float
    ramp_time_s: float
    idle_time_s: float
    adc_rate_hz: float
    n_samples: int
    n_chirps: int
    n_tx: int
    n_rx: int
    tx_order: tuple[int, ...]
    frame_period_s: float
    noise_figure_db: float = 14.0
    tx_power_dbm: float = 12.0
    tx_gain_dbi: float = 10.0
    rx_gain_dbi: float = 10.0
    adc_bits: int | None = None
    array: str = "ula"
    rx_spacing_wl: float = 0.5
    design_freq_hz: float | None = None
    extra: dict = field(default_factory=dict, compare=False, repr=False)

    # ------------------------------------------------------------------ derived quantities
    @property
    def slope_hz_per_s(self) -> float:
        """Chirp slope S = B / T_sample (Hz/s): the bandwidth swept while sampling."""
        return self.bandwidth_hz / self.sampling_time_s

    @property
    def sampling_time_s(self) -> float:
        """Duration of the ADC sampling window, n_samples / f_s."""
        return self.n_samples / self.adc_rate_hz

    @property
    def center_freq_hz(self) -> float:
        return self.start_freq_hz + 0.5 * self.bandwidth_hz

    @property
    def wavelength_m(self) -> float:
        """Wavelength at the centre of the sampled sweep."""
        return SPEED_OF_LIGHT / self.center_freq_hz

    @property
    def range_resolution_m(self) -> float:
        """c / (2 B)."""
        return SPEED_OF_LIGHT / (2.0 * self.bandwidth_hz)

    @property
    def range_bin_m(self) -> float:
        """Range spanned by one bin of an n_samples-point range FFT (= the resolution)."""
        return SPEED_OF_LIGHT * self.adc_rate_hz / (2.0 * self.slope_hz_per_s * self.n_samples)

    @property
    def max_range_m(self) -> float:
        """Largest range a complex-sampled beat tone reaches: f_b = f_s."""
        return self.range_bin_m * self.n_samples

    @property
    def chirp_period_s(self) -> float:
        return self.ramp_time_s + self.idle_time_s

    @property
    def loop_period_s(self) -> float:
        """Time between two chirps of the same TX (TDM-MIMO): n_tx chirp periods."""
        return self.n_tx * self.chirp_period_s

    @property
    def frame_active_time_s(self) -> float:
        return self.n_chirps * self.loop_period_s

    @property
    def max_velocity_mps(self) -> float:
        """Largest unambiguous radial speed, lambda / (4 T_loop)."""
        return self.wavelength_m / (4.0 * self.loop_period_s)

    @property
    def velocity_resolution_mps(self) -> float:
        """lambda / (2 N_loops T_loop)."""
        return self.wavelength_m / (2.0 * self.n_chirps * self.loop_period_s)

    @property
    def noise_power_w(self) -> float:
        """Thermal noise power k T0 F B_IF at the ADC, with B_IF = f_s (complex sampling)."""
        return BOLTZMANN * T0_KELVIN * 10 ** (self.noise_figure_db / 10) * self.adc_rate_hz

    def range_axis_m(self) -> np.ndarray:
        """(n_samples,) range of each range-FFT bin, m."""
        return np.arange(self.n_samples) * self.range_bin_m

    def velocity_axis_mps(self) -> np.ndarray:
        """(n_chirps,) radial velocity of each Doppler bin, zero-centred (fftshift order)."""
        k = np.arange(self.n_chirps) - self.n_chirps // 2
        return k * self.velocity_resolution_mps

    def tx_slot_times_s(self) -> np.ndarray:
        """(n_tx,) start time of each TX slot within a loop, in firing order."""
        return np.arange(self.n_tx) * self.chirp_period_s

    def summary(self) -> dict[str, float]:
        """Derived quantities, for tables and logs."""
        return {
            "center_freq_ghz": self.center_freq_hz / 1e9,
            "wavelength_mm": self.wavelength_m * 1e3,
            "slope_mhz_per_us": self.slope_hz_per_s / 1e12,
            "range_resolution_m": self.range_resolution_m,
            "max_range_m": self.max_range_m,
            "velocity_resolution_mps": self.velocity_resolution_mps,
            "max_velocity_mps": self.max_velocity_mps,
            "chirp_period_us": self.chirp_period_s * 1e6,
            "frame_active_ms": self.frame_active_time_s * 1e3,
        }

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d.pop("extra")
        d["tx_order"] = list(self.tx_order)
        return d

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any], where: str = "radar") -> RadarConfig:
        """Build and validate from a dict or OmegaConf node; ``where`` prefixes key names in errors."""
        m = _plain(mapping)
        known = {f for f in cls.__dataclass_fields__ if f != "extra"}
        required = {
            "start_freq_hz", "bandwidth_hz", "ramp_time_s", "idle_time_s", "adc_rate_hz",
            "n_samples", "n_chirps", "n_tx", "n_rx", "frame_period_s",
        }
        for key in sorted(required):
            if m.get(key) is None:
                raise ConfigError(f"{where}.{key}", None, "a value (the key is required)")
        kwargs: dict[str, Any] = {k: m[k] for k in known if k in m}
        kwargs.setdefault("name", m.get("name", where))
        if kwargs.get("tx_order") is None:
            kwargs["tx_order"] = tuple(range(int(m["n_tx"])))
        kwargs["tx_order"] = tuple(int(t) for t in kwargs["tx_order"])
        kwargs["extra"] = {k: v for k, v in m.items() if k not in known}
        cfg = cls(**kwargs)
        cfg.validate(where)
        return cfg

    def validate(self, where: str = "radar") -> None:
        """Raise ConfigError for the first invalid value (naming key, value and allowed range)."""
        def check(key: str, ok: bool, allowed: str) -> None:
            if not ok:
                raise ConfigError(f"{where}.{key}", getattr(self, key), allowed)

        def positive(key: str, lo: float = 0.0, hi: float = math.inf) -> None:
            v = getattr(self, key)
            ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            check(key, ok and lo < v <= hi, f"a finite number in ({lo:g}, {hi:g}]")

        def count(key: str, hi: int) -> None:
            v = getattr(self, key)
            check(key, isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= hi,
                  f"an integer in [1, {hi}]")

        positive("start_freq_hz", 1e9, 300e9)
        positive("bandwidth_hz", 0.0, 10e9)
        positive("ramp_time_s", 0.0, 1e-2)
        v = self.idle_time_s
        check("idle_time_s", isinstance(v, (int, float)) and math.isfinite(v) and 0 <= v <= 1e-2,
              "a finite number in [0, 0.01]")
        positive("adc_rate_hz", 0.0, 1e9)
        count("n_samples", 1 << 16)
        count("n_chirps", 1 << 16)
        count("n_tx", 64)
        count("n_rx", 64)
        positive("frame_period_s", 0.0, 3600.0)
        for key in ("noise_figure_db", "tx_power_dbm", "tx_gain_dbi", "rx_gain_dbi"):
            v = getattr(self, key)
            check(key, isinstance(v, (int, float)) and math.isfinite(v) and -50 <= v <= 100,
                  "a finite number of dB in [-50, 100]")
        check("adc_bits", self.adc_bits is None or (isinstance(self.adc_bits, int)
                                                    and 2 <= self.adc_bits <= 32),
              "null (no quantisation) or an integer number of bits in [2, 32]")
        check("rx_spacing_wl", math.isfinite(self.rx_spacing_wl) and self.rx_spacing_wl > 0,
              "a positive element spacing in wavelengths")
        check("array", self.array in ARRAY_KINDS, f"one of {sorted(ARRAY_KINDS)}")
        # Sampling must fit inside the ramp, or the swept bandwidth cannot be sampled.
        check("adc_rate_hz", self.sampling_time_s <= self.ramp_time_s * (1 + 1e-9),
              f"at least n_samples / ramp_time_s = {self.n_samples / self.ramp_time_s:.6g} Hz "
              f"so that {self.n_samples} samples fit in the {self.ramp_time_s * 1e6:g} us ramp "
              f"(sampling would take {self.sampling_time_s * 1e6:.4g} us)")
        max_tx = ARRAY_KINDS[self.array][0]
        check("n_tx", self.n_tx <= max_tx, f"at most {max_tx} TX for array '{self.array}'")
        max_rx = ARRAY_KINDS[self.array][1]
        check("n_rx", self.n_rx <= max_rx, f"at most {max_rx} RX for array '{self.array}'")
        order = self.tx_order
        check("tx_order", len(order) == self.n_tx and len(set(order)) == len(order)
              and all(0 <= t < max_tx for t in order),
              f"{self.n_tx} distinct 0-based TX indices below {max_tx}")
        check("frame_period_s", self.frame_period_s >= self.frame_active_time_s,
              f"at least the active chirp time {self.frame_active_time_s:.6g} s "
              f"(n_chirps * n_tx * (ramp + idle))")


# array kind -> (physical TX, physical RX) available
ARRAY_KINDS: dict[str, tuple[int, int]] = {"mmwcas": (12, 16), "ula": (64, 64)}


def _plain(mapping: Mapping[str, Any]) -> dict[str, Any]:
    try:
        from omegaconf import DictConfig, OmegaConf

        if isinstance(mapping, DictConfig):
            return dict(OmegaConf.to_container(mapping, resolve=True))  # type: ignore[arg-type]
    except ImportError:  # pragma: no cover - omegaconf is a dependency
        pass
    if not isinstance(mapping, Mapping):
        raise ConfigError("radar", mapping, "a mapping of radar profile keys")
    return dict(mapping)
