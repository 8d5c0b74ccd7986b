"""Analytic range-Doppler patches of point scatterers: the FFT output without the FFT.

For a sum of point scatterers the FMCW beat signal is a sum of complex tones that separate into a
fast-time factor (beat frequency), a slow-time factor (Doppler across chirp loops), and a
per-channel factor (Doppler phase gained in each TX slot, spatial phase across the virtual array).
The windowed range FFT and Doppler FFT of such a cube are therefore, exactly, the window's
discrete-time Fourier transform evaluated at the bin frequencies:

    X[k, d, c] = sum_s a_s  W_r(f_s / f_s_adc - k / N)  W_d(nu_s - (d - M//2) / M)  C_s[c]

with ``W(nu) = sum_n w[n] exp(j 2 pi nu n)``. This module evaluates that expression for a *patch*
of range bins (all Doppler bins, chosen virtual channels) around the targets of many frames at
once, and draws the receiver noise with exactly the statistics the FFT gives it (the variance
``sigma^2 sum w_r^2 sum w_d^2`` per cell and the correlation a window puts between neighbouring
bins). It is the fast path of the training-data generator (:mod:`blindspot.synth.path_measurement`),
which runs the detection chain on such patches instead of on 64 x 12 x 16 x 256 cubes.

Signal model (the same as :mod:`blindspot.radar.simulator`; SI units)
--------------------------------------------------------------------
Sample n of chirp loop m, TX slot t (firing order), RX r, for a scatterer at range R, radial
velocity v (positive = receding) and azimuth theta (positive towards +x)::

    x = a exp(j [phi_0 + 2 pi (f_b n / f_adc + f_D (m T_loop + t T_chirp)) + psi_{t r}(theta)])

with ``f_b = 2 S R / c + f_D`` (S the chirp slope), ``f_D = 2 v / lambda`` (centre wavelength),
``T_loop`` the loop period, ``T_chirp`` the chirp period, ``phi_0 = 4 pi f_0 R / c`` and ``psi``
the spatial phase of the virtual element (see :func:`spatial_phase`). FFT conventions follow :mod:`blindspot.dsp.range_doppler`: unnormalised
sums, periodic windows of peak 1, Doppler zero-centred (bin ``d`` has signed index ``d - M // 2``).

Shapes: ``B`` frames, ``S`` scatterers per frame (pad with amplitude 0), ``K`` range bins in the
patch, ``M`` Doppler bins (= chirp loops), ``C`` virtual channels.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.fft as sfft

from blindspot.radar.array import VirtualArray
from blindspot.radar.config import SPEED_OF_LIGHT, RadarConfig

__all__ = [
    "PointScatterers",
    "tone_dft",
    "beat_frequency_hz",
    "doppler_frequency_hz",
    "spatial_phase",
    "channel_phasors",
    "patch_factors",
    "range_doppler_patch",
    "channel_energy",
    "patch_terms",
    "separable_channel_energy",
    "range_noise_covariance",
    "post_fft_noise_power",
    "block_noise_covariance",
    "patch_noise",
    "channel_selection",
]


@dataclass(frozen=True)
class PointScatterers:
    """Point scatterers of ``B`` frames with ``S`` scatterers each (all arrays (B, S)).

    Attributes:
        range_m: range of each scatterer from the radar, m.
        velocity_mps: radial velocity, m/s, positive = moving away from the radar.
        azimuth_rad: azimuth, rad, positive towards +x (x = R sin theta, y = R cos theta).
        amplitude: complex amplitude of the beat tone at the ADC (sqrt of received power, W^0.5,
            times the carrier phase); 0 pads a frame with fewer scatterers.
        elevation_rad: elevation above the radar's horizontal plane, rad (None = 0). The unit
            vector to the scatterer is (sin az cos el, cos az cos el, sin el).
    """

    range_m: np.ndarray
    velocity_mps: np.ndarray
    azimuth_rad: np.ndarray
    amplitude: np.ndarray
    elevation_rad: np.ndarray | None = None

    def __post_init__(self) -> None:
        shape = np.shape(self.range_m)
        if self.elevation_rad is None:
            object.__setattr__(self, "elevation_rad", np.zeros(shape))
        for name in ("velocity_mps", "azimuth_rad", "amplitude", "elevation_rad"):
            if np.shape(getattr(self, name)) != shape:
                raise ValueError(
                    f"PointScatterers.{name}: expected shape {shape} like range_m, "
                    f"found {np.shape(getattr(self, name))}"
                )
        if len(shape) != 2:
            raise ValueError("PointScatterers: expected (frames, scatterers) arrays, found shape "
                             f"{shape}")

    @property
    def shape(self) -> tuple[int, int]:
        return np.shape(self.range_m)  # type: ignore[return-value]


# ---------------------------------------------------------------------------------- 1-D kernels
@lru_cache(maxsize=32)
def _dft_columns(n: int, n_bins: int) -> np.ndarray:
    """(n, n_bins) complex128 exp(-j 2 pi p i / n) for i < n, p < n_bins (read-only)."""
    e = np.exp(-2j * np.pi * np.outer(np.arange(n), np.arange(n_bins)) / n)
    e.setflags(write=False)
    return e


def tone_dft(freq_cycles: np.ndarray, first_bin: np.ndarray | int, n_bins: int,
             window: np.ndarray) -> np.ndarray:
    """Windowed DFT of unit complex tones at ``n_bins`` consecutive bins.

    ``X[..., p] = sum_i w[i] exp(j 2 pi f i) exp(-j 2 pi (k0 + p) i / N)`` for p = 0..n_bins-1,
    i.e. exactly ``np.fft.fft(w * exp(j 2 pi f i))[(k0 + p) % N]``.

    Args:
        freq_cycles: (...) tone frequencies in cycles per sample (any real value; aliases wrap).
        first_bin: (...) or scalar integer k0, the first bin of the patch (may be negative).
        n_bins: number of consecutive bins.
        window: (N,) real or complex window.

    Returns:
        complex128 (..., n_bins).

    The tone is demodulated to bin k0 first (N complex exponentials per tone), then one matrix
    product with the (N, n_bins) DFT columns gives all bins, so the cost is O(N * n_bins) per tone
    in BLAS with no approximation.
    """
    w = np.asarray(window)
    n = w.shape[0]
    f = np.asarray(freq_cycles, dtype=np.float64)
    k0 = np.broadcast_to(np.asarray(first_bin, dtype=np.float64), f.shape)
    # Reduce the demodulation frequency to [-0.5, 0.5) cycles/sample for accurate phases.
    nu = f - k0 / n
    nu = nu - np.round(nu)
    i = np.arange(n, dtype=np.float64)
    demod = w * np.exp(2j * np.pi * nu[..., None] * i)
    # one 2-D GEMM (numpy's stacked matmul loops over the leading axes outside BLAS)
    return (demod.reshape(-1, n) @ _dft_columns(n, n_bins)).reshape(f.shape + (n_bins,))


# ----------------------------------------------------------------------------------- physics
def beat_frequency_hz(range_m: np.ndarray, velocity_mps: np.ndarray | float, radar: RadarConfig,
                      *, include_doppler: bool = True) -> np.ndarray:
    """Fast-time beat frequency ``2 S R / c`` (+ ``2 v / lambda`` when ``include_doppler``)."""
    fb = 2.0 * radar.slope_hz_per_s * np.asarray(range_m, dtype=np.float64) / SPEED_OF_LIGHT
    if include_doppler:
        fb = fb + doppler_frequency_hz(velocity_mps, radar)
    return fb


def doppler_frequency_hz(velocity_mps: np.ndarray | float, radar: RadarConfig) -> np.ndarray:
    """Doppler frequency ``2 v / lambda`` (positive for a receding target), Hz."""
    return 2.0 * np.asarray(velocity_mps, dtype=np.float64) / radar.wavelength_m


def spatial_phase(azimuth_rad: np.ndarray, positions_wl: np.ndarray,
                  elevation_rad: np.ndarray | None = None,
                  elevation_positions_wl: np.ndarray | None = None) -> np.ndarray:
    """Phase of each virtual element for a far-field target, the simulator's convention:
    ``+2 pi (p_az u_x - p_el u_z)`` with ``u_x = sin(az) cos(el)``, ``u_z = sin(el)`` (the array's
    azimuth axis increases towards -x, so the steering vector is ``exp(+j 2 pi p sin theta)``;
    see :mod:`blindspot.radar.simulator`). (...), (C,) [, (...), (C,)] -> (..., C), rad."""
    az = np.asarray(azimuth_rad)
    el = np.zeros_like(az, dtype=float) if elevation_rad is None else np.asarray(elevation_rad)
    phase = 2.0 * np.pi * (np.sin(az) * np.cos(el))[..., None] * np.asarray(positions_wl)
    if elevation_positions_wl is not None:
        phase = phase - 2.0 * np.pi * np.sin(el)[..., None] * np.asarray(elevation_positions_wl)
    return phase


def channel_selection(array: VirtualArray, channels: str | tuple[np.ndarray, np.ndarray] = "all"
                      ) -> tuple[np.ndarray, np.ndarray]:
    """(tx_idx (C,), rx_idx (C,)) of the virtual channels a patch holds: ``"all"`` (tx-major, the
    order of ``rd.reshape(..., n_tx * n_rx)``), ``"ula"`` (``array.ula_index``) or explicit."""
    if isinstance(channels, str):
        if channels == "all":
            t, r = np.meshgrid(np.arange(array.n_tx), np.arange(array.n_rx), indexing="ij")
            return t.ravel(), r.ravel()
        if channels == "ula":
            t, r = array.ula_index
            return np.asarray(t), np.asarray(r)
        raise ValueError(f"channels: expected 'all', 'ula' or (tx_idx, rx_idx), found {channels!r}")
    t, r = (np.asarray(a, dtype=int) for a in channels)
    if t.shape != r.shape or t.ndim != 1:
        raise ValueError("channels: expected two equal 1-D index arrays, found shapes "
                         f"{t.shape}, {r.shape}")
    return t, r


def channel_phasors(velocity_mps: np.ndarray, azimuth_rad: np.ndarray, radar: RadarConfig,
                    array: VirtualArray, channels: str | tuple[np.ndarray, np.ndarray] = "all",
                    elevation_rad: np.ndarray | None = None) -> np.ndarray:
    """Per-channel factor of each scatterer: the Doppler phase gained by the TX slot (TDM-MIMO)
    times the spatial phase of the virtual element (azimuth and elevation positions).
    (B, S), (B, S)[, (B, S)] -> complex128 (B, S, C)."""
    t_idx, r_idx = channel_selection(array, channels)
    pos_wl = array.virtual_pos[t_idx, r_idx, 0] * array.spacing_wl
    el_wl = array.virtual_pos[t_idx, r_idx, 1] * array.spacing_wl
    slot_s = radar.tx_slot_times_s()[t_idx]
    fd = doppler_frequency_hz(velocity_mps, radar)
    phase = 2.0 * np.pi * fd[..., None] * slot_s + spatial_phase(
        azimuth_rad, pos_wl, elevation_rad, el_wl if np.any(el_wl) else None)
    return np.exp(1j * phase)


def patch_terms(scatterers: PointScatterers, radar: RadarConfig, array: VirtualArray,
                first_range_bin: np.ndarray, n_range: int, range_window: np.ndarray,
                doppler_window: np.ndarray,
                channels: str | tuple[np.ndarray, np.ndarray] = "all",
                *, include_doppler_in_beat: bool = True
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The three separable factors of a patch:
    ``X[b, k, d, c] = sum_s R[b, s, k] D[b, s, d] C[b, s, c]``.

    Returns:
        R: complex128 (B, S, K) amplitude times windowed range response at the patch's bins;
        D: complex128 (B, S, M) windowed Doppler response, zero-centred bins;
        C: complex128 (B, S, C) channel phasors (:func:`channel_phasors`).
    See :func:`range_doppler_patch` for the arguments.
    """
    b, s = scatterers.shape
    m = doppler_window.shape[0]
    if m != radar.n_chirps or range_window.shape[0] != radar.n_samples:
        raise ValueError(
            f"windows: expected range window of {radar.n_samples} and Doppler window of "
            f"{radar.n_chirps} points for profile '{radar.name}', found "
            f"{range_window.shape[0]} and {m}")
    first = np.asarray(first_range_bin, dtype=np.int64).reshape(b)
    fb = beat_frequency_hz(scatterers.range_m, scatterers.velocity_mps, radar,
                           include_doppler=include_doppler_in_beat)
    rng_k = tone_dft(fb / radar.adc_rate_hz, first[:, None], n_range, range_window)  # (B,S,K)
    nu_d = doppler_frequency_hz(scatterers.velocity_mps, radar) * radar.loop_period_s
    dop = tone_dft(nu_d, -(m // 2), m, doppler_window)  # (B,S,M)
    ch = channel_phasors(scatterers.velocity_mps, scatterers.azimuth_rad, radar, array, channels,
                         scatterers.elevation_rad)
    return rng_k * np.asarray(scatterers.amplitude)[..., None], dop, ch


def patch_factors(scatterers: PointScatterers, radar: RadarConfig, array: VirtualArray,
                  first_range_bin: np.ndarray, n_range: int, range_window: np.ndarray,
                  doppler_window: np.ndarray,
                  channels: str | tuple[np.ndarray, np.ndarray] = "all",
                  *, include_doppler_in_beat: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The two factors of a patch: ``X[b, k, d, c] = sum_s A[b, s, k, d] C[b, s, c]``.

    Returns:
        A: complex128 (B, S, K, M) amplitude times range response times Doppler response;
        C: complex128 (B, S, C) channel phasors (:func:`channel_phasors`).
    See :func:`range_doppler_patch` for the arguments.
    """
    r, d, ch = patch_terms(scatterers, radar, array, first_range_bin, n_range, range_window,
                           doppler_window, channels,
                           include_doppler_in_beat=include_doppler_in_beat)
    return r[:, :, :, None] * d[:, :, None, :], ch


def range_doppler_patch(scatterers: PointScatterers, radar: RadarConfig, array: VirtualArray,
                        first_range_bin: np.ndarray, n_range: int, range_window: np.ndarray,
                        doppler_window: np.ndarray,
                        channels: str | tuple[np.ndarray, np.ndarray] = "all",
                        *, include_doppler_in_beat: bool = True,
                        dtype: type = np.complex64) -> np.ndarray:
    """Noise-free range-Doppler patch of point scatterers, analytically.

    Args:
        scatterers: B frames of S scatterers.
        first_range_bin: (B,) integer first range bin of each frame's patch.
        n_range: K, range bins in the patch (bins first..first+K-1, wrapping like the FFT).
        range_window: (N,) window of the range FFT (peak 1, as the dsp module uses).
        doppler_window: (M,) window of the Doppler FFT (real; zero-centring is done here).
        channels: virtual channels to return, see :func:`channel_selection`.
        include_doppler_in_beat: add the Doppler frequency to the fast-time beat frequency.

    Returns:
        (B, K, M, C) complex: equal to ``range_doppler(cube)[first:first+K, :, tx, rx]`` of the
        directly synthesised cube of the same scatterers, Doppler zero-centred.
    """
    a, ch = patch_factors(scatterers, radar, array, first_range_bin, n_range, range_window,
                          doppler_window, channels, include_doppler_in_beat=include_doppler_in_beat)
    b, s, k, m = a.shape
    out = np.matmul(a.reshape(b, s, k * m).transpose(0, 2, 1), ch)  # (B, K*M, C)
    return out.reshape(b, k, m, ch.shape[-1]).astype(dtype, copy=False)


def separable_channel_energy(range_terms: np.ndarray, doppler_terms: np.ndarray,
                             phasors: np.ndarray) -> np.ndarray:
    """:func:`channel_energy` for separable factors ``A = R[s, k] D[s, d]``, as one batched
    matrix product: ``E[k, d] = Re sum_{s,s'} (conj(R_s) R_s' G_ss')[k] (conj(D_s) D_s')[d]``.

    range_terms (B, S, K), doppler_terms (B, S, M), phasors (B, S, C) -> float64 (B, K, M).
    Cost B K M S^2 (one batched complex GEMM in numpy, OpenBLAS's pinned kernels), independent
    of the number of channels."""
    b, s, k = range_terms.shape
    gram = np.conj(phasors) @ np.swapaxes(phasors, 1, 2)                      # (B, S, S)
    p = (np.conj(range_terms)[:, :, None, :] * range_terms[:, None, :, :]
         * gram[..., None]).reshape(b, s * s, k)                              # (B, S*S, K)
    q = (np.conj(doppler_terms)[:, :, None, :] * doppler_terms[:, None, :, :]
         ).reshape(b, s * s, -1)                                              # (B, S*S, M)
    e = p.transpose(0, 2, 1) @ q                                              # (B, K, M)
    return np.ascontiguousarray(e.real)


def channel_energy(factors: np.ndarray, phasors: np.ndarray) -> np.ndarray:
    """Signal energy summed over channels, ``sum_c |sum_s A[s] C[s, c]|^2``, per cell, without
    forming the channels: ``sum_{s,s'} conj(A_s) G[s, s'] A_s'`` with the Gram matrix
    ``G = conj(C) C^T`` of the scatterers' channel phasors.

    factors: (B, S, K, M), phasors: (B, S, C) -> float64 (B, K, M)."""
    b, s, k, m = factors.shape
    gram = np.conj(phasors) @ np.swapaxes(phasors, 1, 2)  # (B, S, S)
    a = factors.reshape(b, s, k * m)
    ga = gram @ a
    return np.real(np.einsum("bsx,bsx->bx", np.conj(a), ga)).reshape(b, k, m)


# ------------------------------------------------------------------------------------ noise
def range_noise_covariance(range_window: np.ndarray, n_range: int) -> np.ndarray:
    """(K, K) covariance of the range-FFT output of unit-variance white complex noise over K
    consecutive bins: ``C[i, j] = sum_n |w[n]|^2 exp(-j 2 pi (i - j) n / N)`` (Hermitian Toeplitz;
    a Hann window correlates neighbouring bins by -2/3)."""
    w2 = np.abs(np.asarray(range_window, dtype=np.complex128)) ** 2
    n = w2.shape[0]
    lags = np.arange(n_range)
    col = w2 @ np.exp(-2j * np.pi * np.outer(np.arange(n), lags) / n)  # C[lag, 0]
    idx = lags[:, None] - lags[None, :]
    return np.where(idx >= 0, col[np.abs(idx)], np.conj(col[np.abs(idx)]))


def block_noise_covariance(range_window: np.ndarray, doppler_window: np.ndarray,
                           n_range: int, n_doppler: int) -> np.ndarray:
    """(n_range * n_doppler)^2 covariance of the range-Doppler noise over a block of consecutive
    cells (row-major: range outer, Doppler inner) for unit noise power per ADC sample:
    ``kron(C_range, C_doppler)`` (the two FFTs act on independent axes). The diagonal is
    ``sum w_r^2 sum w_d^2``."""
    return np.kron(range_noise_covariance(range_window, n_range),
                   range_noise_covariance(doppler_window, n_doppler))


def post_fft_noise_power(noise_power_w: float, range_window: np.ndarray,
                         doppler_window: np.ndarray) -> float:
    """Noise power per range-Doppler cell and channel: ``sigma^2 sum w_r^2 sum w_d^2``."""
    return float(noise_power_w * np.sum(np.abs(range_window) ** 2)
                 * np.sum(np.abs(doppler_window) ** 2))


def patch_noise(rng: np.random.Generator, n_frames: int, n_range: int, n_channels: int,
                noise_power_w: float, range_window: np.ndarray, doppler_window: np.ndarray,
                *, dtype: type = np.complex64) -> np.ndarray:
    """Receiver noise of a (B, K, M, C) range-Doppler patch with the FFT's exact statistics.

    White complex Gaussian noise of power ``noise_power_w`` per ADC sample, range-FFT'd over N
    samples and Doppler-FFT'd over M loops, is zero-mean Gaussian with the covariance of
    :func:`range_noise_covariance` (times sigma^2) across range bins and the circulant covariance
    of the Doppler window across Doppler bins, independent across channels. It is drawn here as
    ``L z`` over range (L the Cholesky factor) and as the windowed FFT of white noise over the M
    chirp loops, so every cell has variance ``post_fft_noise_power`` and neighbours carry the
    window's correlation. Cost: 2 K M C normal draws per frame.
    """
    m = doppler_window.shape[0]
    cov = range_noise_covariance(range_window, n_range)
    chol = np.linalg.cholesky(cov + 1e-12 * np.real(cov[0, 0]) * np.eye(n_range))
    scale = np.sqrt(noise_power_w / 2.0)
    real = np.float32 if np.dtype(dtype) == np.complex64 else np.float64
    z = rng.standard_normal((n_frames, n_range, m, n_channels, 2), dtype=real)
    z = z.view(np.dtype(dtype))[..., 0]
    z *= scale
    # Doppler: windowed, zero-centred FFT over loops (axis 2).
    wd = np.asarray(doppler_window) * np.exp(2j * np.pi * np.arange(m) * (m // 2) / m)
    z *= wd.astype(dtype)[None, None, :, None]
    z = sfft.fft(z, axis=2, overwrite_x=True)
    # Range: correlate with the Cholesky factor (K, K) over axis 1.
    out = np.matmul(chol.astype(dtype), z.reshape(n_frames, n_range, m * n_channels))
    return out.reshape(n_frames, n_range, m, n_channels)
