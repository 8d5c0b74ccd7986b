"""Raw FMCW captures on disk: TI MMWCAS cascade, DCA1000 and OpenRadar ``.npy`` files.

Every reader returns complex64 cubes with axes ``(frames, chirps, tx, rx, samples)``: ``chirps``
counts chirp *loops*, ``tx`` is the chirp slot within a loop (the order the TX fired; the
physical TX of slot k is ``RadarConfig.tx_order[k]``) and ``rx`` is in file order. Integer ADC
codes are returned as they are (no scaling). Readers map files with ``np.memmap`` and
de-interleave with reshape/transpose only; :class:`TICascadeRecording` and
:class:`DCA1000Recording` read one frame at a time, so a long capture is never loaded whole.

TI MMWCAS cascade (``{master,slave1,slave2,slave3}_NNNN_{data,idx}.bin``)
-------------------------------------------------------------------------
Each device (4 RX) writes one headerless data file. Frame f starts at byte
``f * S * C * L * 4 * 2 * 2`` (S samples, C chirps per loop = n_tx, L loops = n_chirps, 4 RX,
I and Q, 2 bytes); within a frame, slowest to fastest: loop, chirp in loop, sample, RX, I/Q
(int16 little-endian, I first). The ``_idx.bin`` starts with a 24-byte header
``{u32 tag, u32 version, u32 flags, u32 numIdx, u64 dataFileSize}`` followed by one 48-byte entry
per captured frame ``{u16 tag, u16 version, u32 flags, u16 width, u16 height, u32 pitch[4],
u32 size, u64 timestamp, u64 offset}``. The frame count comes from ``numIdx`` (data files can be
padded beyond the last frame). The 16 output RX are master RX1-4, slave1 RX5-8, slave2 RX9-12,
slave3 RX13-16 (geometry reordering is :mod:`blindspot.radar.array`'s job). TI's own processing
drops the first frame; here that is ``skip_first_frame`` (default True).

Checks, each a :class:`CaptureError` naming the file, the size found and the size expected: a
missing device or index file; an index whose length is not ``24 + 48 * numIdx``; a
``dataFileSize`` that is not a whole number of frames of the profile, or smaller than ``numIdx``
frames; a data file shorter than ``dataFileSize`` or than ``numIdx`` frames; an entry whose
non-zero ``offset``/``size`` is not where the profile puts that frame; no frame left. Devices
whose indices list different frame counts are read up to the count they share, with a warning.

Values this module writes in the index fields TI's readers ignore (our choice, documented so the
files are self-describing): header tag 0, version 1, flags 0; entry tag 0, version 1, flags 0,
width = samples, height = chirps per frame (both saturated at 65535), pitch[0] = bytes of one
chirp in a device file, size = bytes per frame, timestamp in nanoseconds, offset = byte offset of
the frame. Timestamps are read as nanoseconds, the unit given in the comment on this struct as
TI's example scripts are commonly transcribed (not verified on a real cascade capture here); the
recording source therefore uses them only when they increase and agree with the profile's frame
period.

DCA1000 (``adc_data.bin``) with an xWR16xx/xWR18xx/xWR68xx radar, complex output
---------------------------------------------------------------------------------
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

OpenRadar ``.npy`` examples
---------------------------
The PreSense OpenRadar examples hold complex128 arrays whose real and imaginary parts are
*unsigned* 16-bit codes (0..65535) stored as floats; :func:`read_openradar_npy` reinterprets them
as two's-complement int16 (``v - 65536`` where ``v > 32767``).
"""

from __future__ import annotations

import os
import re
import tempfile
import warnings
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from blindspot.radar.array import VirtualArray, array_for
from blindspot.radar.config import RadarConfig

__all__ = [
    "CaptureError",
    "Int16Conversion",
    "DcaLayout",
    "CASCADE_DEVICES",
    "IDX_HEADER_DTYPE",
    "IDX_ENTRY_DTYPE",
    "CascadeIndex",
    "TICascadeCapture",
    "TICascadeRecording",
    "DCA1000Capture",
    "DCA1000Recording",
    "cascade_frame_bytes",
    "dca1000_frame_bytes",
    "find_cascade_captures",
    "read_cascade_index",
    "read_ti_cascade",
    "write_ti_cascade",
    "read_dca1000",
    "write_dca1000",
    "read_openradar_npy",
    "to_int16_iq",
]

