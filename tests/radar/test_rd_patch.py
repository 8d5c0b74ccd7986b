"""The analytic range-Doppler patch against numpy's FFT of a directly synthesised cube.

The reference cube is written here straight from the beat-signal model of
``blindspot.radar.simulator`` (one complex exponential per sample, chirp loop, TX slot and RX, no
shortcuts), windowed and transformed with ``np.fft`` and ``np.fft.fftshift``: truth that owes
nothing to the patch's DTFT algebra. A second test uses the simulator's own cube.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

from blindspot.radar.array import array_for
from blindspot.radar.config import SPEED_OF_LIGHT, RadarConfig
from blindspot.radar.rd_patch import (
    PointScatterers,
    channel_energy,
    channel_selection,
    patch_factors,
    patch_terms,
    separable_channel_energy,
    patch_noise,
    post_fft_noise_power,
    range_doppler_patch,
    range_noise_covariance,
    tone_dft,
)

SMALL = dict(name="small", start_freq_hz=77e9, bandwidth_hz=300e6, ramp_time_s=10e-6,
             idle_time_s=5e-6, adc_rate_hz=6.4e6, n_samples=64, n_chirps=16, n_tx=2, n_rx=4,
             frame_period_s=0.05, array="ula", rx_spacing_wl=0.5)
MMWCAS = dict(name="mmwcas", start_freq_hz=76.85e9, bandwidth_hz=300e6, ramp_time_s=30e-6,
              idle_time_s=5e-6, adc_rate_hz=256 / 30e-6, n_samples=256, n_chirps=64, n_tx=12,
              n_rx=16, tx_order=list(range(11, -1, -1)), frame_period_s=0.1, array="mmwcas")


def hann(n: int) -> np.ndarray:
    return scipy.signal.get_window("hann", n, fftbins=True)


def synthesise_cube(radar: RadarConfig, array, r, v, theta, amp, el=None) -> np.ndarray:
    """(chirps, tx, rx, samples) beat signal of point scatterers, sample by sample."""
    el = np.zeros(len(r)) if el is None else el
    pos_el = (array.virtual_pos[..., 1] * array.spacing_wl)[None, :, :, None]
    n = np.arange(radar.n_samples)[None, None, None, :]
    m = np.arange(radar.n_chirps)[:, None, None, None]
    t = np.arange(radar.n_tx)[None, :, None, None]
    pos = (array.virtual_pos[..., 0] * array.spacing_wl)[None, :, :, None]
    cube = np.zeros((radar.n_chirps, radar.n_tx, radar.n_rx, radar.n_samples), complex)
    lam = SPEED_OF_LIGHT / radar.center_freq_hz
    for rs, vs, ths, a, es in zip(r, v, theta, amp, el):
        fb = 2 * radar.slope_hz_per_s * rs / SPEED_OF_LIGHT + 2 * vs / lam
        fd = 2 * vs / lam
        time_slow = m * radar.n_tx * (radar.ramp_time_s + radar.idle_time_s) \
            + t * (radar.ramp_time_s + radar.idle_time_s)
        phase = 2 * np.pi * (fb * n / radar.adc_rate_hz + fd * time_slow) \
            + 2 * np.pi * (pos * np.sin(ths) * np.cos(es) - pos_el * np.sin(es))
        cube += a * np.exp(1j * phase)
    return cube


def fft_range_doppler(cube: np.ndarray, wr: np.ndarray, wd: np.ndarray) -> np.ndarray:
    """(chirps, tx, rx, samples) -> (range, doppler, tx, rx), Doppler fftshifted."""
    x = np.fft.fft(cube * wr, axis=3)
    x = np.fft.fft(x * wd[:, None, None, None], axis=0)
    x = np.fft.fftshift(x, axes=0)
    return np.moveaxis(x, 3, 0)


@pytest.mark.parametrize("profile", [SMALL, MMWCAS], ids=["small-ula", "mmwcas"])
def test_patch_equals_fft_of_synthesised_cube(profile):
    radar = RadarConfig.from_mapping(profile)
    array = array_for(radar)
    rng = np.random.default_rng(3)
    s = 4
    r = rng.uniform(3.0, 0.6 * radar.max_range_m, s)
    v = rng.uniform(-0.9, 0.9, s) * radar.max_velocity_mps
    theta = np.deg2rad(rng.uniform(-70, 70, s))
    amp = rng.uniform(0.5, 2.0, s) * np.exp(2j * np.pi * rng.uniform(size=s))
    el = rng.uniform(-0.3, 0.3, s)
    wr, wd = hann(radar.n_samples), hann(radar.n_chirps)
    truth = fft_range_doppler(synthesise_cube(radar, array, r, v, theta, amp, el), wr, wd)

    k0 = int(np.floor(r.min() / radar.range_bin_m)) - 3
    n_range = int(np.ceil(r.max() / radar.range_bin_m)) + 4 - k0
    scat = PointScatterers(r[None], v[None], theta[None], amp[None], el[None])
    for channels in ("all", "ula"):
        patch = range_doppler_patch(scat, radar, array, np.array([k0]), n_range, wr, wd,
                                    channels, dtype=np.complex128)[0]
        t_idx, r_idx = channel_selection(array, channels)
        ref = truth[k0:k0 + n_range][:, :, t_idx, r_idx]
        assert patch.shape == ref.shape
        rel = np.abs(patch - ref).max() / np.abs(ref).max()
        assert rel < 1e-4, f"{channels}: relative error {rel:.2e}"


def test_patch_matches_dsp_range_doppler_convention():
    """Same numbers as the detection chain's own range_doppler (zero-centring by modulation)."""
    rd_mod = pytest.importorskip("blindspot.dsp.range_doppler")
    radar = RadarConfig.from_mapping(SMALL)
    array = array_for(radar)
    r, v, th, a = np.array([7.3]), np.array([-3.1]), np.array([0.4]), np.array([1.0 + 0.5j])
    cube = synthesise_cube(radar, array, r, v, th, a).astype(np.complex64)
    rd = rd_mod.range_doppler(cube)
    wr, wd = rd_mod.window("hann", radar.n_samples), rd_mod.window("hann", radar.n_chirps)
    patch = range_doppler_patch(PointScatterers(r[None], v[None], th[None], a[None]), radar, array,
                                np.array([10]), 12, wr, wd, "all")[0]
    ref = rd[10:22].reshape(12, radar.n_chirps, -1)
    assert np.abs(patch - ref).max() / np.abs(ref).max() < 1e-4


