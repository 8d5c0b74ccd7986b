"""Range and Doppler FFTs of an FMCW TDM-MIMO cube, and the non-coherent detection map.

Conventions
-----------
* Input cube: complex ``(chirps, tx, rx, samples)`` (one frame; ``chirps`` = chirp loops).
* Output ``rd``: complex ``(range, doppler, tx, rx)``; the Doppler axis is zero-centred
  (``fftshift`` order: bin ``n_doppler // 2`` is zero velocity, bin ``k`` has the signed index
  ``k - n_doppler // 2``), matching ``RadarConfig.velocity_axis_mps()``.
* FFTs are *unnormalised* sums with windows of peak 1 (the convention of TI's own processing of ADC
  counts): a tone of amplitude ``a`` exactly on a bin gives ``|X| = a * sum(w_range) * sum(w_doppler)``.
  Power maps are therefore in (input unit)^2, which is what a dB-domain CFAR scale refers to.
* Zero-Doppler centring costs nothing: the Doppler window is multiplied by ``exp(j 2 pi c h / N)``
  with ``h = N // 2`` (``(-1)^c`` for even N), which shifts the spectrum by ``h`` bins, so no
  ``fftshift`` copy of the cube is ever made.

Both FFTs run in single precision through ``scipy.fft`` in place; ``workers`` sets its threads.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
import scipy.fft as sfft
import scipy.signal

WINDOW_NAMES = ("hann", "hamming", "blackman", "blackmanharris", "rect")


class WindowError(ValueError):
    """An unknown window name."""


@lru_cache(maxsize=64)
def window(name: str, n: int) -> np.ndarray:
    """(n,) float64 periodic (DFT-even) window of peak <= 1; ``"rect"`` is all ones."""
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
    """(n,) complex128 Doppler window times the zero-centring modulation exp(j 2 pi c (n//2) / n)."""
    c = np.arange(n)
    return window(name, n) * np.exp(2j * np.pi * c * (n // 2) / n)


def signed_doppler_index(doppler_bin: np.ndarray | int, n_doppler: int) -> np.ndarray:
    """Signed Doppler index (cycles per frame) of a zero-centred bin: ``bin - n_doppler // 2``."""
    return np.asarray(doppler_bin) - n_doppler // 2


@dataclass(frozen=True)
class RangeDoppler:
    """Range/Doppler FFT configured once for a cube shape (chirps, tx, rx, samples).

    ``__call__(cube) -> rd`` complex64 ``(range, doppler, tx, rx)`` (a transposed *view* of a
    C-contiguous ``(doppler, tx, rx, range)`` array, so nothing is copied). With ``n_range`` only
    the first ``n_range`` range bins are Doppler-processed and returned (a range window for
    scenes that end well before the profile's maximum range; saves most of the Doppler FFT).
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
            raise ValueError(f"n_range must be in [1, {self.n_samples}], got {self.n_range}")
        wr = window(self.range_window, self.n_samples)
        wd = doppler_shift_window(self.doppler_window, self.n_chirps)
        w2d = (wd[:, None] * wr[None, :]).astype(np.complex64)[:, None, None, :]
        object.__setattr__(self, "_w2d", w2d)
        object.__setattr__(self, "_wr", wr.astype(np.float32))
        object.__setattr__(self, "_wd", wd.astype(np.complex64)[:, None, None, None])

    @property
    def cropped(self) -> bool:
        return self.n_range is not None and self.n_range < self.n_samples

    def native(self, cube: np.ndarray) -> np.ndarray:
        """complex64 (doppler, tx, rx, range), C-contiguous: the FFT output before transposing."""
        if cube.ndim not in (4, 5) or cube.shape[-4] != self.n_chirps \
                or cube.shape[-1] != self.n_samples:
            raise ValueError(
                f"range_doppler: expected a cube (chirps={self.n_chirps}, tx, rx, "
                f"samples={self.n_samples}) or a batch of them (frames, chirps, tx, rx, "
                f"samples), got shape {cube.shape}"
            )
        if not self.cropped:
            x = np.multiply(cube, self._w2d, dtype=np.complex64)  # both windows, one pass
            sfft.fft(x, axis=-1, overwrite_x=True, workers=self.workers)
            return sfft.fft(x, axis=-4, overwrite_x=True, workers=self.workers)
        # cropped: the Doppler FFT (and everything after) only sees range bins < n_range
        x = self.range_profiles(cube)
        y = np.multiply(x[..., :self.n_range], self._wd, dtype=np.complex64)
        return sfft.fft(y, axis=-4, overwrite_x=True, workers=self.workers)

    def __call__(self, cube: np.ndarray) -> np.ndarray:
        return np.moveaxis(self.native(cube), 3, 0)

    def range_profiles(self, cube: np.ndarray) -> np.ndarray:
        """Range FFT only: complex64 (chirps, tx, rx, range), range-windowed."""
        x = np.multiply(cube, self._wr, dtype=np.complex64)
        return sfft.fft(x, axis=-1, overwrite_x=True, workers=self.workers)

    def doppler(self, range_profiles: np.ndarray) -> np.ndarray:
        """Doppler FFT (zero-centred) of range profiles (chirps, tx, rx, range), IN PLACE:
        returns the same buffer as (doppler, tx, rx, range)."""
        x = range_profiles[..., :self.n_range] if self.cropped else range_profiles
        x = np.multiply(x, self._wd, dtype=np.complex64) if self.cropped else x.__imul__(self._wd)
        return sfft.fft(x, axis=-4, overwrite_x=True, workers=self.workers)


def range_doppler(cube: np.ndarray, range_window: str = "hann", doppler_window: str = "hann",
                  *, workers: int = 1) -> np.ndarray:
    """Range-Doppler transform of one frame.

    cube : complex (chirps, tx, rx, samples)
    returns complex64 (range, doppler, tx, rx), Doppler zero-centred.
    """
    proc = RangeDoppler(cube.shape[0], cube.shape[-1], range_window, doppler_window, workers)
    return proc(cube)


def detection_map(rd: np.ndarray) -> np.ndarray:
    """Non-coherent integration: (range, doppler, tx, rx) -> float64 (range, doppler) = sum |X|^2
    over all virtual channels (power, never log-magnitude)."""
    if rd.ndim == 5:  # a batch in RangeDoppler.native layout (frames, doppler, tx, rx, range)
        f, d, t, r, n = rd.shape
        x = np.ascontiguousarray(rd).reshape(f * d, t, r, n)
        return _channel_power(x, axes_first=True).reshape(f, d, n).transpose(0, 2, 1)
    if rd.ndim != 4:
        raise ValueError(f"detection_map: expected rd (range, doppler, tx, rx), got shape {rd.shape}")
    base = rd
    # Work on the contiguous (doppler, tx, rx, range) layout when rd is RangeDoppler's view.
    if not rd.flags.c_contiguous and rd.transpose(1, 2, 3, 0).flags.c_contiguous:
        native = rd.transpose(1, 2, 3, 0)
        return _channel_power(native, axes_first=True).T
    return _channel_power(np.ascontiguousarray(base), axes_first=False)


def _channel_power(x: np.ndarray, axes_first: bool) -> np.ndarray:
    """sum |x|^2 over the two channel axes: (D, T, R, N) -> (D, N) if axes_first else
    (N, D, T, R) -> (N, D). Squares the interleaved re/im float view (one pass, no temporaries of
    complex size), sums channels in the input precision, returns float64."""
    if x.dtype not in (np.complex64, np.complex128):
        x = x.astype(np.complex128)
    f = x.view(np.float32 if x.dtype == np.complex64 else np.float64)  # interleaved re/im
    if axes_first:
        d, t, r, n = x.shape
        s = np.square(f.reshape(d, t * r, 2 * n)).sum(axis=1)  # (D, 2N)
        return s.reshape(d, n, 2).sum(axis=2, dtype=np.float64)
    n, d, t, r = x.shape
    s = np.square(f.reshape(n, d, t * r * 2)).sum(axis=2, dtype=np.float64)
    return s
