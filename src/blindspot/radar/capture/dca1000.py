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

Sizes and consistency (issue 9). A headerless file cannot say where a gap is, so a size that is
not a whole number of frames is never reported as a cut end as a fact: the warning (or, with
``strict=True``, the :class:`CaptureError`) lists the causes that fit the numbers, each with them:
a cut capture (the last frame incomplete), lost UDP packets (the bytes missing to the next whole
frame, as a multiple of the 1456-byte DCA1000 payload when they are one; every frame after a
lost packet is shifted), a wrong profile (the nearest ``n_samples`` / ``n_chirps`` whose frame
size divides the file size) and zero padding at either end. Leading zero padding (the file starts
with at least the extra bytes, and at least :data:`ZERO_RUN_CODES` codes, of exact zeros, the
end does not) is skipped, with the warning, so that the frames after it are not shifted
(``skip_bytes`` overrides). A real ADC practically never gives :data:`ZERO_RUN_CODES` exact-zero
int16 codes in a row (the longest run in the AWR1843 recording is 2), so longer runs inside a
frame (zero-filled lost packets, as mmWave Studio's packet reorder writes them, or padding) are
warned about when the frame is read and counted per frame by :meth:`DCA1000Capture.diagnose`.
The packet-level recording (:mod:`.dca1000_packets`) locates lost packets exactly.

``adc_bits`` (the profile's ``radar.adc_bits``): 16 reads the codes as they are; 12 or 14 apply
TI's sign compensation for codes stored in 16-bit words (SWRA581, section 9 "Interpreting
Binary File in MATLAB": codes above ``2**(bits-1) - 1`` less ``2**bits``), and codes outside the
range a ``bits``-bit ADC can give raise :class:`CaptureError`.
"""

from __future__ import annotations

import contextlib
import os
import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from blindspot.radar.array import VirtualArray, array_for
from blindspot.radar.capture.common import (
    BYTES_PER_IQ,
    CaptureError,
    Int16Conversion,
    atomic_files,
    check_adc_bits,
    check_dims,
    check_range,
    iter_frames_of,
    to_int16_iq,
)
from blindspot.radar.config import RadarConfig
from blindspot.radar.source import RecordingFrames, check_frame_index

__all__ = [
    "DCA1000_PAYLOAD_BYTES",
    "ZERO_RUN_CODES",
    "DcaDiagnosis",
    "DcaLayout",
    "DCA1000Capture",
    "DCA1000Recording",
    "FrameQuality",
    "dca1000_frame_bytes",
    "read_dca1000",
    "write_dca1000",
]

DcaLayout = Literal["xwr16xx", "xwr14xx"]

# Data bytes of one DCA1000 UDP packet: 1466-byte packets = 4-byte sequence number + 6-byte byte
# count + 1456 bytes of ADC data (TI DCA1000EVM user guide SPRUIJ4, "Data Format"; see
# .dca1000_packets).
DCA1000_PAYLOAD_BYTES = 1456
# Exact-zero int16 codes in a row from which a run counts as padding or zero-filled packets.
ZERO_RUN_CODES = 32
ADC_BITS_DCA = (12, 14, 16)  # the xWR ADC's output widths (adcCfg numADCBits)


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


def _sign_compensate(raw: np.ndarray, adc_bits: int, path: Path) -> np.ndarray:
    """int16 codes of a ``adc_bits``-bit ADC stored in 16-bit words -> signed codes (int16)."""
    if adc_bits == 16 or raw.size == 0:
        return raw
    lo, hi = int(raw.min()), int(raw.max())
    if lo < -(1 << (adc_bits - 1)) or hi > (1 << adc_bits) - 1:
        raise CaptureError(path, f"codes outside the range of a {adc_bits}-bit ADC (radar."
                           f"adc_bits = {adc_bits})", f"[{lo}, {hi}]",
                           f"[{-(1 << (adc_bits - 1))}, {(1 << adc_bits) - 1}]")
    r = raw.astype(np.int32)
    r[r > (1 << (adc_bits - 1)) - 1] -= 1 << adc_bits
    return r.astype(np.int16)


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


def encode_frames(cube: np.ndarray | Iterable[np.ndarray], layout: str,
                  conversion: Int16Conversion) -> Iterable[np.ndarray]:
    """Each (loops, tx, rx, samples) frame of ``cube`` as its int16 stream in file order;
    ``ValueError`` for a frame of another rank or no frame at all."""
    n = 0
    for k, frame in enumerate(iter_frames_of(cube, 4)):
        frame = np.asarray(frame)
        if frame.ndim != 4:
            raise ValueError(f"frame {k} has shape {frame.shape}; expected (loops, tx, rx, "
                             "samples)")
        yield _complex_to_dca(to_int16_iq(frame, conversion, f"cube frame {k}"), layout)
        n += 1
    if n == 0:
        raise ValueError("cube holds no frame to write")


# ---------------------------------------------------------------------------------- consistency
def zero_runs(codes: np.ndarray, min_codes: int = ZERO_RUN_CODES) -> tuple[np.ndarray,
                                                                          np.ndarray]:
    """Runs of exact-zero codes along the last axis of int16 ``codes`` (rows, n).

    Returns ``(longest, in_runs)``: (rows,) the longest run of zeros in each row, and (rows,) how
    many codes of each row lie in runs of at least ``min_codes``. Vectorised (no loop per code).
    """
    rows, n = codes.shape
    padded = np.zeros((rows, n + 2), np.int8)
    padded[:, 1:-1] = codes == 0
    edge = np.diff(padded, axis=1)
    r0, c0 = np.nonzero(edge == 1)  # run starts, row-major, so they pair with the ends
    _, c1 = np.nonzero(edge == -1)
    length = c1 - c0
    longest = np.zeros(rows, np.int64)
    in_runs = np.zeros(rows, np.int64)
    np.maximum.at(longest, r0, length)
    np.add.at(in_runs, r0, np.where(length >= min_codes, length, 0))
    return longest, in_runs


@dataclass(frozen=True)
class FrameQuality:
    """Exact-zero runs of frames ``[start, start + len)`` of a capture (int16 codes as stored).

    longest_zero_run : (frames,) the longest run of exact-zero int16 codes in each frame.
    zero_run_codes : (frames,) codes in runs of at least :data:`ZERO_RUN_CODES`.
    """

    start: int
    longest_zero_run: np.ndarray
    zero_run_codes: np.ndarray

    @property
    def suspect_frames(self) -> np.ndarray:
        """Frame numbers holding a run of at least :data:`ZERO_RUN_CODES` zero codes."""
        return self.start + np.flatnonzero(self.longest_zero_run >= ZERO_RUN_CODES)


@dataclass(frozen=True)
class DcaDiagnosis:
    """What the size and content of a headerless DCA1000 file say (:meth:`DCA1000Capture.diagnose`).

    size, frame_bytes : file size and bytes of one frame of the profile.
    skip_bytes : leading bytes not read (zero padding skipped, or as passed).
    n_whole_frames, extra_bytes : ``size - skip_bytes = n_whole_frames * frame_bytes +
        extra_bytes``; the extra bytes (after the whole frames) are not returned.
    leading_zero_bytes, trailing_zero_bytes : exact-zero bytes at each end (searched within
        ``extra_bytes + frame_bytes`` of the end).
    causes : the possible causes of a size that is not a whole number of frames, with numbers
        (empty when it is one).
    profiles : ``(n_samples, n_chirps, n_frames)`` of the nearest profiles (same TX, RX) whose
        frame size divides the file size.
    frames : the zero runs of every whole frame (:class:`FrameQuality`).
    """

    path: Path
    size: int
    frame_bytes: int
    skip_bytes: int
    n_whole_frames: int
    extra_bytes: int
    leading_zero_bytes: int
    trailing_zero_bytes: int
    causes: tuple[str, ...]
    profiles: tuple[tuple[int, int, int], ...]
    frames: FrameQuality | None = None

    @property
    def ok(self) -> bool:
        """True if the file is whole frames and no frame holds a long zero run."""
        frames_ok = self.frames is None or self.frames.suspect_frames.size == 0
        return not (self.extra_bytes or self.skip_bytes) and frames_ok


def _zero_prefix(mm: np.ndarray) -> int:
    """Length of the run of zero bytes at the start of a uint8 array."""
    nz = np.flatnonzero(mm)
    return int(nz[0]) if nz.size else int(mm.size)


def _nearest_profiles(size: int, n_samples: int, n_chirps: int, n_tx: int, n_rx: int,
                      layout: str, k: int = 3) -> tuple[tuple[int, int, int], ...]:
    """Up to ``k`` (n_samples, n_chirps, frames) within a factor 2 of the profile's whose frame
    size divides ``size`` exactly, nearest first (relative distance)."""
    ns = np.arange(max(1, n_samples // 2), 2 * n_samples + 1)
    if layout == "xwr16xx":
        ns = ns[ns % 2 == 0]
    nc = np.arange(max(1, n_chirps // 2), 2 * n_chirps + 1)
    fb = ns[:, None] * nc[None, :] * (n_tx * n_rx * BYTES_PER_IQ)
    ok = (size % fb == 0) & (fb <= size)
    ok &= ~((ns[:, None] == n_samples) & (nc[None, :] == n_chirps))
    i, j = np.nonzero(ok)
    dist = np.abs(ns[i] / n_samples - 1) + np.abs(nc[j] / n_chirps - 1)
    best = np.argsort(dist, kind="stable")[:k]
    return tuple((int(ns[i[b]]), int(nc[j[b]]), int(size // fb[i[b], j[b]])) for b in best)


class DCA1000Capture:
    """An opened DCA1000 ``adc_data.bin``: whole frames, read on demand through a memory map.

    ``skip_bytes`` None (default) skips leading zero padding when the size and the file's first
    bytes show it (module docstring); an int reads frames from that byte. ``strict`` turns every
    warning about the size or a frame's zero runs into a :class:`CaptureError`. ``adc_bits`` as
    in the module docstring. Other errors: a missing file or one smaller than one frame
    (:class:`CaptureError`), a profile the layout cannot carry (``ValueError``), an ``adc_bits``
    not in 12, 14, 16 (:class:`~blindspot.typed_config.ConfigError`).
    """

    def __init__(self, path: str | os.PathLike, n_samples: int, n_chirps: int, n_tx: int,
                 n_rx: int, *, layout: DcaLayout = "xwr16xx", adc_bits: int | None = 16,
                 skip_bytes: int | None = None, strict: bool = False):
        self.path = Path(path)
        self.n_samples, self.n_chirps, self.n_tx, self.n_rx = check_dims(
            n_samples=n_samples, n_chirps=n_chirps, n_tx=n_tx, n_rx=n_rx)
        self.layout, self.strict = layout, bool(strict)
        self.adc_bits = check_adc_bits(adc_bits, ADC_BITS_DCA, "DCA1000")
        _dca_file_shape(layout, self.n_samples, self.n_chirps, self.n_tx, self.n_rx)  # checks
        if not self.path.is_file():
            raise CaptureError(self.path, "DCA1000 capture file not found")
        self.frame_bytes = fb = dca1000_frame_bytes(self.n_samples, self.n_chirps, self.n_tx,
                                                    self.n_rx)
        self.profile = (f"{self.n_samples} samples x {self.n_chirps} loops x {self.n_tx} TX x "
                        f"{self.n_rx} RX")
        self.size = size = self.path.stat().st_size
        extra = size % fb
        window = min(size, max(extra, 2 * ZERO_RUN_CODES) + fb)
        raw = (np.memmap(self.path, np.uint8, mode="r", shape=(size,)) if size
               else np.zeros(0, np.uint8))
        self.leading_zero_bytes = _zero_prefix(raw[:window])
        self.trailing_zero_bytes = _zero_prefix(raw[size - window:][::-1])
        del raw
        pad = max(extra, 2 * ZERO_RUN_CODES)
        lead_pad = extra > 0 and self.leading_zero_bytes >= pad
        trail_pad = extra > 0 and self.trailing_zero_bytes >= pad
        if skip_bytes is None:
            skip_bytes = extra if lead_pad and not trail_pad else 0
        if not 0 <= int(skip_bytes) <= size:
            raise ValueError(f"skip_bytes = {skip_bytes}: expected 0 to the file size {size}")
        self.skip_bytes = int(skip_bytes)
        self.n_frames, self.extra_bytes = divmod(size - self.skip_bytes, fb)
        if self.n_frames == 0:
            raise CaptureError(self.path, f"file smaller than one frame ({self.profile})",
                               f"{size} bytes" + (f" ({self.skip_bytes} skipped)"
                                                  if self.skip_bytes else ""),
                               f"at least {fb} bytes")
        self.profiles = (_nearest_profiles(size, self.n_samples, self.n_chirps, self.n_tx,
                                           self.n_rx, layout) if self.extra_bytes else ())
        self.causes = self._causes(lead_pad, trail_pad)
        if self.causes:
            self._report_size()
        self._map: np.memmap | None = None
        self._warned_zero_runs = False

    # ------------------------------------------------------------------------------ checks
    def _causes(self, lead_pad: bool, trail_pad: bool) -> tuple[str, ...]:
        """Possible causes of a size that is not a whole number of frames, with numbers."""
        fb, extra, n = self.frame_bytes, self.extra_bytes, self.n_frames
        causes = []
        if self.skip_bytes:
            causes.append(f"zero padding at the start: the file begins with "
                          f"{self.leading_zero_bytes} zero bytes; the first {self.skip_bytes} "
                          "were skipped so that whole frames fill the rest (skip_bytes=0 reads "
                          "from byte 0)")
        elif lead_pad:
            causes.append(f"zero padding at the start: the file begins with "
                          f"{self.leading_zero_bytes} zero bytes (not skipped: the end is zeros "
                          "too; pass skip_bytes to choose)")
        if not extra:
            return tuple(causes)
        if trail_pad:
            causes.append(f"zero padding at the end: the last {self.trailing_zero_bytes} bytes "
                          "are exact zeros, not ADC data")
        else:
            causes.append(f"a cut capture: the last frame incomplete ({extra} of {fb} bytes of "
                          f"frame {n} present)")
        missing = fb - extra
        packets = (f" = {missing // DCA1000_PAYLOAD_BYTES} DCA1000 packet(s) of "
                   f"{DCA1000_PAYLOAD_BYTES} bytes" if missing % DCA1000_PAYLOAD_BYTES == 0
                   else f", not a whole number of {DCA1000_PAYLOAD_BYTES}-byte DCA1000 packets")
        causes.append(f"lost packets: {missing} bytes missing to {n + 1} whole frames{packets}; "
                      "every frame after a lost packet is shifted and a headerless file cannot "
                      "tell where the gap is (the packet-level recording adc_data_Raw_0.bin, "
                      "read_dca1000_packets, masks lost samples)")
        if self.profiles:
            causes.append("a wrong profile: " + "; ".join(
                f"n_samples={s}, n_chirps={c} gives {f} whole frames" for s, c, f in self.profiles))
        else:
            causes.append("a wrong profile: no n_samples / n_chirps within a factor 2 of the "
                          "profile's (same TX, RX) divides the file size")
        if self.size % BYTES_PER_IQ:
            causes.append(f"the size is not a whole number of {BYTES_PER_IQ}-byte complex "
                          "samples: the file ends inside a sample")
        return tuple(causes)

    def _report_size(self) -> None:
        causes = self.causes
        terms = ([f"{self.skip_bytes} skipped"] if self.skip_bytes else []) + [
            f"{self.n_frames} frames of {self.frame_bytes} bytes"] + (
            [f"{self.extra_bytes} bytes"] if self.extra_bytes else [])
        found = f"{self.size} bytes = " + " + ".join(terms)
        problem = (f"size is not a whole number of frames ({self.profile})"
                   if self.extra_bytes or self.skip_bytes else "zero padding")
        note = (f"{self.n_frames} whole frames are read"
                + (f", the {self.extra_bytes} bytes after them are not returned"
                   if self.extra_bytes else "")
                + ". Possible causes: " + "; ".join(f"({k}) {c}" for k, c in
                                                    enumerate(causes, 1)))
        if self.strict:
            raise CaptureError(self.path, problem, found,
                               f"a multiple of {self.frame_bytes} bytes", note)
        warnings.warn(str(CaptureError(self.path, problem, found,
                                       f"a multiple of {self.frame_bytes} bytes", note)),
                      stacklevel=4)

    def _codes(self, start: int, stop: int) -> np.ndarray:
        """int16 (stop - start, frame_int16) codes of frames [start, stop) as stored."""
        if self._map is None:
            self._map = np.memmap(self.path, dtype="<i2", mode="r", offset=self.skip_bytes,
                                  shape=(self.n_frames, self.frame_bytes // 2))
        return self._map[start:stop]

    def frame_quality(self, start: int = 0, stop: int | None = None) -> FrameQuality:
        """Zero runs of frames [start, stop) (:class:`FrameQuality`)."""
        start, stop = check_range(start, stop, self.n_frames)
        return FrameQuality(start, *zero_runs(np.asarray(self._codes(start, stop))))

    def diagnose(self, batch: int = 16) -> DcaDiagnosis:
        """The size analysis and the zero runs of every whole frame (read ``batch`` frames at a
        time)."""
        parts = [self.frame_quality(a, min(a + batch, self.n_frames))
                 for a in range(0, self.n_frames, batch)]
        frames = FrameQuality(0, np.concatenate([p.longest_zero_run for p in parts]),
                              np.concatenate([p.zero_run_codes for p in parts]))
        return DcaDiagnosis(self.path, self.size, self.frame_bytes, self.skip_bytes,
                            self.n_frames, self.extra_bytes, self.leading_zero_bytes,
                            self.trailing_zero_bytes, self.causes, self.profiles, frames)

    def _check_zero_runs(self, codes: np.ndarray, start: int) -> None:
        q = FrameQuality(start, *zero_runs(codes))
        bad = q.suspect_frames
        if not bad.size or (self._warned_zero_runs and not self.strict):
            return
        k = int(bad[0]) - start
        run = int(q.longest_zero_run[k])
        packets = (f" = {2 * run // DCA1000_PAYLOAD_BYTES} DCA1000 packet(s)"
                   if (2 * run) % DCA1000_PAYLOAD_BYTES == 0 else "")
        err = CaptureError(self.path, f"frame(s) {bad.tolist()} hold runs of exact-zero int16 "
                           f"codes (frame {int(bad[0])}: {int(q.zero_run_codes[k])} codes in "
                           f"such runs, the longest {run} codes = {2 * run} bytes{packets})",
                           note="zero-filled lost packets or padding, not ADC data (a real ADC "
                           f"practically never gives {ZERO_RUN_CODES} zero codes in a row); "
                           "DCA1000Capture.diagnose() counts them per frame")
        if self.strict:
            raise err
        self._warned_zero_runs = True
        warnings.warn(str(err) + " (not repeated for later frames)", stacklevel=4)

    # ------------------------------------------------------------------------------ reading
    def read(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """complex64 (stop - start, loops, tx, rx, samples) of frames [start, stop)."""
        start, stop = check_range(start, stop, self.n_frames)
        codes = np.asarray(self._codes(start, stop))
        self._check_zero_runs(codes, start)
        return _dca_to_complex(_sign_compensate(codes, self.adc_bits, self.path), self.layout,
                               self.n_samples, self.n_chirps, self.n_tx, self.n_rx)

    def frame(self, index: int) -> np.ndarray:
        """complex64 (loops, tx, rx, samples) of one frame."""
        i = check_frame_index(index, self.n_frames)
        return self.read(i, i + 1)[0]

    def close(self) -> None:
        self._map = None


def read_dca1000(path: str | os.PathLike, n_samples: int, n_chirps: int, n_tx: int, n_rx: int,
                 *, layout: DcaLayout = "xwr16xx", adc_bits: int | None = 16,
                 skip_bytes: int | None = None, strict: bool = False) -> np.ndarray:
    """Read a raw DCA1000 capture (``adc_data.bin``, complex int16 output).

    Returns complex64 (frames, n_chirps, n_tx, n_rx, n_samples): chirps stored loop by loop, the
    TX slot faster than the loop; ADC codes (no scaling). ``layout`` ("xwr16xx" for
    xWR16xx/18xx/68xx, "xwr14xx" for TI's four-lane format), ``adc_bits``, ``skip_bytes`` and
    the size checks are explained in the module docstring.

    Warnings (``UserWarning``; each a :class:`CaptureError` with ``strict=True``): a size that is
    not a whole number of frames, with its possible causes; leading zero padding skipped; runs of
    exact-zero codes in a frame. Errors: :class:`CaptureError` (file, size found, size expected)
    for a missing file, one smaller than one frame, codes outside the ``adc_bits`` range;
    ``ValueError`` for a profile the layout cannot carry; ``ConfigError`` (a ``ValueError``) for
    an unsupported ``adc_bits``.
    """
    with contextlib.closing(DCA1000Capture(
            path, n_samples, n_chirps, n_tx, n_rx, layout=layout, adc_bits=adc_bits,
            skip_bytes=skip_bytes, strict=strict)) as cap:
        return cap.read()


def write_dca1000(path: str | os.PathLike, cube: np.ndarray | Iterable[np.ndarray], *,
                  layout: DcaLayout = "xwr16xx", conversion: Int16Conversion = "exact") -> Path:
    """Write complex (frames, loops, tx, rx, samples) (or an iterable of (loops, tx, rx, samples)
    frames) as a DCA1000 ``adc_data.bin`` in ``layout``, through :func:`blindspot.io.atomic_path`
    (temporary name, then rename; nothing is left on error). Values become int16 codes as
    ``conversion`` says (:func:`~blindspot.radar.capture.common.to_int16_iq`). Returns the path."""
    path = Path(path)
    with atomic_files([path]) as (tmp,), open(tmp, "wb") as fh:
        for stream in encode_frames(cube, layout, conversion):
            fh.write(stream.tobytes())
    return path


class DCA1000Recording(RecordingFrames):
    """A DCA1000 ``adc_data.bin`` as a frame source (lazy; times ``i * radar.frame_period_s``).

    radar : the capture's chirp profile: n_samples, n_chirps, n_tx, n_rx, adc_bits (12, 14 or
        16) and frame_period_s are read from it; tx_order and the array keys shape ``array``.
    array : the virtual array; default ``array_for(radar)``.
    layout, strict, options : as :func:`read_dca1000` (options: ``skip_bytes``).
    """

    _capture_class: type = DCA1000Capture

    def __init__(self, path: str | os.PathLike | Sequence[str | os.PathLike], radar: RadarConfig,
                 *, array: VirtualArray | None = None, layout: DcaLayout = "xwr16xx",
                 strict: bool = False, **options):
        self.radar = radar
        self.array = array_for(radar) if array is None else array
        self.capture = self._capture_class(path, radar.n_samples, radar.n_chirps, radar.n_tx,
                                           radar.n_rx, layout=layout, adc_bits=radar.adc_bits,
                                           strict=strict, **options)

    @property
    def times_s(self) -> np.ndarray:
        """(n_frames,) frame start times, s."""
        return np.arange(self.n_frames) * self.radar.frame_period_s
