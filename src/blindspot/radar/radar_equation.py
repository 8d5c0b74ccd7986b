"""The monostatic radar equation and the SNR it implies for an FMCW radar (SI units).

Received power from a point target of radar cross-section sigma at range R::

    P_r = P_t G_t G_r lambda^2 sigma / ((4 pi)^3 R^4)

Thermal noise per complex ADC sample is k T0 F f_s (``RadarConfig.noise_power_w``: complex
sampling, noise bandwidth = ADC rate). The beat tone of amplitude sqrt(P_r) therefore has a
per-sample SNR P_r / (k T0 F f_s); an unwindowed FFT over N_s samples and N_c chirps adds the
coherent gain N_s N_c to the peak of a tone centred in its bin, and summing power over N_v virtual
channels non-coherently (a detection map) adds N_v to the signal and the noise alike.
"""

from __future__ import annotations

import numpy as np

from blindspot.arrays import checked_array
from blindspot.radar.config import RadarConfig


class RadarEquationError(ValueError):
    """A radar cross-section or range that is not a finite real array (RCS >= 0, range > 0)."""


def db_to_linear(db: float | np.ndarray) -> float | np.ndarray:
    """Power ratio from dB."""
    return 10.0 ** (np.asarray(db, dtype=float) / 10.0)


def received_power_w(radar: RadarConfig, rcs_m2: np.ndarray | float,
                     range_m: np.ndarray | float) -> np.ndarray:
    """P_r = P_t G_t G_r lambda^2 sigma / ((4 pi)^3 R^4), W, for one TX firing (TDM-MIMO).

    rcs_m2, range_m : broadcastable arrays (m^2 >= 0, m > 0). Wavelength at the sweep centre.
    Raises RadarEquationError for NaN/inf, negative RCS, a range <= 0 or non-real input.
    """
    rcs = checked_array(rcs_m2, "rcs_m2", RadarEquationError, kind="real", nonnegative=True,
                        where="received_power_w", axes="radar cross-sections in m^2")
    r = checked_array(range_m, "range_m", RadarEquationError, kind="real",
                      where="received_power_w", axes="ranges in m").astype(float)
    if r.size and r.min() <= 0:
        raise RadarEquationError(f"received_power_w: range_m must be positive (the radar "
                                 f"equation diverges at R = 0); found a minimum of {r.min()}")
    p_t = 1e-3 * db_to_linear(radar.tx_power_dbm)
    g = db_to_linear(radar.tx_gain_dbi) * db_to_linear(radar.rx_gain_dbi)
    lam = radar.wavelength_m
    return p_t * g * lam**2 * rcs.astype(float) / ((4 * np.pi) ** 3 * r**4)


def snr_per_sample(radar: RadarConfig, rcs_m2: np.ndarray | float,
                   range_m: np.ndarray | float) -> np.ndarray:
    """Beat-signal power over thermal noise power per complex ADC sample (linear)."""
    return received_power_w(radar, rcs_m2, range_m) / radar.noise_power_w


def snr_range_doppler(radar: RadarConfig, rcs_m2: np.ndarray | float,
                      range_m: np.ndarray | float) -> np.ndarray:
    """SNR (linear) at the peak of one virtual channel's unwindowed 2-D FFT, target centred in
    its range and Doppler bins: per-sample SNR times the coherent gain n_samples * n_chirps."""
    return snr_per_sample(radar, rcs_m2, range_m) * radar.n_samples * radar.n_chirps
