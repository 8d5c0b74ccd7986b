"""Range and Doppler FFTs of an FMCW TDM-MIMO cube, and the non-coherent detection map.

Conventions
-----------
* Input cube: complex ``(chirps, tx, rx, samples)`` for one frame, or a batch
  ``(frames, chirps, tx, rx, samples)`` (``chirps`` = chirp loops). Every method and
  :func:`detection_map` take either; the batch axis stays in front.
* Output ``rd``: complex ``(range, doppler, tx, rx)`` (batch: ``(frames, range, doppler, tx,
  rx)``); the Doppler axis is zero-centred (``fftshift`` order: bin ``n_doppler // 2`` is zero
  velocity, bin ``k`` has the signed index ``k - n_doppler // 2``), matching
  ``RadarConfig.velocity_axis_mps()``.
* FFTs are *unnormalised* sums with windows of peak 1 (the convention of TI's own processing of ADC
  counts): a tone of amplitude ``a`` exactly on a bin gives ``|X| = a * sum(w_range) * sum(w_doppler)``.
  Power maps are therefore in (input unit)^2, which is what a dB-domain CFAR scale refers to.
* Zero-Doppler centring costs nothing: the Doppler window is multiplied by ``exp(j 2 pi c h / N)``
  with ``h = N // 2`` (``(-1)^c`` for even N), which shifts the spectrum by ``h`` bins, so no
  ``fftshift`` copy of the cube is ever made.

Memory layout (measured in ``benchmarks/bench_fft.py``, one MMWCAS frame, one thread)
---------------------------------------------------------------------------------------
The window multiply writes the cube once into a *channel-major* buffer ``(..., tx, rx, chirps,
samples)``: each virtual channel's chirps x samples block is contiguous (64 x 256 complex64 =
128 KiB, it stays in L2 through both FFTs), and the channel sum of the map then runs over the
outermost axis in one streaming pass. The arrays handed out (``native``, ``__call__``,
``range_profiles``) are transposed *views* of the channel-major result with the documented axis
order (no transposing copy); :func:`detection_map` recognises the layout.

* Full range (``n_range`` None or ``n_samples``): both FFTs by FFTW (pyFFTW), one 2-D plan per
  cache-sized block of channels (2 MMWCAS channels, 256 KiB): the window multiply writes the block
  from the cube into a scratch buffer that stays in L2, and FFTW transforms it straight into its
  slice of the result, so the 25 MB cube is read once and the result written once (see
  ``RangeDoppler._fft2``). Measured on one thread (AMD EPYC, AVX2) it beat ``torch.fft.fft2``
  (MKL) on the whole windowed frame, ``scipy.fft`` (pocketfft) and ``numpy.fft``, blocked or not.
  The plan is ``FFTW_ESTIMATE`` (chosen without timing runs), so the result is the same on every
  run. ``workers`` sets FFTW's threads.
* Range window (``n_range`` < ``n_samples``): range FFT in place with ``scipy.fft``, then the
  Doppler window and FFT only on the kept range bins (``scipy.fft``; faster than torch here, and
  the same arithmetic as before, so the stages' detections are unchanged bit for bit).
All arithmetic is complex64 (complex128 costs twice the time and agrees within float32 rounding).

Bad input
---------
Shapes and element kinds are checked on entry (:class:`RangeDopplerError`, naming the argument,
the expected axes and what was found). Non-finite samples are found *after* the transform, at no
cost: every output bin of a DFT is a weighted sum of all its inputs, and IEEE arithmetic carries
a NaN or infinity through every product and sum (``NaN * 0`` and ``inf * 0`` are NaN), so one bad
sample makes its channel's whole row of range bins (range FFT) or whole 2-D spectrum (both
FFTs) non-finite. Checking one bin per chirp or channel therefore finds any non-finite sample,
where an ``isfinite`` pass over a 3.1 M-sample MMWCAS frame would cost 3-6 ms (10-15 % of the
chain; measured with ``np.sum`` / ``np.isfinite`` on this machine).
"""

