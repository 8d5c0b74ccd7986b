"""DCA1000 raw ADC captures (``adc_data.bin``) of an xWR16xx/xWR18xx/xWR68xx radar, complex output.

Cubes are complex64 ``(frames, chirps, tx, rx, samples)`` as everywhere in
:mod:`blindspot.radar.capture`: ``chirps`` counts chirp loops, ``tx`` the chirp slot within a
loop, ``rx`` in file order. :class:`DCA1000Capture` maps the file with ``np.memmap`` and
de-interleaves whole frames with reshape/transpose only; :class:`DCA1000Recording` is the frame
source over it (one frame read at a time).

Layout ``"xwr16xx"`` (the default): the file is the raw int16 stream, chirp after chirp (loop,
then TX slot), and within a chirp RX after RX; each RX block holds its samples in groups of four
int16 ``I(n), I(n+1), Q(n), Q(n+1)`` (TI, "mmWave Radar Device ADC Raw Data Capture", SWRA581,
section "xWR16xx ... with DCA1000": two LVDS lanes, each lane carrying two samples). Layout
``"xwr14xx"`` is TI's four-lane format (per sample: I of RX0..3, then Q of RX0..3; RX innermost).

Evidence from the real AWR1843 recording (``../shared/data/radar/dca1000-awr1843/adc_data.bin``,
128 samples, 255 loops, 2 TX, 4 RX, 4 whole frames), measured by
``tests/radar/test_real_recordings.py`` (DC removed, Hann window, range FFT per chirp, bins
within 4 of DC ignored) for five readings of the same bytes:

=============================  ===========  ===========  ===========  =============
reading                        peak/median  chirps with  loop-to-loop near/far-half
                               of profile   argmax at a  coherence    power ratio
                                            top-3 peak   (min)
=============================  ===========  ===========  ===========  =============
xwr16xx (I I Q Q, RX-major)    27.7 dB      100 %        1.000        +16.0 dB
same bytes, I and Q swapped    27.7 dB      100 %        1.000        -16.1 dB
I Q I Q pairs, RX-major        15.0 dB      100 %        0.996         +2.1 dB
xwr14xx (four-lane)            11.5 dB      99.2 %       0.996         -2.4 dB
xwr16xx but TX slot slowest    27.7 dB      50.2 %       0.763        +16.0 dB
=============================  ===========  ===========  ===========  =============

("chirps with argmax at a top-3 peak": worst channel's share of chirps whose strongest bin is
within one bin of one of the channel's three strongest profile peaks.)

Only the xwr16xx reading gives a sharp profile (returns at 3.1, 5.4 and 9.4 m, 28 dB above the
median bin, the same bins in every chirp of every frame) whose power falls with range as a real
scene's does (``R^-4`` and the IF low-pass); I/Q swapped is its exact mirror image (strong
returns beyond 19 m, empty near range), the other lane orders smear the returns over the
spectrum (12-16 dB less contrast), and static returns stay phase-coherent from loop to loop
only if the TX slot varies faster than the loop (chirps are stored loop by loop). The data are
two's complement (codes -2617..3064 around a small DC offset), not offset binary.

A trailing partial frame (a cut recording; this file holds 4 frames and 12,942 extra bytes) is
dropped with a warning naming the file and the sizes; a file smaller than one frame raises.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path
from typing import Literal

import numpy as np

from blindspot.radar.array import VirtualArray, array_for
from blindspot.radar.capture.common import (
    BYTES_PER_IQ,
    CaptureError,
    Int16Conversion,
    atomic_files,
    check_dims,
    check_range,
    iter_frames_of,
    to_int16_iq,
    whole_frames,
)
from blindspot.radar.config import RadarConfig
from blindspot.radar.source import RecordingFrames, check_frame_index

__all__ = [
    "DcaLayout",
    "DCA1000Capture",
    "DCA1000Recording",
    "dca1000_frame_bytes",
    "read_dca1000",
    "write_dca1000",
]

DcaLayout = Literal["xwr16xx", "xwr14xx"]


def dca1000_frame_bytes(n_samples: int, n_chirps: int, n_tx: int, n_rx: int) -> int:
    """Bytes of one frame: samples * loops * TX * RX * 4 (complex int16)."""
    return int(n_samples) * int(n_chirps) * int(n_tx) * int(n_rx) * BYTES_PER_IQ


def _dca_file_shape(layout: str, n_samples: int, n_chirps: int, n_tx: int,
                    n_rx: int) -> tuple[int, ...]:
    """int16 shape of one frame in the file, slowest axis first."""
    if layout == "xwr16xx":
        if n_samples % 2:
            raise ValueError(f"n_samples = {n_samples}: the xwr16xx DCA1000 layout stores "
                             "samples in pairs, expected an even number")
        return (n_chirps, n_tx, n_rx, n_samples // 2, 2, 2)  # (loop, tx, rx, pair, iq, k)
    if layout == "xwr14xx":
        if n_rx != 4:
            raise ValueError(f"n_rx = {n_rx}: the xwr14xx (four-lane) layout carries exactly 4 RX")
        return (n_chirps, n_tx, n_samples, 2, n_rx)  # (loop, tx, sample, iq, rx)
    raise ValueError(f"layout = {layout!r}: expected 'xwr16xx' or 'xwr14xx'")


def _dca_to_complex(raw: np.ndarray, layout: str, n_samples: int, n_chirps: int, n_tx: int,
                    n_rx: int) -> np.ndarray:
    """int16 (frames, frame_int16) -> complex64 (frames, loops, tx, rx, samples)."""
    fshape = _dca_file_shape(layout, n_samples, n_chirps, n_tx, n_rx)
    f = raw.shape[0]
    out = np.empty((f, n_chirps, n_tx, n_rx, n_samples), np.complex64)
    out_iq = out.view(np.float32).reshape(out.shape + (2,))
    r = raw.reshape((f,) + fshape)
    if layout == "xwr16xx":
        # file (f, loop, tx, rx, pair, iq, k) -> out (f, loop, tx, rx, pair, k, iq)
        out_iq.reshape(f, n_chirps, n_tx, n_rx, n_samples // 2, 2, 2)[...] = \
            r.transpose(0, 1, 2, 3, 4, 6, 5)
    else:
        # file (f, loop, tx, sample, iq, rx) -> out (f, loop, tx, rx, sample, iq)
        out_iq[...] = r.transpose(0, 1, 2, 5, 3, 4)
    return out


def _complex_to_dca(iq: np.ndarray, layout: str) -> np.ndarray:
    """int16 (loops, tx, rx, samples, 2) -> the frame's int16 stream in file order."""
    l, t, r, s, _ = iq.shape
    if layout == "xwr16xx":
        if s % 2:
            raise ValueError(f"n_samples = {s}: the xwr16xx layout needs an even sample count")
        return iq.reshape(l, t, r, s // 2, 2, 2).transpose(0, 1, 2, 3, 5, 4).ravel()
    if layout == "xwr14xx":
        if r != 4:
            raise ValueError(f"n_rx = {r}: the xwr14xx (four-lane) layout carries exactly 4 RX")
        return iq.transpose(0, 1, 3, 4, 2).ravel()
    raise ValueError(f"layout = {layout!r}: expected 'xwr16xx' or 'xwr14xx'")


class DCA1000Capture:
    """An opened DCA1000 ``adc_data.bin``: whole frames, read on demand through a memory map."""

    def __init__(self, path: str | os.PathLike, n_samples: int, n_chirps: int, n_tx: int,
                 n_rx: int, *, layout: DcaLayout = "xwr16xx"):
        self.path = Path(path)
        self.n_samples, self.n_chirps, self.n_tx, self.n_rx = check_dims(
            n_samples=n_samples, n_chirps=n_chirps, n_tx=n_tx, n_rx=n_rx)
        self.layout = layout
        _dca_file_shape(layout, self.n_samples, self.n_chirps, self.n_tx, self.n_rx)  # checks
        if not self.path.is_file():
            raise CaptureError(self.path, "DCA1000 capture file not found")
        self.frame_bytes = dca1000_frame_bytes(self.n_samples, self.n_chirps, self.n_tx, self.n_rx)
        profile = (f"{self.n_samples} samples x {self.n_chirps} loops x {self.n_tx} TX x "
                   f"{self.n_rx} RX")
        self.n_frames = whole_frames(self.path, self.path.stat().st_size, self.frame_bytes,
                                     profile)
        self._map: np.memmap | None = None

    def _memmap(self) -> np.memmap:
        if self._map is None:
            self._map = np.memmap(self.path, dtype="<i2", mode="r",
                                  shape=(self.n_frames, self.frame_bytes // 2))
        return self._map

    def read(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """complex64 (stop - start, loops, tx, rx, samples) of frames [start, stop)."""
        start, stop = check_range(start, stop, self.n_frames)
        return _dca_to_complex(self._memmap()[start:stop], self.layout, self.n_samples,
                               self.n_chirps, self.n_tx, self.n_rx)

    def frame(self, index: int) -> np.ndarray:
        """complex64 (loops, tx, rx, samples) of one frame."""
        i = check_frame_index(index, self.n_frames)
        return self.read(i, i + 1)[0]

    def close(self) -> None:
        self._map = None


def read_dca1000(path: str | os.PathLike, n_samples: int, n_chirps: int, n_tx: int, n_rx: int,
                 *, layout: DcaLayout = "xwr16xx") -> np.ndarray:
    """Read a raw DCA1000 capture (``adc_data.bin``, complex int16 output).

    Returns complex64 (frames, n_chirps, n_tx, n_rx, n_samples): chirps stored loop by loop, the
    TX slot faster than the loop. A trailing partial frame is dropped with a warning; a missing
    file or one smaller than one frame raises :class:`CaptureError` (file, size found, size
    expected); a profile the layout cannot carry raises ``ValueError``. ``layout`` is explained
    in the module docstring ("xwr16xx" for xWR16xx/18xx/68xx, "xwr14xx" for TI's four-lane
    format).
    """
    cap = DCA1000Capture(path, n_samples, n_chirps, n_tx, n_rx, layout=layout)
    try:
        return cap.read()
    finally:
        cap.close()


def write_dca1000(path: str | os.PathLike, cube: np.ndarray | Iterable[np.ndarray], *,
                  layout: DcaLayout = "xwr16xx", conversion: Int16Conversion = "exact") -> Path:
    """Write complex (frames, loops, tx, rx, samples) (or an iterable of (loops, tx, rx, samples)
    frames) as a DCA1000 ``adc_data.bin`` in ``layout``, through :func:`blindspot.io.atomic_path`
    (temporary name, then rename; nothing is left on error). Values become int16 codes as
    ``conversion`` says (:func:`~blindspot.radar.capture.common.to_int16_iq`). Returns the path."""
    path = Path(path)
    with atomic_files([path]) as (tmp,), open(tmp, "wb") as fh:
        n = 0
        for k, frame in enumerate(iter_frames_of(cube, 4)):
            frame = np.asarray(frame)
            if frame.ndim != 4:
                raise ValueError(f"frame {k} has shape {frame.shape}; expected (loops, tx, rx, "
                                 "samples)")
            fh.write(_complex_to_dca(to_int16_iq(frame, conversion, f"cube frame {k}"),
                                     layout).tobytes())
            n += 1
        if n == 0:
            raise ValueError("cube holds no frame to write")
    return path


class DCA1000Recording(RecordingFrames):
    """A DCA1000 ``adc_data.bin`` as a frame source (lazy; times ``i * radar.frame_period_s``).

    radar : the capture's chirp profile (n_samples, n_chirps, n_tx, n_rx, frame_period_s).
    array : the virtual array; default ``array_for(radar)``.
    layout : the lane order, see the module docstring.
    """

    def __init__(self, path: str | os.PathLike, radar: RadarConfig, *,
                 array: VirtualArray | None = None, layout: DcaLayout = "xwr16xx"):
        self.radar = radar
        self.array = array_for(radar) if array is None else array
        self.capture = DCA1000Capture(path, radar.n_samples, radar.n_chirps, radar.n_tx,
                                      radar.n_rx, layout=layout)

    @property
    def times_s(self) -> np.ndarray:
        """(n_frames,) frame start times, s."""
        return np.arange(self.n_frames) * self.radar.frame_period_s