CASCADE_DEVICES: tuple[str, ...] = ("master", "slave1", "slave2", "slave3")
RX_PER_DEVICE = 4
CASCADE_N_RX = RX_PER_DEVICE * len(CASCADE_DEVICES)
BYTES_PER_IQ = 4  # int16 I + int16 Q

IDX_HEADER_DTYPE = np.dtype(
    [("tag", "<u4"), ("version", "<u4"), ("flags", "<u4"), ("num_idx", "<u4"),
     ("data_file_size", "<u8")]
)
IDX_ENTRY_DTYPE = np.dtype(
    [("tag", "<u2"), ("version", "<u2"), ("flags", "<u4"), ("width", "<u2"), ("height", "<u2"),
     ("pitch", "<u4", (4,)), ("size", "<u4"), ("timestamp", "<u8"), ("offset", "<u8")]
)
assert IDX_HEADER_DTYPE.itemsize == 24 and IDX_ENTRY_DTYPE.itemsize == 48

Int16Conversion = Literal["exact", "round", "clip"]
DcaLayout = Literal["xwr16xx", "xwr14xx"]
_FILE_MODE = 0o644  # mkstemp creates 0600; captures are data to share
_CAPTURE_RE = re.compile(r"^master_(\d+)_data\.bin$")


class CaptureError(ValueError):
    """A capture file is missing, cut, or does not fit the chirp profile."""

    def __init__(self, path: str | os.PathLike, problem: str, found: Any = None,
                 expected: Any = None):
        self.path, self.problem, self.found, self.expected = Path(path), problem, found, expected
        msg = f"{path}: {problem}"
        if found is not None or expected is not None:
            msg += f" (found {found}, expected {expected})"
        super().__init__(msg)


# ---------------------------------------------------------------------------------- int16 codes
def to_int16_iq(cube: np.ndarray, conversion: Int16Conversion = "exact",
                origin: str = "cube") -> np.ndarray:
    """Complex values -> int16 array (..., 2) of (I, Q) codes.

    conversion: "exact" - values must already be integers within int16 (else CaptureError);
    "round" - round half to even, error if a rounded value falls outside int16;
    "clip" - round, then saturate at -32768 / 32767 like an ADC.
    NaN or infinite values always raise.
    """
    if conversion not in ("exact", "round", "clip"):
        raise ValueError(f"conversion = {conversion!r}: expected 'exact', 'round' or 'clip'")
    z = np.asarray(cube)
    iq = np.stack([z.real, z.imag], axis=-1) if np.iscomplexobj(z) else np.stack(
        [z, np.zeros_like(z)], axis=-1)
    if iq.dtype.kind in "iu":
        ints = iq
    else:
        if not np.all(np.isfinite(iq)):
            raise CaptureError(origin, "values contain NaN or infinity, cannot write int16 codes")
        ints = np.rint(iq)
        if conversion == "exact" and not np.array_equal(ints, iq):
            bad = np.abs(ints - iq).max()
            raise CaptureError(origin, "values are not integer ADC codes (pass conversion="
                               "'round' or 'clip' to quantise)",
                               f"a fractional part up to {bad:.3g}", "integers")
    if conversion == "clip":
        return np.clip(ints, -32768, 32767).astype("<i2")
    lo, hi = ints.min(initial=0), ints.max(initial=0)
    if lo < -32768 or hi > 32767:
        raise CaptureError(origin, "values exceed the int16 range (pass conversion='clip' to "
                           "saturate)", f"[{lo:g}, {hi:g}]", "[-32768, 32767]")
    return ints.astype("<i2")


def _write_atomic(targets: list[Path], writers: list) -> None:
    """Write each target via its writer(fileobj) to a temporary name, then rename all into place."""
    temps: list[Path] = []
    try:
        for target, writer in zip(targets, writers):
            fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
            temps.append(Path(tmp))
            with os.fdopen(fd, "wb") as fh:
                writer(fh)
        for tmp, target in zip(temps, targets):
            os.chmod(tmp, _FILE_MODE)
            os.replace(tmp, target)
    finally:
        for tmp in temps:
            tmp.unlink(missing_ok=True)


def _frames_of(cube: np.ndarray | Iterable[np.ndarray], frame_ndim: int) -> Iterator[np.ndarray]:
    """Frames of a stacked array (frames, ...) or of any iterable of frames."""
    if isinstance(cube, np.ndarray):
        if cube.ndim != frame_ndim + 1:
            raise ValueError(f"cube has {cube.ndim} axes {cube.shape}; expected {frame_ndim + 1} "
                             "(frames, chirps, tx, rx, samples)")
        yield from cube
    else:
        yield from cube