from __future__ import annotations

import importlib.util
import threading
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
import scipy.fft as sfft
import scipy.signal

from blindspot.arrays import checked_array, count_nonfinite
from blindspot.dsp.config import WINDOW_NAMES
# Full-range FFT in blocks of about _BLOCK_BYTES of channels (2 MMWCAS channels of 64 x 256
# complex64): the scratch block and its result fit a 512 KiB L2 together. Blocks of 1 to 8
# channels measured alike, 32 channels (4 MiB) a quarter slower (benchmarks/bench_fft.py).
_BLOCK_BYTES = 256 << 10
_PLANS = threading.local()  # per thread: FFTW plans by (block shape, threads, alignment)
# pyFFTW (BSD) wraps FFTW (GPL-2.0-or-later): installed by requirements.lock for speed, never
# required. Without it the same blocks go through scipy.fft (pocketfft, BSD): the same transform
# to float32 rounding, about twice the time of the range-Doppler step (benchmarks/bench_fft.py).
HAVE_FFTW = importlib.util.find_spec("pyfftw") is not None


def _aligned_empty(shape: tuple[int, ...]) -> np.ndarray:
    """Uninitialised complex64 C-contiguous array whose data start on a 64-byte boundary (the
    SIMD alignment FFTW's plans assume; plain ``np.empty`` without pyFFTW)."""
    if not HAVE_FFTW:
        return np.empty(shape, dtype=np.complex64)
    import pyfftw

    return pyfftw.empty_aligned(shape, dtype=np.complex64, n=64)


def _fft2_plan(shape: tuple[int, ...], threads: int, aligned: bool):
    """FFTW plan (cached per thread: plans are not re-entrant) of the forward 2-D DFT over the
    last two axes of complex64 C-contiguous blocks ``shape``, out of place, allowed to destroy its
    scratch input (``plan.input_array``). ``aligned``: every output block starts 64-byte aligned
    (else the plan is made for unaligned arrays)."""
    import pyfftw

    cache = getattr(_PLANS, "plans", None)
    if cache is None:
        cache = _PLANS.plans = {}
    key = (shape, threads, aligned)
    plan = cache.get(key)
    if plan is None:
        flags = ("FFTW_ESTIMATE", "FFTW_DESTROY_INPUT") + (() if aligned else ("FFTW_UNALIGNED",))
        plan = pyfftw.FFTW(_aligned_empty(shape), _aligned_empty(shape), axes=(-2, -1),
                           direction="FFTW_FORWARD", flags=flags, threads=threads)
        cache[key] = plan
    return plan


class RangeDopplerError(ValueError):
    """A cube, range profiles or range-Doppler data of the wrong shape or kind, or holding
    NaN/inf samples; the message names the argument, what was expected and what was found."""


class WindowError(RangeDopplerError):
    """An unknown window name or a bad window length."""


@lru_cache(maxsize=64)
def window(name: str, n: int) -> np.ndarray:
    """(n,) float64 periodic (DFT-even) window of peak <= 1; ``"rect"`` is all ones.

    Raises WindowError for a name not in ``WINDOW_NAMES`` or ``n < 1``."""
    if name not in WINDOW_NAMES:
        raise WindowError(f"window '{name}' is unknown: expected one of {WINDOW_NAMES}")
    if n < 1:
        raise WindowError(f"window length must be >= 1, got {n}")
    if name == "rect":
        w = np.ones(n)
    else:
        w = scipy.signal.get_window(name, n, fftbins=True).astype(np.float64)
    w.setflags(write=False)
    return w


