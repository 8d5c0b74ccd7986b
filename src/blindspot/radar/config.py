"""FMCW radar configuration: the chirp profile and the quantities derived from it.

``RadarConfig`` holds what a TI chirp profile holds (start frequency, swept bandwidth, ramp and
idle time, ADC rate, samples, chirp loops, TX firing order) plus the link-budget numbers the
simulator needs (noise figure, TX power, antenna gains). Everything is SI. Build it from a Hydra
node with ``RadarConfig.from_mapping(cfg.radar)`` (:mod:`blindspot.typed_config`), which validates
every key and names the offending key, the value found and the allowed range in its error.
:class:`SimConfig` is the ``sim`` group (simulator noise and ADC headroom).

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
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from blindspot.typed_config import ConfigError, TypedConfig, setting

__all__ = ["ARRAY_KINDS", "RadarConfig", "SimConfig", "SPEED_OF_LIGHT"]

SPEED_OF_LIGHT = 299_792_458.0
BOLTZMANN = 1.380_649e-23
T0_KELVIN = 290.0

# array kind -> (physical TX, physical RX) available
ARRAY_KINDS: dict[str, tuple[int, int]] = {"mmwcas": (12, 16), "ula": (64, 64)}

_DB = dict(ge=-50.0, le=100.0)


@dataclass(frozen=True)
class RadarConfig(TypedConfig):
    """An FMCW TDM-MIMO chirp profile (all SI units); the Hydra group ``radar``.

    ``tx_order`` (0-based TX indices in firing order) defaults to ``0 .. n_tx - 1``.
    """

    GROUP = "radar"

    name: str = setting()
    start_freq_hz: float = setting(gt=1e9, le=300e9)
    bandwidth_hz: float = setting(gt=0.0, le=10e9)
    ramp_time_s: float = setting(gt=0.0, le=1e-2)
    idle_time_s: float = setting(ge=0.0, le=1e-2)
    adc_rate_hz: float = setting(gt=0.0, le=1e9)
    n_samples: int = setting(ge=1, le=1 << 16)
    n_chirps: int = setting(ge=1, le=1 << 16)
    n_tx: int = setting(ge=1, le=64)
    n_rx: int = setting(ge=1, le=64)
    frame_period_s: float = setting(gt=0.0, le=3600.0)
    tx_order: tuple[int, ...] | None = setting(None, ge=0)
    noise_figure_db: float = setting(14.0, **_DB)
    tx_power_dbm: float = setting(12.0, **_DB)
    tx_gain_dbi: float = setting(10.0, **_DB)
    rx_gain_dbi: float = setting(10.0, **_DB)
    adc_bits: int | None = setting(
        None, ge=2, le=32, doc="null (no quantisation) or an integer number of bits in [2, 32]")
    array: str = setting("ula", choices=tuple(ARRAY_KINDS))
    rx_spacing_wl: float = setting(0.5, gt=0.0, le=1e3)
    design_freq_hz: float | None = setting(None, gt=0.0, le=300e9)

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
        d["tx_order"] = list(self.tx_order)
        return d

    # ------------------------------------------------------------------ cross-field rules
    def validate(self) -> None:
        """Rules between keys (each key's own range is checked from its field)."""
        if self.tx_order is None:
            object.__setattr__(self, "tx_order", tuple(range(self.n_tx)))

        def check(key: str, ok: bool, allowed: str) -> None:
            if not ok:
                raise ConfigError(key, getattr(self, key), allowed)

        # Sampling must fit inside the ramp, or the swept bandwidth cannot be sampled.
        check("adc_rate_hz", self.sampling_time_s <= self.ramp_time_s * (1 + 1e-9),
              f"at least n_samples / ramp_time_s = {self.n_samples / self.ramp_time_s:.6g} Hz "
              f"so that {self.n_samples} samples fit in the {self.ramp_time_s * 1e6:g} us ramp "
              f"(sampling would take {self.sampling_time_s * 1e6:.4g} us)")
        max_tx, max_rx = ARRAY_KINDS[self.array]
        check("n_tx", self.n_tx <= max_tx, f"at most {max_tx} TX for array '{self.array}'")
        check("n_rx", self.n_rx <= max_rx, f"at most {max_rx} RX for array '{self.array}'")
        order = self.tx_order
        check("tx_order", len(order) == self.n_tx and len(set(order)) == len(order)
              and all(0 <= t < max_tx for t in order),
              f"{self.n_tx} distinct 0-based TX indices below {max_tx}")
        check("frame_period_s", self.frame_period_s >= self.frame_active_time_s,
              f"at least the active chirp time {self.frame_active_time_s:.6g} s "
              f"(n_chirps * n_tx * (ramp + idle))")


@dataclass(frozen=True)
class SimConfig(TypedConfig):
    """The Hydra group ``sim``: FMCW simulator settings (the chirp profile, link budget and ADC
    width live in :class:`RadarConfig`).

    Attributes:
        noise: add thermal noise k T0 F f_s per complex sample; false = noiseless cubes.
        adc_headroom_db: with ``radar.adc_bits`` set, the ADC full scale above the per-component
            noise RMS, dB.
    """

    GROUP = "sim"

    noise: bool = setting(True)
    adc_headroom_db: float = setting(60.0, gt=0.0, lt=200.0)