# ---------------------------------------------------------------------------------- TI cascade
def cascade_frame_bytes(n_samples: int, n_chirps: int, n_tx: int) -> int:
    """Bytes of one frame in one device file: S * C * L * 4 RX * 2 (I/Q) * 2 bytes."""
    return int(n_samples) * int(n_tx) * int(n_chirps) * RX_PER_DEVICE * BYTES_PER_IQ


def find_cascade_captures(folder: str | os.PathLike) -> list[int]:
    """Capture indices NNNN for which ``master_NNNN_data.bin`` exists in ``folder``, ascending."""
    folder = Path(folder)
    if not folder.is_dir():
        raise CaptureError(folder, "cascade capture folder not found")
    return sorted(int(m.group(1)) for p in folder.iterdir() if (m := _CAPTURE_RE.match(p.name)))


def _cascade_paths(folder: Path, capture_index: int) -> tuple[list[Path], list[Path]]:
    """The 4 data and 4 index paths of capture NNNN (4 digits, more if the index needs them)."""
    stem = [f"{dev}_{capture_index:04d}" for dev in CASCADE_DEVICES]
    return ([folder / f"{s}_data.bin" for s in stem], [folder / f"{s}_idx.bin" for s in stem])


@dataclass(frozen=True)
class CascadeIndex:
    """Parsed ``_idx.bin``: header fields and the (num_idx,) structured entries."""

    path: Path
    header: np.void
    entries: np.ndarray

    @property
    def num_idx(self) -> int:
        return int(self.header["num_idx"])

    @property
    def data_file_size(self) -> int:
        return int(self.header["data_file_size"])


def read_cascade_index(path: str | os.PathLike) -> CascadeIndex:
    """Read an ``_idx.bin``; its length must be 24 + 48 * numIdx bytes."""
    path = Path(path)
    if not path.is_file():
        raise CaptureError(path, "index file missing")
    raw = path.read_bytes()
    hsize, esize = IDX_HEADER_DTYPE.itemsize, IDX_ENTRY_DTYPE.itemsize
    if len(raw) < hsize:
        raise CaptureError(path, "index file shorter than its header", f"{len(raw)} bytes",
                           f"at least {hsize} bytes")
    header = np.frombuffer(raw, IDX_HEADER_DTYPE, count=1)[0]
    n = int(header["num_idx"])
    if len(raw) != hsize + esize * n:
        raise CaptureError(path, f"index length does not match numIdx = {n}", f"{len(raw)} bytes",
                           f"{hsize + esize * n} bytes (24 + 48 * numIdx)")
    entries = np.frombuffer(raw, IDX_ENTRY_DTYPE, count=n, offset=hsize)
    return CascadeIndex(path, header, entries)