def doppler_shift_window(name: str, n: int) -> np.ndarray:
    """(n,) complex128 Doppler window times the zero-centring modulation exp(j 2 pi c (n//2) / n),
    indexed by chirp c."""
    c = np.arange(n)
    return window(name, n) * np.exp(2j * np.pi * c * (n // 2) / n)


def signed_doppler_index(doppler_bin: np.ndarray | int, n_doppler: int) -> np.ndarray:
    """Signed Doppler index (cycles per frame) of a zero-centred bin: ``bin - n_doppler // 2``."""
    return np.asarray(doppler_bin) - n_doppler // 2


def _to_channel_major(x: np.ndarray) -> np.ndarray:
    """View (..., chirps, tx, rx, n) as (..., tx, rx, chirps, n)."""
    return np.moveaxis(x, -4, -2)


def _from_channel_major(x: np.ndarray) -> np.ndarray:
    """View (..., tx, rx, chirps, n) as (..., chirps, tx, rx, n)."""
    return np.moveaxis(x, -2, -4)


@dataclass(frozen=True)
class RangeDoppler:
    """Range/Doppler FFT configured once for a cube shape (chirps, tx, rx, samples).

    ``__call__(cube) -> rd`` complex64 ``(range, doppler, tx, rx)`` (batch: ``(frames, range,
    doppler, tx, rx)``), a transposed *view* of the C-contiguous channel-major result
    ``(tx, rx, doppler, range)`` (see :meth:`channel_major`), so nothing is copied. With
    ``n_range`` only the first ``n_range`` range bins are Doppler-processed and returned (a range
    window for scenes that end well before the profile's maximum range; saves most of the Doppler
    FFT). ``workers``: threads of FFTW and scipy.fft.

    Raises WindowError for an unknown window, RangeDopplerError for ``n_range`` outside
    [1, n_samples] and, from every method, for a cube of the wrong shape or kind or with NaN/inf
    samples (found in the result, see the module docstring).
    """

    n_chirps: int
    n_samples: int
    range_window: str = "hann"
    doppler_window: str = "hann"
    workers: int = 1
    n_range: int | None = None  # keep range bins 0..n_range-1 only (None = all)
    _w2d: np.ndarray = field(init=False, repr=False, compare=False)
    _wr: np.ndarray = field(init=False, repr=False, compare=False)
    _wd: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.n_range is not None and not 1 <= self.n_range <= self.n_samples:
            raise RangeDopplerError(f"n_range must be in [1, {self.n_samples}], got {self.n_range}")
        wr = window(self.range_window, self.n_samples)
        wd = doppler_shift_window(self.doppler_window, self.n_chirps)
        # (chirps, samples): both windows and the zero-centring, for the channel-major buffer
        object.__setattr__(self, "_w2d", (wd[:, None] * wr[None, :]).astype(np.complex64))
        object.__setattr__(self, "_wr", wr.astype(np.float32))
        object.__setattr__(self, "_wd", wd.astype(np.complex64)[:, None])  # (chirps, 1)

    @property
    def cropped(self) -> bool:
        """True when only the first ``n_range`` < ``n_samples`` range bins are kept."""
        return self.n_range is not None and self.n_range < self.n_samples

    # ------------------------------------------------------------------------------ helpers
    def _check(self, cube: np.ndarray, name: str = "cube") -> np.ndarray:
        """Shape and kind of a cube (..., chirps, tx, rx, samples); finiteness is checked on
        the result (:func:`_check_finite`)."""
        return checked_array(cube, name, RangeDopplerError, where="range_doppler",
                             axes=f"a cube (chirps={self.n_chirps}, tx, rx, samples="
                                  f"{self.n_samples}) or a batch (frames, chirps, tx, rx, samples)",
                             ndim=(4, 5), kind="numeric", finite=False,
                             lengths={-4: self.n_chirps, -1: self.n_samples})

    def _windowed(self, cube: np.ndarray, w: np.ndarray) -> np.ndarray:
        """complex64 (..., tx, rx, chirps, samples) C-contiguous = cube * w, one pass."""
        lead, (c, t, r, n) = cube.shape[:-4], cube.shape[-4:]
        buf = np.empty((*lead, t, r, c, n), np.complex64)
        with np.errstate(invalid="ignore"):  # inf * 0: a bad sample is reported after the FFT
            np.multiply(_to_channel_major(cube), w, out=buf)
        return buf

    def _fft2(self, cube: np.ndarray) -> np.ndarray:
        """Window and both FFTs: complex64 C-contiguous (..., tx, rx, doppler, range) of a
        checked cube (..., chirps, tx, rx, samples), in cache-sized blocks of virtual channels.

        A block (about ``_BLOCK_BYTES``: 2 MMWCAS channels of 64 x 256 complex64; whole frames
        when a frame is smaller, otherwise a divisor of the frame's channels, so a block never
        spans two frames) is window-multiplied from the cube into a small scratch buffer (the
        layout change to channel-major and the window in one pass, the buffer stays in L2) and
        transformed by one FFTW plan (``FFTW_ESTIMATE``: a deterministic plan, so the result
        does not depend on timings) straight into its slice of the result. The cube is read
        once and the result written once; nothing else of cube size is allocated. The loop
        runs over cache blocks, not over chirps or samples (an MMWCAS frame is 96 blocks)."""
        lead, (c, t, r, n) = cube.shape[:-4], cube.shape[-4:]
        n_frames, n_ch = int(np.prod(lead, dtype=np.int64)), t * r
        per_ch = c * n * np.dtype(np.complex64).itemsize
        src = np.moveaxis(cube.reshape(n_frames, c, n_ch, n), 1, 2)  # (F, T*R, C, N) view
        out = _aligned_empty((*lead, t, r, c, n))
        if n_frames == 0:  # an empty batch: nothing to transform
            return out
        dst = out.reshape(n_frames, n_ch, c, n)
        budget = max(1, _BLOCK_BYTES // per_ch)  # channels per block
        if budget >= n_ch:  # whole frames per block
            k_f, k_c = min(n_frames, budget // n_ch), n_ch
        else:  # the largest divisor of the frame's channels within the budget
            k_f, k_c = 1, max(d for d in range(1, budget + 1) if n_ch % d == 0)
        with np.errstate(invalid="ignore"):  # inf * 0, as in _windowed
            for f0 in range(0, n_frames, k_f):
                f1 = min(f0 + k_f, n_frames)
                # one frame per block: 3-D blocks (channels, chirps, samples), whose strides
                # match the plan's whatever the frame's channel count
                shape = (f1 - f0, k_c, c, n) if k_f > 1 else (k_c, c, n)
                plan = (_fft2_plan(shape, self.workers, aligned=per_ch % 64 == 0)
                        if HAVE_FFTW else None)
                buf = np.empty(shape, dtype=np.complex64) if plan is None else plan.input_array
                for c0 in range(0, n_ch, k_c):
                    block = (slice(f0, f1) if k_f > 1 else f0, slice(c0, c0 + k_c))
                    np.multiply(src[block], self._w2d, out=buf)
                    if plan is None:  # without pyFFTW: scipy.fft on the same block
                        dst[block] = sfft.fft2(buf, axes=(-2, -1), workers=self.workers)
                    else:
                        plan.update_arrays(buf, dst[block])
                        plan.execute()
        return out

    def _doppler_cut(self, profiles_cm: np.ndarray) -> np.ndarray:
        """Doppler window and FFT of the kept range bins of channel-major range profiles
        (..., tx, rx, chirps, range >= n_range) -> new C-contiguous (..., tx, rx, doppler,
        n_range)."""
        x = profiles_cm[..., :self.n_range] if self.cropped else profiles_cm
        with np.errstate(invalid="ignore"):  # as in _windowed
            y = np.multiply(x, self._wd, dtype=np.complex64)
        return sfft.fft(y, axis=-2, overwrite_x=True, workers=self.workers)

    # ------------------------------------------------------------------------------ public
    def channel_major(self, cube: np.ndarray) -> np.ndarray:
        """Both FFTs, in the layout they are computed in.

        cube : complex (chirps, tx, rx, samples) or (frames, chirps, tx, rx, samples)
        returns complex64 C-contiguous (tx, rx, doppler, range) or (frames, tx, rx, doppler,
        range), range = ``n_range`` bins when cropped. Raises ValueError for a wrong shape."""
        cube = self._check(cube)
        if not self.cropped:
            out = self._fft2(cube)
        else:  # cropped: the Doppler FFT (and everything after) only sees range bins < n_range
            x = self._windowed(cube, self._wr)
            sfft.fft(x, axis=-1, overwrite_x=True, workers=self.workers)
            out = self._doppler_cut(x)
        _check_finite(out[..., 0, 0], cube, "cube")  # one bin per channel sees every sample
        return out

    def native(self, cube: np.ndarray) -> np.ndarray:
        """Both FFTs: complex64 (doppler, tx, rx, range), or (frames, doppler, tx, rx, range)
        for a batch; a view of :meth:`channel_major`'s buffer (not C-contiguous)."""
        return _from_channel_major(self.channel_major(cube))

    def __call__(self, cube: np.ndarray) -> np.ndarray:
        """Both FFTs: complex64 (range, doppler, tx, rx), or (frames, range, doppler, tx, rx)."""
        return np.moveaxis(self.native(cube), -1, -4)

    def range_profiles(self, cube: np.ndarray) -> np.ndarray:
        """Range FFT only, range-windowed, all ``n_samples`` bins.

        cube : complex (chirps, tx, rx, samples) or (frames, chirps, tx, rx, samples)
        returns complex64 (chirps, tx, rx, range) or (frames, chirps, tx, rx, range), a view of
        a C-contiguous channel-major (..., tx, rx, chirps, range) buffer."""
        cube = self._check(cube)
        x = sfft.fft(self._windowed(cube, self._wr), axis=-1, overwrite_x=True,
                     workers=self.workers)
        _check_finite(x[..., 0], cube, "cube")  # range bin 0 of each chirp sees all its samples
        return _from_channel_major(x)

    def doppler(self, range_profiles: np.ndarray) -> np.ndarray:
        """Doppler window and FFT (zero-centred) of range profiles, on the first ``n_range``
        range bins when cropped.

        range_profiles : complex (chirps, tx, rx, range) or (frames, chirps, tx, rx, range), any
            strides (e.g. :meth:`range_profiles`' output); it is not modified.
        returns complex64 (doppler, tx, rx, range) or (frames, doppler, tx, rx, range), a view of
        a new C-contiguous channel-major buffer (same layout as :meth:`native`)."""
        p = checked_array(range_profiles, "range_profiles", RangeDopplerError, where="doppler",
                          axes=f"range profiles (chirps={self.n_chirps}, tx, rx, range) or a "
                               "batch (frames, chirps, tx, rx, range)",
                          ndim=(4, 5), kind="numeric", finite=False,
                          lengths={-4: self.n_chirps}, min_lengths={-1: self.n_range or 1})
        out = self._doppler_cut(_to_channel_major(p))
        # Doppler bin 0 of each range bin sees every chirp of that bin
        _check_finite(out[..., 0, :], p[..., :self.n_range or None], "range_profiles")
        return _from_channel_major(out)


def range_doppler(cube: np.ndarray, range_window: str = "hann", doppler_window: str = "hann",
                  *, workers: int = 1) -> np.ndarray:
    """Range-Doppler transform of one frame or a batch of frames.

    cube : complex (chirps, tx, rx, samples) or (frames, chirps, tx, rx, samples)
    returns complex64 (range, doppler, tx, rx) or (frames, range, doppler, tx, rx), Doppler
    zero-centred (a view; see :class:`RangeDoppler`).
    Raises RangeDopplerError for a cube of the wrong shape or kind or with NaN/inf samples.
    """
    cube = checked_array(cube, "cube", RangeDopplerError, where="range_doppler",
                         axes="a cube (chirps, tx, rx, samples) or a batch (frames, chirps, tx, "
                              "rx, samples)", ndim=(4, 5), kind="numeric", finite=False,
                         min_lengths={-4: 1, -1: 1})
    proc = RangeDoppler(cube.shape[-4], cube.shape[-1], range_window, doppler_window, workers)
    return proc(cube)


def detection_map(rd: np.ndarray) -> np.ndarray:
    """Non-coherent integration over all virtual channels (power, never log-magnitude).

    rd : complex (range, doppler, tx, rx) or (frames, range, doppler, tx, rx), any strides
    returns float64 (range, doppler) or (frames, range, doppler) = sum over tx, rx of |rd|^2.
    Summed in the precision of ``rd`` (float32 for complex64), returned in float64. For
    :class:`RangeDoppler`'s output it is a transposed view of a C-contiguous (doppler, range)
    array (Fortran order for one frame), as it always was; otherwise C-contiguous.

    Fast on :class:`RangeDoppler`'s output (a view of a channel-major buffer): one streaming pass
    over the channels, no temporaries of cube size. Raises RangeDopplerError for another number
    of axes, a non-numeric array, or NaN/inf values (found in the map: they survive the sum).
    """
    rd = checked_array(rd, "rd", RangeDopplerError, where="detection_map",
                       axes="range-Doppler data (range, doppler, tx, rx) or (frames, range, "
                            "doppler, tx, rx)", ndim=(4, 5), kind="numeric", finite=False)
    power = _channel_power(rd)
    _check_finite(power, rd, "rd")
    return power


def _check_finite(probe: np.ndarray, source: np.ndarray, name: str) -> None:
    """RangeDopplerError if ``probe`` (a few output bins that depend on every element of
    ``source``) holds NaN/inf; the message counts the bad elements of ``source`` (slow path)."""
    if not np.isfinite(probe).all():
        bad = count_nonfinite(source)
        raise RangeDopplerError(f"{name} must hold finite samples; found {bad} NaN/inf value(s) "
                                f"of {source.size}" if bad else
                                f"{name}: its samples overflow the transform (values too large "
                                f"for complex64, up to {np.abs(source).max():.3g})")


def _channel_power(rd: np.ndarray) -> np.ndarray:
    """Sum over tx, rx of |rd|^2 (see :func:`detection_map`)."""
    if rd.dtype not in (np.complex64, np.complex128):
        rd = rd.astype(np.complex128)
    real = np.float32 if rd.dtype == np.complex64 else np.float64
    lead, (n, d, t, r) = rd.shape[:-4], rd.shape[-4:]
    b = int(np.prod(lead, dtype=np.int64))
    cm = np.moveaxis(rd, (-2, -1), (-4, -3))  # (..., tx, rx, range, doppler)
    cm = np.swapaxes(cm, -1, -2)              # (..., tx, rx, doppler, range)
    if cm.flags.c_contiguous:
        # channel-major: sum of squares over the channel rows of the interleaved re/im floats
        f = cm.view(real).reshape(b, t * r, d * n * 2)
        s = np.einsum("bck,bck->bk", f, f).reshape(b, d, n, 2)   # (B, doppler, range, re/im)
        dn = np.add(s[..., 0], s[..., 1], dtype=np.float64)      # (B, doppler, range)
        return np.swapaxes(dn.reshape(*lead, d, n), -1, -2)
    # any other layout: channels innermost, (B, range, doppler, channels * re/im)
    f = np.ascontiguousarray(rd).view(real).reshape(b, n, d, t * r * 2)
    return np.square(f).sum(axis=-1, dtype=np.float64).reshape(*lead, n, d)
