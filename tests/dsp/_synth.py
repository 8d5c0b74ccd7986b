"""Independent point-target tone generator for the DSP tests (no simulator, no chain code).

cube[c, t, r, s] = sum_k a_k exp(j 2 pi (fb_k s / fs + fd_k (c T_loop + t T_chirp)
                                         + p_az[t, r] sin theta_k)) + noise
with fb = 2 S R / c, fd = 2 v / lambda and p_az the virtual azimuth positions in wavelengths
(elevation phase omitted: targets at elevation 0).
"""

from __future__ import annotations

import numpy as np

from blindspot.radar.array import VirtualArray
from blindspot.radar.config import SPEED_OF_LIGHT, RadarConfig


def tone_cube(radar: RadarConfig, array: VirtualArray, targets, *, noise_power: float = 0.0,
              rng: np.random.Generator | None = None) -> np.ndarray:
    """targets: iterable of (range_m, velocity_mps, angle_deg, amplitude). complex64
    (chirps, tx, rx, samples); noise is circular complex Gaussian of ``noise_power`` per sample."""
    c = np.arange(radar.n_chirps)[:, None, None, None]
    t = np.arange(radar.n_tx)[None, :, None, None]
    s = np.arange(radar.n_samples)[None, None, None, :]
    p = (array.virtual_pos[..., 0] * array.spacing_wl)[None, :, :, None]
    cube = np.zeros((radar.n_chirps, radar.n_tx, radar.n_rx, radar.n_samples), np.complex128)
    for rng_m, v, ang, amp in targets:
        fb = 2 * radar.slope_hz_per_s * rng_m / SPEED_OF_LIGHT
        fd = 2 * v / radar.wavelength_m
        slow = c * radar.loop_period_s + t * radar.chirp_period_s
        phase = fb * s / radar.adc_rate_hz + fd * slow + p * np.sin(np.radians(ang))
        cube += amp * np.exp(2j * np.pi * phase)
    if noise_power > 0:
        rng = rng or np.random.default_rng(0)
        cube += np.sqrt(noise_power / 2) * (rng.standard_normal(cube.shape)
                                            + 1j * rng.standard_normal(cube.shape))
    return cube.astype(np.complex64)


def mmwcas():
    """The paper's MMWCAS profile and its virtual array."""
    from omegaconf import OmegaConf

    from blindspot.radar.array import array_for
    from tests.conftest import REPO_ROOT

    radar = RadarConfig.from_mapping(
        OmegaConf.to_container(OmegaConf.load(REPO_ROOT / "conf/radar/mmwcas.yaml")))
    return radar, array_for(radar)