def test_patch_wraps_around_the_range_axis_and_pads():
    """A patch starting below bin 0 wraps like the FFT does; zero-amplitude padding adds nothing."""
    radar = RadarConfig.from_mapping(SMALL)
    array = array_for(radar)
    wr, wd = hann(radar.n_samples), hann(radar.n_chirps)
    r, v = np.array([0.7, 5.0]), np.array([1.0, 0.0])
    th, a = np.array([0.1, 0.0]), np.array([1.0, 0.0])
    truth = fft_range_doppler(synthesise_cube(radar, array, r[:1], v[:1], th[:1], a[:1]), wr, wd)
    patch = range_doppler_patch(PointScatterers(r[None], v[None], th[None], a[None]), radar, array,
                                np.array([-3]), 8, wr, wd, dtype=np.complex128)[0]
    ref = truth[np.arange(-3, 5) % radar.n_samples].reshape(8, radar.n_chirps, -1)
    assert np.abs(patch - ref).max() / np.abs(ref).max() < 1e-4


def test_tone_dft_is_the_windowed_fft():
    rng = np.random.default_rng(0)
    w = hann(50) * (1 + 0.1 * rng.standard_normal(50))  # any window, not only Hann
    f = rng.uniform(-3, 3, 7)
    got = tone_dft(f, 45, 10, w)  # bins 45..54 wrap past N = 50
    ref = np.fft.fft(w * np.exp(2j * np.pi * f[:, None] * np.arange(50)), axis=1)
    np.testing.assert_allclose(got, ref[:, np.arange(45, 55) % 50], rtol=0, atol=1e-9)


def test_noise_statistics_match_fft_of_white_noise():
    """Patch noise vs numpy FFT of white ADC noise: per-cell variance sigma^2 sum w_r^2 sum w_d^2
    and the window's correlation between neighbouring range and Doppler bins."""
    radar = RadarConfig.from_mapping(SMALL)
    n, m, k, c = radar.n_samples, radar.n_chirps, 6, 3
    wr, wd = hann(n), hann(m)
    sigma2 = 2.5
    rng = np.random.default_rng(11)
    frames = 4000
    noise = patch_noise(rng, frames, k, c, sigma2, wr, wd, dtype=np.complex128)
    assert noise.shape == (frames, k, m, c)
    white = np.sqrt(sigma2 / 2) * (rng.standard_normal((frames, m, c, n))
                                   + 1j * rng.standard_normal((frames, m, c, n)))
    ref = np.fft.fftshift(np.fft.fft(np.fft.fft(white * wr, axis=3) * wd[:, None, None], axis=1),
                          axes=1)[..., 20:20 + k]                     # (frames, m, c, k)
    ref = np.moveaxis(ref, 3, 1)                                       # (frames, k, m, c)

    expected = post_fft_noise_power(sigma2, wr, wd)
    for x in (noise, ref):
        var = np.mean(np.abs(x) ** 2)
        assert var == pytest.approx(expected, rel=0.02)

    def corr(x, axis):
        a = np.take(x, np.arange(x.shape[axis] - 1), axis=axis)
        b = np.take(x, np.arange(1, x.shape[axis]), axis=axis)
        return np.mean(a * np.conj(b)) / np.mean(np.abs(x) ** 2)

    for axis in (1, 2):
        assert abs(corr(noise, axis) - corr(ref, axis)) < 0.02
    # Hann: neighbouring bins correlate by -2/3, bins two apart by +1/6 (theory).
    assert corr(noise, 1).real == pytest.approx(-2 / 3, abs=0.02)
    cov = range_noise_covariance(wr, 3) / np.sum(wr ** 2)
    np.testing.assert_allclose(cov[0], [1, -2 / 3, 1 / 6], atol=1e-12)
    # Real and imaginary parts independent and equal (circular noise).
    assert abs(np.mean(noise ** 2)) / expected < 0.02