class TICascadeCapture:
    """An opened, validated MMWCAS capture; frames are read on demand through memory maps.

    Frame numbering starts after the skipped first frame when ``skip_first_frame`` is True.
    """

    def __init__(self, folder: str | os.PathLike, n_samples: int, n_chirps: int, n_tx: int, *,
                 skip_first_frame: bool = True, capture_index: int | None = None):
        self.folder = Path(folder)
        self.n_samples, self.n_chirps, self.n_tx = int(n_samples), int(n_chirps), int(n_tx)
        for key, v in (("n_samples", n_samples), ("n_chirps", n_chirps), ("n_tx", n_tx)):
            if int(v) < 1:
                raise ValueError(f"{key} = {v}: expected a positive integer")
        found = find_cascade_captures(self.folder)
        if capture_index is None:
            if not found:
                raise CaptureError(self.folder, "no cascade capture (master_NNNN_data.bin) found")
            capture_index = found[0]
        self.capture_index = int(capture_index)
        self.data_paths, self.idx_paths = _cascade_paths(self.folder, self.capture_index)
        for p in self.data_paths + self.idx_paths:
            if not p.is_file():
                raise CaptureError(p, "device file missing from the cascade capture", "no file",
                                   "all 8 files {master,slave1,slave2,slave3}_"
                                   f"{self.capture_index:04d}_{{data,idx}}.bin")
        self.frame_bytes = cascade_frame_bytes(self.n_samples, self.n_chirps, self.n_tx)
        self.indices = [read_cascade_index(p) for p in self.idx_paths]
        counts = [self._validate(d, i) for d, i in zip(self.data_paths, self.indices)]
        total = min(counts)
        if len(set(counts)) > 1:
            warnings.warn(f"{self.folder}: devices index different frame counts "
                          f"{dict(zip(CASCADE_DEVICES, counts))}; using the {total} they share",
                          stacklevel=2)
        self.first = 1 if skip_first_frame else 0
        self.n_frames = total - self.first
        if self.n_frames < 1:
            raise CaptureError(self.idx_paths[0], "no frame left to read"
                               + (" after skipping the first" if skip_first_frame else ""),
                               f"{total} indexed frame(s)", f"at least {self.first + 1}")
        self._maps: list[np.memmap] | None = None
        self._total = total

    def _validate(self, data_path: Path, idx: CascadeIndex) -> int:
        """Check one device's data file against its index; return its frame count."""
        idx_path = idx.path
        fb, n, dfs = self.frame_bytes, idx.num_idx, idx.data_file_size
        profile = f"{self.n_samples} samples x {self.n_tx} chirps/loop x {self.n_chirps} loops"
        if dfs % fb:
            raise CaptureError(idx_path, f"dataFileSize is not a whole number of {fb}-byte frames "
                               f"({profile})", f"{dfs} bytes", f"a multiple of {fb} bytes")
        if n * fb > dfs:
            raise CaptureError(idx_path, f"index lists {n} frames of {fb} bytes ({profile}) but "
                               "dataFileSize holds fewer",
                               f"dataFileSize {dfs} bytes", f"at least {n * fb} bytes")
        size = data_path.stat().st_size
        if size < dfs or size < n * fb:
            raise CaptureError(data_path, f"data file shorter than its index says ({n} frames of "
                               f"{fb} bytes, dataFileSize {dfs})", f"{size} bytes",
                               f"at least {max(dfs, n * fb)} bytes")
        if n == 0 or size < fb:
            raise CaptureError(data_path, f"capture holds no whole frame ({profile})",
                               f"{size} bytes, {n} indexed", f"at least {fb} bytes")
        e = idx.entries
        expect_off = np.arange(n, dtype=np.uint64) * np.uint64(fb)
        bad = np.flatnonzero((e["offset"] != 0) & (e["offset"] != expect_off))
        if bad.size:
            k = int(bad[0])
            raise CaptureError(idx_path, f"entry {k} offset does not match the profile",
                               f"{int(e['offset'][k])}", f"{int(expect_off[k])}")
        bad = np.flatnonzero((e["size"] != 0) & (e["size"] != fb))
        if bad.size:
            k = int(bad[0])
            raise CaptureError(idx_path, f"entry {k} frame size does not match the profile "
                               f"({profile})", f"{int(e['size'][k])} bytes", f"{fb} bytes")
        return n

    # -------------------------------------------------------------------------------- reading
    @property
    def timestamps_ns(self) -> np.ndarray:
        """(n_frames,) uint64 index timestamps of the master device for the frames read."""
        return self.indices[0].entries["timestamp"][self.first:self._total].copy()

    def _memmaps(self) -> list[np.memmap]:
        if self._maps is None:
            shape = (self._total, self.n_chirps, self.n_tx, self.n_samples, RX_PER_DEVICE, 2)
            self._maps = [np.memmap(p, dtype="<i2", mode="r", shape=shape)
                          for p in self.data_paths]
        return self._maps

    def read(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """complex64 (stop - start, chirps, tx, 16, samples) of frames [start, stop)."""
        stop = self.n_frames if stop is None else stop
        if not 0 <= start <= stop <= self.n_frames:
            raise IndexError(f"frames [{start}, {stop}) outside [0, {self.n_frames})")
        a, b = start + self.first, stop + self.first
        out = np.empty((b - a, self.n_chirps, self.n_tx, CASCADE_N_RX, self.n_samples),
                       np.complex64)
        for d, mm in enumerate(self._memmaps()):
            rx = slice(d * RX_PER_DEVICE, (d + 1) * RX_PER_DEVICE)
            for f in range(a, b):  # one frame at a time bounds the float32 temporary
                # (loop, chirp, sample, rx, iq) int16 -> complex64 (loop, chirp, sample, rx):
                # a contiguous cast, then an 8-byte-element transpose (9x faster than 4-byte)
                z = mm[f].astype(np.float32).view(np.complex64)[..., 0]
                out[f - a, :, :, rx] = z.transpose(0, 1, 3, 2)
        return out

    def frame(self, index: int) -> np.ndarray:
        """complex64 (chirps, tx, 16, samples) of one frame (negative index: from the end)."""
        i = _check_index(index, self.n_frames)
        return self.read(i, i + 1)[0]

    def close(self) -> None:
        self._maps = None


def _check_index(index: int, n: int) -> int:
    i = int(index)
    if i < 0:
        i += n
    if not 0 <= i < n:
        raise IndexError(f"frame {index} outside a capture of {n} frames")
    return i


def read_ti_cascade(folder: str | os.PathLike, n_samples: int, n_chirps: int, n_tx: int, *,
                    skip_first_frame: bool = True, capture_index: int | None = None) -> np.ndarray:
    """Read a TI MMWCAS cascade capture.

    Parameters
    ----------
    folder : holds ``{master,slave1,slave2,slave3}_NNNN_{data,idx}.bin``.
    n_samples, n_chirps, n_tx : ADC samples per chirp, chirp loops per frame, chirps per loop.
    skip_first_frame : drop frame 0, as TI's own processing does.
    capture_index : NNNN; default the lowest present.

    Returns
    -------
    complex64 (frames, n_chirps, n_tx, 16, n_samples); tx in firing order within a loop, rx in
    file order (master RX1-4, slave1 RX5-8, slave2 RX9-12, slave3 RX13-16).
    """
    cap = TICascadeCapture(folder, n_samples, n_chirps, n_tx, skip_first_frame=skip_first_frame,
                           capture_index=capture_index)
    try:
        return cap.read()
    finally:
        cap.close()


def write_ti_cascade(folder: str | os.PathLike, cube: np.ndarray | Iterable[np.ndarray], *,
                     capture_index: int = 0, timestamps: np.ndarray | None = None,
                     frame_period_s: float | None = None,
                     conversion: Int16Conversion = "exact") -> list[Path]:
    """Write a cube as a TI MMWCAS cascade capture (4 data + 4 index files).

    cube : complex (frames, chirps, tx, 16, samples), or an iterable of (chirps, tx, 16, samples)
        frames (e.g. a frame source), written frame by frame.
    timestamps : (frames,) nanoseconds for the index entries; default ``f * frame_period_s`` if
        a period is given, else zeros.
    conversion : how values become int16 codes, see :func:`to_int16_iq` (default: they must be
        integers within int16 already, so the round trip is bit-exact).

    Files are written under temporary names and renamed into place only when all are complete.
    Returns the 8 paths written (data files, then index files).
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    data_paths, idx_paths = _cascade_paths(folder, int(capture_index))
    frame_shape: tuple[int, ...] | None = None
    # The 4 data files are written together so that an iterable of frames is consumed once.
    temps: list[Path] = []
    fhs = []
    try:
        for target in data_paths:
            fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=folder)
            temps.append(Path(tmp))
            fhs.append(os.fdopen(fd, "wb"))
        n_frames = 0
        for k, frame in enumerate(_frames_of(cube, 4)):
            frame = np.asarray(frame)
            if frame.ndim != 4 or frame.shape[2] != CASCADE_N_RX:
                raise ValueError(f"frame {k} has shape {frame.shape}; expected (chirps, tx, "
                                 f"{CASCADE_N_RX}, samples)")
            if frame_shape is None:
                frame_shape = frame.shape
            elif frame.shape != frame_shape:
                raise ValueError(f"frame {k} has shape {frame.shape}; frame 0 had {frame_shape}")
            iq = to_int16_iq(frame, conversion, origin=f"cube frame {k}")  # (L, C, 16, S, 2)
            for d, fh in enumerate(fhs):
                block = iq[:, :, d * RX_PER_DEVICE:(d + 1) * RX_PER_DEVICE]   # (L, C, 4, S, 2)
                fh.write(np.ascontiguousarray(block.transpose(0, 1, 3, 2, 4)).tobytes())
            n_frames += 1
        for fh in fhs:
            fh.close()
        if frame_shape is None:
            raise ValueError("cube holds no frame to write")
        n_chirps, n_tx, _, n_samples = frame_shape
        fb = cascade_frame_bytes(n_samples, n_chirps, n_tx)
        idx_bytes = _cascade_index_bytes(n_frames, fb, n_samples, n_chirps * n_tx, timestamps,
                                         frame_period_s)
        for target in idx_paths:
            fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=folder)
            temps.append(Path(tmp))
            with os.fdopen(fd, "wb") as fh:
                fh.write(idx_bytes)
        # all 8 complete: data files first, the index files (which readers trust) last
        for tmp, target in zip(temps, data_paths + idx_paths):
            os.chmod(tmp, _FILE_MODE)
            os.replace(tmp, target)
    finally:
        for fh in fhs:
            fh.close()
        for tmp in temps:
            tmp.unlink(missing_ok=True)
    return data_paths + idx_paths


def _cascade_index_bytes(n_frames: int, frame_bytes: int, n_samples: int, chirps_per_frame: int,
                         timestamps: np.ndarray | None, frame_period_s: float | None) -> bytes:
    if timestamps is None:
        period_ns = 0 if frame_period_s is None else round(frame_period_s * 1e9)
        ts = np.arange(n_frames, dtype=np.uint64) * np.uint64(period_ns)
    else:
        ts = np.asarray(timestamps)
        if ts.shape != (n_frames,):
            raise ValueError(f"timestamps shape {ts.shape}; expected ({n_frames},), one per frame")
        if np.any(ts < 0):
            raise ValueError("timestamps must be non-negative nanoseconds")
        ts = ts.astype(np.uint64)
    header = np.zeros(1, IDX_HEADER_DTYPE)
    header["version"], header["num_idx"] = 1, n_frames
    header["data_file_size"] = n_frames * frame_bytes
    entries = np.zeros(n_frames, IDX_ENTRY_DTYPE)
    entries["version"] = 1
    entries["width"] = min(n_samples, 0xFFFF)
    entries["height"] = min(chirps_per_frame, 0xFFFF)
    entries["pitch"][:, 0] = n_samples * RX_PER_DEVICE * BYTES_PER_IQ
    entries["size"] = frame_bytes
    entries["timestamp"] = ts
    entries["offset"] = np.arange(n_frames, dtype=np.uint64) * np.uint64(frame_bytes)
    return header.tobytes() + entries.tobytes()


# ---------------------------------------------------------------------------------- DCA1000
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
        self.n_samples, self.n_chirps, self.n_tx, self.n_rx = map(int, (n_samples, n_chirps,
                                                                       n_tx, n_rx))
        self.layout = layout
        _dca_file_shape(layout, self.n_samples, self.n_chirps, self.n_tx, self.n_rx)  # checks
        if not self.path.is_file():
            raise CaptureError(self.path, "DCA1000 capture file not found")
        self.frame_bytes = dca1000_frame_bytes(self.n_samples, self.n_chirps, self.n_tx, self.n_rx)
        size = self.path.stat().st_size
        profile = (f"{self.n_samples} samples x {self.n_chirps} loops x {self.n_tx} TX x "
                   f"{self.n_rx} RX")
        self.n_frames, extra = divmod(size, self.frame_bytes)
        if self.n_frames == 0:
            raise CaptureError(self.path, f"file smaller than one frame ({profile})",
                               f"{size} bytes", f"at least {self.frame_bytes} bytes")
        if extra:
            warnings.warn(f"{self.path}: {size} bytes = {self.n_frames} frames of "
                          f"{self.frame_bytes} bytes ({profile}) + {extra} bytes of a partial "
                          f"frame, which is dropped", stacklevel=2)
        self._map: np.memmap | None = None

    def _memmap(self) -> np.memmap:
        if self._map is None:
            self._map = np.memmap(self.path, dtype="<i2", mode="r",
                                  shape=(self.n_frames, self.frame_bytes // 2))
        return self._map

    def read(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """complex64 (stop - start, loops, tx, rx, samples) of frames [start, stop)."""
        stop = self.n_frames if stop is None else stop
        if not 0 <= start <= stop <= self.n_frames:
            raise IndexError(f"frames [{start}, {stop}) outside [0, {self.n_frames})")
        return _dca_to_complex(self._memmap()[start:stop], self.layout, self.n_samples,
                               self.n_chirps, self.n_tx, self.n_rx)

    def frame(self, index: int) -> np.ndarray:
        """complex64 (loops, tx, rx, samples) of one frame."""
        i = _check_index(index, self.n_frames)
        return self.read(i, i + 1)[0]

    def close(self) -> None:
        self._map = None


def read_dca1000(path: str | os.PathLike, n_samples: int, n_chirps: int, n_tx: int, n_rx: int,
                 *, layout: DcaLayout = "xwr16xx") -> np.ndarray:
    """Read a raw DCA1000 capture (``adc_data.bin``, complex int16 output).

    Returns complex64 (frames, n_chirps, n_tx, n_rx, n_samples): chirps stored loop by loop, the
    TX slot faster than the loop. A trailing partial frame is dropped with a warning; a file
    smaller than one frame raises :class:`CaptureError`. ``layout`` is explained in the module
    docstring ("xwr16xx" for xWR16xx/18xx/68xx, "xwr14xx" for TI's four-lane format).
    """
    cap = DCA1000Capture(path, n_samples, n_chirps, n_tx, n_rx, layout=layout)
    try:
        return cap.read()
    finally:
        cap.close()


def write_dca1000(path: str | os.PathLike, cube: np.ndarray | Iterable[np.ndarray], *,
                  layout: DcaLayout = "xwr16xx", conversion: Int16Conversion = "exact") -> Path:
    """Write complex (frames, loops, tx, rx, samples) (or an iterable of frames) as a DCA1000
    ``adc_data.bin`` in ``layout``; temporary name, then rename. Returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)

    def write(fh) -> None:
        n = 0
        for k, frame in enumerate(_frames_of(cube, 4)):
            frame = np.asarray(frame)
            if frame.ndim != 4:
                raise ValueError(f"frame {k} has shape {frame.shape}; expected (loops, tx, rx, "
                                 "samples)")
            fh.write(_complex_to_dca(to_int16_iq(frame, conversion, f"cube frame {k}"),
                                     layout).tobytes())
            n += 1
        if n == 0:
            raise ValueError("cube holds no frame to write")

    _write_atomic([path], [write])
    return path


# ---------------------------------------------------------------------------------- OpenRadar
def read_openradar_npy(path: str | os.PathLike, *, n_tx: int | None = None,
                       unsigned: bool = True) -> np.ndarray:
    """Read an OpenRadar example ``.npy`` as complex64 int16 codes.

    unsigned : the file holds unsigned 16-bit codes in floats (the PreSense examples do); they
        are reinterpreted as two's-complement int16. With False the values must already be in
        the int16 range.
    n_tx : if given and the array is (chirps, n_tx * n_rx, samples), return the cube
        (1, chirps, n_tx, n_rx, samples) (virtual channels TX-major, as the examples store them).

    Returns the stored shape, e.g. (chirps, samples) or (chirps, channels, samples), unless
    ``n_tx`` reshapes it.
    """
    path = Path(path)
    if not path.is_file():
        raise CaptureError(path, "OpenRadar .npy file not found")
    a = np.load(path, allow_pickle=False)
    if not np.iscomplexobj(a):
        raise CaptureError(path, "expected a complex array", str(a.dtype), "complex I + jQ")
    iq = np.stack([a.real, a.imag], axis=-1)
    if not np.all(np.isfinite(iq)) or not np.array_equal(iq, np.rint(iq)):
        raise CaptureError(path, "values are not integer ADC codes", "fractional or NaN values",
                           "integers")
    lo, hi = (0, 65535) if unsigned else (-32768, 32767)
    if iq.size and (iq.min() < lo or iq.max() > hi):
        raise CaptureError(path, "values outside the code range", f"[{iq.min():g}, {iq.max():g}]",
                           f"[{lo}, {hi}]" + (" (unsigned codes; pass unsigned=False for signed)"
                                              if unsigned else ""))
    codes = iq.astype(np.int64)
    if unsigned:
        codes = np.where(codes > 32767, codes - 65536, codes)
    z = (codes[..., 0] + 1j * codes[..., 1]).astype(np.complex64)
    if n_tx is None:
        return z
    if z.ndim != 3 or z.shape[1] % n_tx:
        raise CaptureError(path, f"cannot split channels into {n_tx} TX", str(z.shape),
                           f"(chirps, {n_tx} * n_rx, samples)")
    c, v, s = z.shape
    return z.reshape(1, c, n_tx, v // n_tx, s)


# ---------------------------------------------------------------------------------- frame sources
class _CaptureFrames:
    """The frame-source methods shared by the recordings on disk: frames come from
    ``self.capture.frame(i)`` (lazy reads), one at a time."""

    capture: TICascadeCapture | DCA1000Capture

    @property
    def n_frames(self) -> int:
        return self.capture.n_frames

    def frame(self, index: int) -> np.ndarray:
        """complex64 (chirps, tx, rx, samples)."""
        return self.capture.frame(index)

    def __len__(self) -> int:
        return self.n_frames

    def __iter__(self) -> Iterator[np.ndarray]:
        for i in range(self.n_frames):
            yield self.capture.frame(i)


class TICascadeRecording(_CaptureFrames):
    """A TI MMWCAS capture on disk as a frame source (frames read lazily, one at a time).

    radar : the capture's chirp profile (n_samples, n_chirps, n_tx, n_rx = 16, frame_period_s).
    array : the virtual array; default ``array_for(radar)``.
    times_s : index timestamps (ns, relative to the first frame read) when they increase and agree
        with ``radar.frame_period_s`` within 50 %; otherwise ``i * frame_period_s`` (with a
        warning if the timestamps were usable but disagreed).
    """

    def __init__(self, folder: str | os.PathLike, radar: RadarConfig, *,
                 array: VirtualArray | None = None, skip_first_frame: bool = True,
                 capture_index: int | None = None):
        if radar.n_rx != CASCADE_N_RX:
            raise ValueError(f"radar '{radar.name}' has n_rx = {radar.n_rx}; an MMWCAS capture "
                             f"has {CASCADE_N_RX} RX")
        self.radar = radar
        self.array = array_for(radar) if array is None else array
        self.capture = TICascadeCapture(folder, radar.n_samples, radar.n_chirps, radar.n_tx,
                                        skip_first_frame=skip_first_frame,
                                        capture_index=capture_index)
        self._times = _frame_times(self.capture.timestamps_ns, radar.frame_period_s,
                                   self.capture.idx_paths[0])

    @property
    def times_s(self) -> np.ndarray:
        """(n_frames,) frame start times, s."""
        return self._times.copy()



class DCA1000Recording(_CaptureFrames):
    """A DCA1000 ``adc_data.bin`` as a frame source (lazy; times ``i * radar.frame_period_s``)."""

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


def _frame_times(timestamps_ns: np.ndarray, frame_period_s: float, where: Path) -> np.ndarray:
    n = timestamps_ns.size
    fallback = np.arange(n) * frame_period_s
    if n < 2:
        return fallback
    t = (timestamps_ns.astype(np.int64) - np.int64(timestamps_ns[0])) * 1e-9
    dt = np.diff(t)
    if np.any(dt <= 0):
        return fallback  # zeros or unordered: no usable timing in the index
    if abs(np.median(dt) / frame_period_s - 1) > 0.5:
        warnings.warn(f"{where}: index timestamps give a median frame interval of "
                      f"{np.median(dt):.6g} s but the profile's frame_period_s is "
                      f"{frame_period_s:.6g} s; using the profile's period", stacklevel=3)
        return fallback
    return t


class ArrayRecording:
    """Frames already in memory, complex (frames, chirps, tx, rx, samples), as a frame source."""

    def __init__(self, frames: np.ndarray, radar: RadarConfig, origin: str = "array"):
        from blindspot.radar.source import check_frame_shape

        self.radar = radar
        self.array = array_for(radar)
        self._frames = np.asarray(frames, dtype=np.complex64)
        for i in range(min(1, len(self._frames))):
            check_frame_shape(self._frames[i], radar, origin)

    @property
    def n_frames(self) -> int:
        return len(self._frames)

    @property
    def times_s(self) -> np.ndarray:
        return np.arange(self.n_frames) * self.radar.frame_period_s

    def frame(self, index: int) -> np.ndarray:
        return self._frames[_check_index(index, self.n_frames)]

    def __iter__(self) -> Iterator[np.ndarray]:
        return iter(self._frames)


RECORDING_KINDS = ("ti_cascade", "dca1000", "openradar_npy")


def open_recording(kind: str, path: str | os.PathLike, radar: RadarConfig):
    """A recording on disk as a frame source: ``kind`` in :data:`RECORDING_KINDS`."""
    if kind == "ti_cascade":
        return TICascadeRecording(path, radar)
    if kind == "dca1000":
        return DCA1000Recording(path, radar)
    if kind == "openradar_npy":
        return ArrayRecording(read_openradar_npy(path, n_tx=radar.n_tx), radar, str(path))
    raise ValueError(f"recording kind {kind!r} unknown: expected one of {RECORDING_KINDS}")
