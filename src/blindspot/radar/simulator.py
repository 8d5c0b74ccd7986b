"""FMCW TDM-MIMO baseband simulator: point scatterers -> complex ADC cube (chirps, tx, rx, samples).

Signal model
------------
For scatterer k at slant range R_k (m), radial velocity v_k (m/s, + = receding) and direction
cosines (u_x, u_z), the de-chirped complex beat signal of chirp loop m, TX slot t (firing order),
RX r and ADC sample n is::

    s = a_k exp(j [ 4 pi f0 R_k / c                          carrier phase at frame start
                    + 2 pi f_k n / f_s                        beat tone, f_k = 2 S R_k / c + 2 v_k / lambda
                    + 4 pi v_k (m T_loop + t T_chirp) / lambda    slow-time Doppler, incl. the TX slot
                    + 2 pi d (p_az[t, r] u_x - p_el[t, r] u_z) ])  spatial phase of the virtual element

with a_k = sqrt(P_r,k) 10^(-att_k / 20), P_r from the radar equation (``radar_equation``), f0 the
start of the sampled sweep, S the slope, lambda the centre wavelength, d the array unit in
wavelengths (``VirtualArray.spacing_wl``) and p the virtual positions in those units. Each TX
slot carries its own slot time, so the Doppler-induced phase step of 4 pi v T_chirp / lambda
between consecutive TX that real TDM-MIMO data has is present (and must be compensated before
angle estimation of moving targets).

Sign conventions: a receding target has increasing phase (positive Doppler bins after fftshift,
matching ``RadarConfig.velocity_axis_mps``); the beat tone is a positive frequency (range bin
R / range_bin_m). The azimuth axis of the virtual array is taken to increase towards -x (the
radar's left), so the spatial phase is +2 pi p sin(theta) and the steering vector
a(theta) = exp(+j 2 pi p sin theta) recovers theta with x = R sin theta; elevation increases
upwards.

Approximations (stated): the range change within one frame is neglected in the beat frequency
and the amplitude (range migration: at 2 m/s over the 26.9 ms of MMWCAS chirps a target moves
5.4 cm = 0.11 range bin); velocities are constant within a frame; each scatterer is isotropic
within the antenna beam (gains are boresight gains, no element pattern); no multipath.

Noise: circular complex Gaussian of power k T0 F f_s per sample (``RadarConfig.noise_power_w``),
drawn by Box-Muller from a SFC64 stream seeded by (scene seed, frame index), so any frame can be
regenerated on its own and one seed gives identical bytes. Box-Muller with 24-bit uniforms
truncates |n|^2 at 16.6 times the mean (probability 6e-8 per sample).

Units: without ADC quantisation the cube is in sqrt(W) at the receiver input. With
``radar.adc_bits = b`` it holds ADC codes (integer-valued complex64, I and Q in
[-2^(b-1), 2^(b-1) - 1]) of a converter whose full scale is ``adc_headroom_db`` above the
per-component noise RMS (60 dB: thermal noise spans about 33 LSB RMS at 16 bits); that is what the
capture readers return for real recordings.

Speed: the sum over scatterers is one complex GEMM, (chirps*tx*rx, K) @ (K, samples), whose left
factor is the outer product of the small Doppler (chirps, tx, K) and spatial (tx, rx, K) factors;
the noise is written first and the GEMM accumulates into it (BLAS beta = 1), so the 25 MB cube is
touched only a few times.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
from scipy.linalg import blas

from blindspot.arrays import checked_array
from blindspot.radar.array import VirtualArray, array_for
from blindspot.radar.config import SPEED_OF_LIGHT, RadarConfig, SimConfig
from blindspot.radar.radar_equation import received_power_w
from blindspot.radar.scene import Scene, SceneConfig


class SimulationError(ValueError):
    """Arrays handed to the simulator's codecs or quantiser of the wrong kind or shape, not
    finite, or not representable as ADC codes."""
from blindspot.typed_config import ConfigError

_TWO_PI = 2.0 * np.pi


def frame_bit_generator(seed: int, frame_index: int) -> np.random.SFC64:
    """The noise stream of one frame: SFC64 seeded by SeedSequence([seed, frame_index])."""
    return np.random.SFC64(np.random.SeedSequence([int(seed), int(frame_index)]))


class FmcwSimulator:
    """Baseband cubes of one radar profile and array from point scatterers.

    Not thread-safe: the instance keeps scratch buffers for the noise between calls.
    """

    def __init__(self, radar: RadarConfig, array: VirtualArray | None = None, *,
                 noise: bool = True, adc_headroom_db: float = 60.0):
        self.radar = radar
        self.array = array if array is not None else array_for(radar)
        if (self.array.n_tx, self.array.n_rx) != (radar.n_tx, radar.n_rx):
            raise ValueError(f"array has {self.array.n_tx} TX x {self.array.n_rx} RX but radar "
                             f"'{radar.name}' has {radar.n_tx} x {radar.n_rx}")
        if not (np.isfinite(adc_headroom_db) and 0 < adc_headroom_db < 200):
            raise ConfigError("sim.adc_headroom_db", adc_headroom_db, "a number of dB in (0, 200)")
        self.noise = bool(noise)
        self.adc_headroom_db = float(adc_headroom_db)
        r = radar
        self.shape = (r.n_chirps, r.n_tx, r.n_rx, r.n_samples)
        loops = np.arange(r.n_chirps)[:, None] * r.loop_period_s
        self.slow_time_s = loops + r.tx_slot_times_s()[None, :]          # (chirps, tx)
        self.fast_time_s = np.arange(r.n_samples) / r.adc_rate_hz        # (samples,)
        vp = self.array.virtual_pos.reshape(-1, 2).astype(float) * self.array.spacing_wl
        self.virtual_az_wl, self.virtual_el_wl = vp[:, 0], vp[:, 1]      # (tx*rx,)
        self._scratch: tuple[np.ndarray, np.ndarray] | None = None

    # ------------------------------------------------------------------ scales
    @property
    def noise_power_w(self) -> float:
        return self.radar.noise_power_w

    @property
    def adc_lsb(self) -> float | None:
        """Size of one ADC code in sqrt(W), or None without quantisation."""
        bits = self.radar.adc_bits
        if bits is None:
            return None
        full_scale = np.sqrt(self.noise_power_w / 2) * 10 ** (self.adc_headroom_db / 20)
        return float(full_scale / 2 ** (bits - 1))

    @property
    def output_scale(self) -> float:
        """Cube units per sqrt(W): 1 without quantisation, 1 / LSB with it."""
        lsb = self.adc_lsb
        return 1.0 if lsb is None else 1.0 / lsb

    # ------------------------------------------------------------------ signal
    def signal_factors(self, position_m: np.ndarray, velocity_mps: np.ndarray,
                       rcs_m2: np.ndarray, attenuation_db: np.ndarray | None = None
                       ) -> tuple[np.ndarray, np.ndarray]:
        """Separable factors of the noiseless cube: left (chirps*tx*rx, K) and right (K, samples),
        complex64, with left @ right = cube.reshape(-1, samples) (in sqrt(W)).

        position_m (K, 3) relative to the radar (x, y, z; (K, 2) means z = 0), velocity_mps
        the same shape, rcs_m2 (K,), attenuation_db (K,) or None.
        """
        pos, vel = _xyz(position_m, "position_m"), _xyz(velocity_mps, "velocity_mps")
        k = pos.shape[0]
        rcs = np.broadcast_to(np.asarray(rcs_m2, dtype=float), (k,))
        att = np.zeros(k) if attenuation_db is None else np.broadcast_to(
            np.asarray(attenuation_db, dtype=float), (k,))
        if vel.shape != pos.shape:
            raise ValueError(f"velocity_mps shape {vel.shape} != position_m shape {pos.shape}")
        r = self.radar
        rng = np.linalg.norm(pos, axis=1)
        if np.any(rng <= 0):
            raise ValueError("a scatterer sits at the radar (range 0)")
        u = pos / rng[:, None]
        v_r = np.einsum("kd,kd->k", vel, u)
        lam = r.wavelength_m
        amp = np.sqrt(received_power_w(r, rcs, rng)) * 10 ** (-att / 20) * self.output_scale
        carrier = np.mod(4 * np.pi * r.start_freq_hz * rng / SPEED_OF_LIGHT, _TWO_PI)
        f_beat = 2 * r.slope_hz_per_s * rng / SPEED_OF_LIGHT + 2 * v_r / lam
        right = np.exp(1j * _TWO_PI * f_beat[:, None] * self.fast_time_s[None, :])    # (K, N)
        doppler = np.exp(1j * (4 * np.pi * v_r / lam) * self.slow_time_s[..., None])   # (M, T, K)
        spatial = _TWO_PI * (np.outer(self.virtual_az_wl, u[:, 0])
                             - np.outer(self.virtual_el_wl, u[:, 2]))                  # (T*R, K)
        weight = (amp * np.exp(1j * carrier)) * np.exp(1j * spatial)
        m_, t_, r_, n_ = self.shape
        left = np.empty((m_, t_, r_, k), dtype=np.complex64)
        np.multiply(doppler.astype(np.complex64)[:, :, None, :],
                    weight.astype(np.complex64).reshape(t_, r_, k)[None], out=left)
        return left.reshape(m_ * t_ * r_, k), right.astype(np.complex64)

    # ------------------------------------------------------------------ noise
    def add_noise(self, out: np.ndarray, bit_generator: np.random.BitGenerator) -> np.ndarray:
        """Fill ``out`` (complex64, C-contiguous) with circular Gaussian noise of power
        k T0 F f_s per sample (in cube units), by Box-Muller from 24-bit uniforms."""
        n = out.size
        if self._scratch is None or self._scratch[1].size != n:
            self._scratch = (np.empty(2 * n, np.float32), np.empty(n, np.float32))
        uni, tmp = self._scratch
        raw = bit_generator.random_raw(n).view(np.uint32)       # 2n independent 32-bit words
        np.right_shift(raw, np.uint32(8), out=raw)              # 24-bit integers k in [0, 2^24)
        np.copyto(uni, raw, casting="unsafe")                   # exact in float32
        radius, angle = uni[:n], uni[n:]
        # |z|^2 = -P ln(1 - U), 1 - U = (2^24 - k) 2^-24 in [2^-24, 1]
        np.subtract(np.float32(2**24), radius, out=radius)
        np.log(radius, out=radius)
        np.subtract(np.float32(24 * np.log(2)), radius, out=radius)
        power = self.noise_power_w * self.output_scale**2
        np.multiply(radius, np.float32(power), out=radius)
        np.sqrt(radius, out=radius)
        np.multiply(angle, np.float32(_TWO_PI / 2**24), out=angle)
        flat = out.reshape(-1)
        np.cos(angle, out=tmp)
        np.multiply(tmp, radius, out=flat.real)
        np.sin(angle, out=tmp)
        np.multiply(tmp, radius, out=flat.imag)
        return out

    # ------------------------------------------------------------------ frames
    def frame(self, position_m: np.ndarray, velocity_mps: np.ndarray, rcs_m2: np.ndarray,
              attenuation_db: np.ndarray | None = None, *,
              bit_generator: np.random.BitGenerator | None = None,
              out: np.ndarray | None = None) -> np.ndarray:
        """complex64 (chirps, tx, rx, samples): the scatterers' beat signals plus thermal noise
        (when the simulator has noise; ``bit_generator`` is then required), quantised when
        ``radar.adc_bits`` is set. ``out`` may be a preallocated cube to write into."""
        if out is None:
            out = np.empty(self.shape, dtype=np.complex64)
        elif out.shape != self.shape or out.dtype != np.complex64 or not out.flags.c_contiguous:
            raise ValueError(f"out must be C-contiguous complex64 {self.shape}, got "
                             f"{out.dtype} {out.shape}")
        left, right = self.signal_factors(position_m, velocity_mps, rcs_m2, attenuation_db)
        flat = out.reshape(-1, self.shape[-1])
        if self.noise:
            if bit_generator is None:
                raise ValueError("a noisy simulator needs bit_generator (see frame_bit_generator)")
            self.add_noise(out, bit_generator)
            if left.shape[1]:
                # out^T (F-ordered view) += right^T @ left^T, in place (BLAS beta = 1)
                res = blas.cgemm(1.0, right.T, left.T, beta=1.0, c=flat.T, overwrite_c=1)
                if not np.shares_memory(res, out):  # pragma: no cover - BLAS copied c
                    flat.T[...] = res
        elif left.shape[1]:
            np.matmul(left, right, out=flat)
        else:
            out[...] = 0
        if self.radar.adc_bits is not None:
            quantise(out, self.radar.adc_bits, out=out)
        return out


def quantise(cube: np.ndarray, bits: int, out: np.ndarray | None = None) -> np.ndarray:
    """Round I and Q to integer codes and clip to [-2^(bits-1), 2^(bits-1) - 1] (cube already in
    LSB units). complex64 in, complex64 out (integer-valued).

    Raises SimulationError for ``bits`` outside [2, 24] or a cube that is not finite complex64.
    """
    if not (isinstance(bits, (int, np.integer)) and 2 <= bits <= 24):
        raise SimulationError(f"adc_bits must be an integer in [2, 24] to be exact in float32, "
                              f"got {bits!r}")
    x = checked_array(cube, "cube", SimulationError, where="quantise", kind="numeric",
                      min_ndim=1, axes="a cube (...) of complex64 samples in LSB")
    if x.dtype != np.complex64:
        raise SimulationError(f"quantise: cube must be complex64; found {x.dtype}")
    x = np.ascontiguousarray(x)  # the float32 view below needs contiguous (re, im) pairs
    out = np.empty_like(x) if out is None else out
    f_in, f_out = x.view(np.float32), out.view(np.float32)
    np.rint(f_in, out=f_out)
    top = float(2 ** (int(bits) - 1))
    np.clip(f_out, -top, top - 1, out=f_out)
    return out


def to_int16_iq(cube: np.ndarray) -> np.ndarray:
    """Integer-valued complex64 (..., n) -> int16 (..., n, 2) of (I, Q); raises SimulationError
    if not exact (or not finite numbers)."""
    x = checked_array(cube, "cube", SimulationError, where="to_int16_iq", kind="numeric",
                      axes="a cube (...) of integer-valued samples")
    f = np.ascontiguousarray(x, dtype=np.complex64).view(np.float32).reshape(*x.shape, 2)
    codes = f.astype(np.int16)
    if not np.array_equal(codes, f):
        raise SimulationError("cube is not integer-valued within int16 (set radar.adc_bits: 16)")
    return codes


def from_int16_iq(codes: np.ndarray) -> np.ndarray:
    """int16 (..., 2) of (I, Q) -> complex64 (...). Raises SimulationError for other input."""
    c = checked_array(codes, "codes", SimulationError, where="from_int16_iq", kind="integer",
                      min_ndim=1, lengths={-1: 2}, axes="ADC codes (..., 2) of (I, Q)")
    return np.ascontiguousarray(c.astype(np.float32)).view(np.complex64)[..., 0]


# ---------------------------------------------------------------------- frame source
class SimulatedSource:
    """A :class:`blindspot.radar.source.FrameSource` for one scene: frame i is the scene at time
    ``times_s[i]`` simulated with the noise stream (scene seed, i)."""

    def __init__(self, scene: Scene | SceneConfig | Mapping[str, Any], radar: RadarConfig,
                 array: VirtualArray | None = None, *, noise: bool = True,
                 adc_headroom_db: float = 60.0):
        if isinstance(scene, Mapping) or not isinstance(scene, (Scene, SceneConfig)):
            scene = SceneConfig.from_mapping(scene)
        self.scene = scene if isinstance(scene, Scene) else Scene(scene)
        self.radar = radar
        self.simulator = FmcwSimulator(radar, array, noise=noise, adc_headroom_db=adc_headroom_db)
        self.array = self.simulator.array
        self._times = self.scene.frame_times(radar.frame_period_s)

    @classmethod
    def from_config(cls, scene_cfg: SceneConfig | Mapping[str, Any], radar: RadarConfig,
                    sim_cfg: SimConfig | Mapping[str, Any] | None = None) -> SimulatedSource:
        """Build from a scene and the ``sim`` config group (a :class:`SimConfig` or its mapping)."""
        s = sim_cfg if isinstance(sim_cfg, SimConfig) else SimConfig.from_mapping(sim_cfg)
        return cls(scene_cfg, radar, noise=s.noise, adc_headroom_db=s.adc_headroom_db)

    @property
    def n_frames(self) -> int:
        return self.scene.cfg.n_frames

    @property
    def times_s(self) -> np.ndarray:
        """(n_frames,) frame start times, s."""
        return self._times

    def _bitgen(self, index: int) -> np.random.BitGenerator:
        return frame_bit_generator(self.scene.cfg.seed, index)

    def frame(self, index: int, out: np.ndarray | None = None) -> np.ndarray:
        """complex64 (chirps, tx, rx, samples) of frame ``index``."""
        if not (isinstance(index, (int, np.integer)) and 0 <= index < self.n_frames):
            raise IndexError(f"frame {index} outside [0, {self.n_frames}) of scene "
                             f"'{self.scene.cfg.name}'")
        sc = self.scene.scatterers_at(float(self._times[index]))
        return self.simulator.frame(*sc, bit_generator=self._bitgen(int(index)), out=out)

    def __iter__(self) -> Iterator[np.ndarray]:
        """Frames in order, each exactly (byte for byte) what ``frame(i)`` returns."""
        for i in range(self.n_frames):
            yield self.frame(i)

    def __len__(self) -> int:
        return self.n_frames

    def truth(self):
        """Per-frame pedestrian truth (``blindspot.radar.scene.TRUTH_COLUMNS``)."""
        return self.scene.truth(self._times)

    def write_ti_cascade(self, folder: str | Path, **kwargs: Any) -> list[Path]:
        """Save the scene as a TI MMWCAS cascade capture (frame by frame) with
        ``blindspot.radar.capture.write_ti_cascade``; needs the MMWCAS 16-RX profile and
        ``adc_bits: 16`` so that the frames are int16 codes."""
        if self.radar.n_rx != 16 or self.radar.array != "mmwcas":
            raise ConfigError("radar.array", self.radar.array, "'mmwcas' with 16 RX to write a cascade capture")
        if self.radar.adc_bits != 16:
            raise ConfigError("radar.adc_bits", self.radar.adc_bits,
                              "16 to write TI cascade captures (int16 ADC codes)")
        from blindspot.radar.capture import write_ti_cascade

        kwargs.setdefault("frame_period_s", self.radar.frame_period_s)
        return write_ti_cascade(folder, iter(self), **kwargs)


def _xyz(a: np.ndarray, name: str) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.ndim != 2 or a.shape[1] not in (2, 3):
        raise ValueError(f"{name} must be (K, 2) or (K, 3), got shape {a.shape}")
    if a.shape[1] == 2:
        a = np.concatenate([a, np.zeros((a.shape[0], 1))], axis=1)
    return a