def test_channel_energy_is_the_channel_sum_of_the_patch():
    radar = RadarConfig.from_mapping(MMWCAS)
    array = array_for(radar)
    rng = np.random.default_rng(5)
    b, s = 3, 5
    scat = PointScatterers(rng.uniform(4, 6, (b, s)), rng.uniform(-2, 2, (b, s)),
                           rng.uniform(-1, 1, (b, s)),
                           np.exp(2j * np.pi * rng.uniform(size=(b, s))),
                           elevation_rad=rng.uniform(-0.2, 0.2, (b, s)))
    wr, wd = hann(radar.n_samples), hann(radar.n_chirps)
    first = np.array([6, 7, 8])
    patch = range_doppler_patch(scat, radar, array, first, 6, wr, wd, dtype=np.complex128)
    a, c = patch_factors(scat, radar, array, first, 6, wr, wd)
    energy = channel_energy(a, c)
    np.testing.assert_allclose(energy, np.sum(np.abs(patch) ** 2, axis=-1), rtol=1e-9)
    r_t, d_t, c_t = patch_terms(scat, radar, array, first, 6, wr, wd)
    np.testing.assert_allclose(separable_channel_energy(r_t, d_t, c_t), energy, rtol=1e-9,
                               atol=1e-12 * energy.max())


def test_patch_equals_range_doppler_of_the_simulator_cube():
    """The project's simulator (noise off) through the chain's range_doppler: same cells."""
    sim_mod = pytest.importorskip("blindspot.radar.simulator")
    rd_mod = pytest.importorskip("blindspot.dsp.range_doppler")
    radar = RadarConfig.from_mapping(MMWCAS)
    array = array_for(radar)
    sim = sim_mod.FmcwSimulator(radar, array, noise=False)
    rng = np.random.default_rng(9)
    pos = np.column_stack([rng.uniform(-4, 4, 5), rng.uniform(6, 12, 5), rng.uniform(-0.5, 1, 5)])
    vel = np.column_stack([rng.uniform(-2, 2, 5), rng.uniform(-2, 2, 5), np.zeros(5)])
    rcs = rng.uniform(0.05, 0.5, 5)
    rd = rd_mod.range_doppler(sim.frame(pos, vel, rcs))
    r = np.linalg.norm(pos, axis=1)
    u = pos / r[:, None]
    carrier = 4 * np.pi * radar.start_freq_hz * r / SPEED_OF_LIGHT
    from blindspot.radar.radar_equation import received_power_w
    amp = np.sqrt(received_power_w(radar, rcs, r)) * np.exp(1j * carrier)
    scat = PointScatterers(r[None], np.einsum("kd,kd->k", vel, u)[None],
                           np.arctan2(u[:, 0], u[:, 1])[None], amp[None],
                           np.arcsin(u[:, 2])[None])
    wr, wd = rd_mod.window("hann", radar.n_samples), rd_mod.window("hann", radar.n_chirps)
    k0 = 8
    patch = range_doppler_patch(scat, radar, array, np.array([k0]), 20, wr, wd)[0]
    ref = rd[k0:k0 + 20].reshape(20, radar.n_chirps, -1)
    assert np.abs(patch - ref).max() / np.abs(ref).max() < 1e-4


def test_block_noise_covariance_matches_fft_noise():
    """3 x 3 block covariance vs the empirical covariance of FFT'd white noise."""
    from blindspot.radar.rd_patch import block_noise_covariance

    n, m = 32, 16
    wr, wd = hann(n), hann(m)
    rng = np.random.default_rng(8)
    white = (rng.standard_normal((20000, m, n))
             + 1j * rng.standard_normal((20000, m, n))) / np.sqrt(2)
    x = np.fft.fft(np.fft.fft(white * wr, axis=2) * wd[:, None], axis=1)   # (F, doppler, range)
    block = x[:, 5:8, 10:13].transpose(0, 2, 1).reshape(20000, 9)         # range outer
    emp = block.T @ block.conj() / 20000
    cov = block_noise_covariance(wr, wd, 3, 3)
    assert np.abs(emp - cov).max() / cov[0, 0].real < 0.03
