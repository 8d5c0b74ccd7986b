"""TI MMWCAS cascade captures (``{master,slave1,slave2,slave3}_NNNN_{data,idx}.bin``).

Cubes are complex64 ``(frames, chirps, tx, rx, samples)`` as everywhere in
:mod:`blindspot.radar.capture`: ``chirps`` counts chirp loops, ``tx`` the chirp slot within a
loop (the physical TX of slot k is ``RadarConfig.tx_order[k]``), ``rx`` in file order; int16 ADC
codes are returned as they are. :class:`TICascadeCapture` maps the device files with
``np.memmap`` and de-interleaves with reshape/transpose only, one frame at a time, so a long
capture is never loaded whole; :class:`TICascadeRecording` is the frame source over it.

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

Parts: TI's capture splits a long recording into parts NNNN = 0000, 0001, ..., each a complete
set of 8 files whose offsets start at 0. By default every part is read, in order, as one
recording: the first frame is skipped once (frame 0 of the first part holding frames), parts
whose indices list no frame are skipped with a warning, and a gap in the numbering (or no part
0000) raises, since frames would be missing between them. ``part=N`` reads one part alone.
``frame_numbers`` gives each frame's number within the whole recording.

Checks, each a :class:`CaptureError` naming the file, the size found and the size expected: a
missing device or index file; an index whose length is not ``24 + 48 * numIdx``; a
``dataFileSize`` that is not a whole number of frames of the profile, or smaller than ``numIdx``
frames; a data file shorter than ``dataFileSize`` or than ``numIdx`` frames; an entry whose
non-zero ``offset``/``size`` is not where the profile puts that frame; no frame left; a part
missing from the sequence. Devices whose indices list different frame counts are read up to the
count they share, with a warning.

Values this module writes in the index fields TI's readers ignore (our choice, documented so the
files are self-describing): header tag 0, version 1, flags 0; entry tag 0, version 1, flags 0,
width = samples, height = chirps per frame (both saturated at 65535), pitch[0] = bytes of one
chirp in a device file, size = bytes per frame, timestamp in nanoseconds, offset = byte offset of
the frame. Timestamps are read as nanoseconds, the unit given in the comment on this struct as
TI's example scripts are commonly transcribed (not verified on a real cascade capture here); the
recording source therefore uses them only when they increase and agree with the profile's frame
period.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import re
import warnings
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

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
from blindspot.typed_config import ConfigError

__all__ = [
    "CASCADE_DEVICES",
    "CASCADE_N_RX",
    "IDX_HEADER_DTYPE",
    "IDX_ENTRY_DTYPE",
    "CascadeIndex",
    "TICascadeCapture",
    "TICascadeRecording",
    "cascade_frame_bytes",
    "CascadePart",
    "find_cascade_captures",
    "find_cascade_parts",
    "read_cascade_index",
    "read_ti_cascade",
    "write_ti_cascade",
]

CASCADE_DEVICES: tuple[str, ...] = ("master", "slave1", "slave2", "slave3")
RX_PER_DEVICE = 4
CASCADE_N_RX = RX_PER_DEVICE * len(CASCADE_DEVICES)

IDX_HEADER_DTYPE = np.dtype(
    [("tag", "<u4"), ("version", "<u4"), ("flags", "<u4"), ("num_idx", "<u4"),
     ("data_file_size", "<u8")]
)
IDX_ENTRY_DTYPE = np.dtype(
    [("tag", "<u2"), ("version", "<u2"), ("flags", "<u4"), ("width", "<u2"), ("height", "<u2"),
     ("pitch", "<u4", (4,)), ("size", "<u4"), ("timestamp", "<u8"), ("offset", "<u8")]
)
assert IDX_HEADER_DTYPE.itemsize == 24 and IDX_ENTRY_DTYPE.itemsize == 48

_PART_RE = re.compile(r"^master_(\d+)_data\.bin$")


def cascade_frame_bytes(n_samples: int, n_chirps: int, n_tx: int) -> int:
    """Bytes of one frame in one device file: S * C * L * 4 RX * 2 (I/Q) * 2 bytes."""
    return int(n_samples) * int(n_tx) * int(n_chirps) * RX_PER_DEVICE * BYTES_PER_IQ


def find_cascade_parts(folder: str | os.PathLike) -> list[int]:
    """Part numbers NNNN for which ``master_NNNN_data.bin`` exists in ``folder``, ascending.

    Raises :class:`CaptureError` if ``folder`` is not a directory.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise CaptureError(folder, "cascade capture folder not found")
    return sorted(int(m.group(1)) for p in folder.iterdir() if (m := _PART_RE.match(p.name)))


def find_cascade_captures(folder: str | os.PathLike) -> list[int]:
    """Alias of :func:`find_cascade_parts`, under the name other MMWCAS readers use for the parts
    ("captures") of one recording: the part numbers NNNN in ``folder``, ascending."""
    return find_cascade_parts(folder)


def _part_or_capture_index(part: int | None, capture_index: int | None) -> int | None:
    """``part``, or ``capture_index`` (its alias); ``TypeError`` if both are given."""
    if part is not None and capture_index is not None:
        raise TypeError(f"part = {part} and capture_index = {capture_index} given: "
                        "capture_index is an alias of part, give one")
    return part if capture_index is None else capture_index


def _cascade_paths(folder: Path, part: int) -> tuple[list[Path], list[Path]]:
    """The 4 data and 4 index paths of part NNNN (4 digits, more if the number needs them)."""
    stem = [f"{dev}_{part:04d}" for dev in CASCADE_DEVICES]
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


@dataclass(frozen=True)
class CascadePart:
    """One validated part ``NNNN`` of a cascade recording (its 4 data and 4 index files).

    number : NNNN.
    n_indexed : whole frames every device holds (the smallest ``numIdx`` of the four).
    first_frame : recording frame number of the part's frame 0 (frames of the parts before it),
        or None when an earlier part could not be counted (see ``TICascadeCapture``).
    """

    number: int
    data_paths: tuple[Path, ...]
    idx_paths: tuple[Path, ...]
    indices: tuple[CascadeIndex, ...]
    n_indexed: int
    first_frame: int | None


class TICascadeCapture:
    """An opened, validated MMWCAS recording; frames are read on demand through memory maps.

    TI's capture splits a long recording into parts ``master_0000_data.bin``,
    ``master_0001_data.bin``, ... (each with its slave and index files). With ``part=None`` all
    parts are read in order as one recording: they must be numbered 0000, 0001, ... without a
    gap, empty parts (every index lists 0 frames) are skipped with a warning, and
    ``skip_first_frame`` drops the recording's first frame once. With ``part=N`` only that part
    is read; its first frame is skipped only if it is the recording's first frame (every earlier
    part holds no frame).

    Frames are numbered from 0 over the frames read (after the skipped one);
    :attr:`frame_numbers` gives each one's number in the whole recording (0 = the first frame
    the capture wrote). Errors are :class:`CaptureError` naming the file, the size found and the
    size expected (see the module docstring); an error in one part of a multi-part recording
    also says which part, and that ``part=`` reads another part alone.
    """

    def __init__(self, folder: str | os.PathLike, n_samples: int, n_chirps: int, n_tx: int, *,
                 skip_first_frame: bool = True, part: int | None = None,
                 capture_index: int | None = None):
        part = _part_or_capture_index(part, capture_index)
        self.folder = Path(folder)
        self.n_samples, self.n_chirps, self.n_tx = check_dims(n_samples=n_samples,
                                                              n_chirps=n_chirps, n_tx=n_tx)
        self.frame_bytes = cascade_frame_bytes(self.n_samples, self.n_chirps, self.n_tx)
        found = find_cascade_parts(self.folder)
        if part is None:
            parts = self._all_parts(found)
        else:
            opened = self._open_part(int(part), None, hint=None)
            parts = [dataclasses.replace(
                opened, first_frame=self._frames_before(opened.number, found))]
        total = sum(p.n_indexed for p in parts)
        if total == 0:  # the only part or every part is empty
            p = parts[0]
            size = p.data_paths[0].stat().st_size
            profile = self._profile()
            raise CaptureError(p.data_paths[0], f"capture holds no whole frame ({profile})",
                               f"{size} bytes, 0 indexed", f"at least {self.frame_bytes} bytes")
        for p in parts:
            if p.n_indexed == 0:
                warnings.warn(f"{p.idx_paths[0]}: part {p.number:04d} of the recording holds no "
                              "frame (numIdx 0); skipped", stacklevel=2)
        self.parts: tuple[CascadePart, ...] = tuple(p for p in parts if p.n_indexed)
        self.skipped_parts: tuple[int, ...] = tuple(p.number for p in parts if not p.n_indexed)
        # the skipped frame is the recording's first: frame 0 of the first part holding frames
        first_part = self.parts[0]
        self.first = 1 if skip_first_frame and first_part.first_frame == 0 else 0
        self.n_frames = total - self.first
        if self.n_frames < 1:
            raise CaptureError(first_part.idx_paths[0], "no frame left to read"
                               + (" after skipping the first" if skip_first_frame else ""),
                               f"{total} indexed frame(s)", f"at least {self.first + 1}")
        # where each part's frames start among the frames of all parts read (before the skip)
        self._starts = np.cumsum([0] + [p.n_indexed for p in self.parts])
        self._maps: dict[int, list[np.memmap]] = {}

    # -------------------------------------------------------------------------------- parts
    def _profile(self) -> str:
        return f"{self.n_samples} samples x {self.n_tx} chirps/loop x {self.n_chirps} loops"

    def _all_parts(self, found: list[int]) -> list[CascadePart]:
        """Every part 0000, 0001, ... in order; a gap or a missing part 0000 raises."""
        if not found:
            raise CaptureError(self.folder, "no cascade capture (master_NNNN_data.bin) found")
        listed = ", ".join(f"{n:04d}" for n in found)
        missing = sorted(set(range(found[-1] + 1)) - set(found))
        if missing:
            path = _cascade_paths(self.folder, missing[0])[0][0]
            raise CaptureError(path, f"part {missing[0]:04d} missing from the multi-part cascade "
                               f"recording (parts found: {listed}); pass part=N to read one "
                               "part alone", "no file",
                               f"parts {0:04d} to {found[-1]:04d} without a gap")
        parts, before = [], 0
        for n in found:
            hint = (f"in part {n:04d} of the recording's parts {listed} (pass part=N to read "
                    "another part alone)") if len(found) > 1 else None
            parts.append(self._open_part(n, before, hint))
            before += parts[-1].n_indexed
        return parts

    def _frames_before(self, number: int, found: list[int]) -> int | None:
        """Recording frame number of part ``number``'s frame 0: the frames every device holds in
        the parts before it; None (with a warning) if one of them is absent or unreadable."""
        before = 0
        for n in range(number):
            try:
                if n not in found:
                    raise CaptureError(_cascade_paths(self.folder, n)[0][0], "part missing")
                before += min(read_cascade_index(p).num_idx
                              for p in _cascade_paths(self.folder, n)[1])
            except CaptureError as err:
                warnings.warn(f"{self.folder}: frames of part {number:04d} cannot be numbered "
                              f"within the recording ({err}); frame_numbers count from the "
                              "part's first frame", stacklevel=4)
                return None
        return before

    def _open_part(self, number: int, first_frame: int | None,
                   hint: str | None) -> CascadePart:
        """Check part ``number``'s 8 files; ``hint`` becomes the note of any error."""
        try:
            data_paths, idx_paths = _cascade_paths(self.folder, number)
            for p in data_paths + idx_paths:
                if not p.is_file():
                    raise CaptureError(p, "device file missing from the cascade capture",
                                       "no file", "all 8 files {master,slave1,slave2,slave3}_"
                                       f"{number:04d}_{{data,idx}}.bin")
            indices = [read_cascade_index(p) for p in idx_paths]
            counts = [self._validate(d, i) for d, i in zip(data_paths, indices)]
        except CaptureError as err:
            if hint is None:
                raise
            raise CaptureError(err.path, err.problem, err.found, err.expected, hint) from err
        shared = min(counts)
        if len(set(counts)) > 1:
            where = self.folder if number == 0 else f"{self.folder} part {number:04d}"
            warnings.warn(f"{where}: devices index different frame counts "
                          f"{dict(zip(CASCADE_DEVICES, counts))}; using the {shared} they share",
                          stacklevel=4)
        return CascadePart(number, tuple(data_paths), tuple(idx_paths), tuple(indices), shared,
                           first_frame)

    def _validate(self, data_path: Path, idx: CascadeIndex) -> int:
        """Check one device's data file against its index; return its frame count (0: empty)."""
        idx_path = idx.path
        fb, n, dfs = self.frame_bytes, idx.num_idx, idx.data_file_size
        profile = self._profile()
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
    def data_paths(self) -> list[Path]:
        """The 4 data files of the first part read (master, slave1, slave2, slave3)."""
        return list(self.parts[0].data_paths)

    @property
    def idx_paths(self) -> list[Path]:
        """The 4 index files of the first part read."""
        return list(self.parts[0].idx_paths)

    @property
    def frame_numbers(self) -> np.ndarray:
        """(n_frames,) int64 number of each frame read within the whole recording (0 = the
        first frame the capture wrote; the parts' frames counted in order). If an earlier part
        could not be counted (``part=N`` only, warned when opened), numbers count from the
        part's first frame."""
        p0 = self.parts[0]
        base = p0.first_frame if p0.first_frame is not None else 0
        return np.arange(self.first, self.first + self.n_frames, dtype=np.int64) + base

    @property
    def part_numbers(self) -> np.ndarray:
        """(n_frames,) int64 part NNNN each frame read comes from."""
        counts = np.diff(self._starts)
        numbers = np.repeat([p.number for p in self.parts], counts)
        return numbers[self.first:].astype(np.int64)

    @property
    def timestamps_ns(self) -> np.ndarray:
        """(n_frames,) uint64 index timestamps of the master device for the frames read."""
        ts = np.concatenate([p.indices[0].entries["timestamp"][:p.n_indexed]
                             for p in self.parts])
        return ts[self.first:].copy()

    def _memmaps(self, k: int) -> list[np.memmap]:
        """The 4 device memory maps of ``self.parts[k]``, opened on first use."""
        if k not in self._maps:
            p = self.parts[k]
            shape = (p.n_indexed, self.n_chirps, self.n_tx, self.n_samples, RX_PER_DEVICE, 2)
            self._maps[k] = [np.memmap(d, dtype="<i2", mode="r", shape=shape)
                             for d in p.data_paths]
        return self._maps[k]

    def read(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """complex64 (stop - start, chirps, tx, 16, samples) of frames [start, stop); frames of
        several parts are joined in order. ``IndexError`` outside [0, n_frames]."""
        start, stop = check_range(start, stop, self.n_frames)
        a, b = start + self.first, stop + self.first  # among the frames of all parts read
        out = np.empty((b - a, self.n_chirps, self.n_tx, CASCADE_N_RX, self.n_samples),
                       np.complex64)
        for k in range(len(self.parts)):  # one loop per file part
            p0, p1 = int(self._starts[k]), int(self._starts[k + 1])
            lo, hi = max(a, p0), min(b, p1)
            if lo >= hi:
                continue
            for d, mm in enumerate(self._memmaps(k)):
                rx = slice(d * RX_PER_DEVICE, (d + 1) * RX_PER_DEVICE)
                for f in range(lo, hi):  # one frame at a time bounds the float32 temporary
                    # (loop, chirp, sample, rx, iq) int16 -> complex64 (loop, chirp, sample, rx):
                    # a contiguous cast, then an 8-byte-element transpose (9x faster than 4-byte)
                    z = mm[f - p0].astype(np.float32).view(np.complex64)[..., 0]
                    out[f - a, :, :, rx] = z.transpose(0, 1, 3, 2)
        return out

    def frame(self, index: int) -> np.ndarray:
        """complex64 (chirps, tx, 16, samples) of one frame (negative index: from the end)."""
        i = check_frame_index(index, self.n_frames)
        return self.read(i, i + 1)[0]

    def close(self) -> None:
        self._maps = {}


def read_ti_cascade(folder: str | os.PathLike, n_samples: int, n_chirps: int, n_tx: int, *,
                    skip_first_frame: bool = True, part: int | None = None,
                    capture_index: int | None = None) -> np.ndarray:
    """Read a TI MMWCAS cascade recording, all its parts or one.

    Parameters
    ----------
    folder : holds ``{master,slave1,slave2,slave3}_NNNN_{data,idx}.bin``, NNNN the part.
    n_samples, n_chirps, n_tx : ADC samples per chirp, chirp loops per frame, chirps per loop.
    skip_first_frame : drop the recording's first frame (frame 0 of part 0000), as TI's own
        processing does; applied once, however many parts are read.
    part : None (default) reads every part 0000, 0001, ... in order as one recording (empty
        parts skipped with a warning); N reads part N alone.
    capture_index : alias of ``part`` (the name other MMWCAS readers use); ``TypeError`` if both
        are given.

    Returns
    -------
    complex64 (frames, n_chirps, n_tx, 16, n_samples); tx in firing order within a loop, rx in
    file order (master RX1-4, slave1 RX5-8, slave2 RX9-12, slave3 RX13-16).

    Raises
    ------
    CaptureError
        naming the file, the size found and the size expected: a missing folder, part or device
        file, a gap in the part numbers, an index that disagrees with its data, no frame left.
    """
    with contextlib.closing(TICascadeCapture(
            folder, n_samples, n_chirps, n_tx, skip_first_frame=skip_first_frame, part=part,
            capture_index=capture_index)) as cap:
        return cap.read()


def write_ti_cascade(folder: str | os.PathLike, cube: np.ndarray | Iterable[np.ndarray], *,
                     part: int = 0, timestamps: np.ndarray | None = None,
                     frame_period_s: float | None = None,
                     conversion: Int16Conversion = "exact") -> list[Path]:
    """Write a cube as a TI MMWCAS cascade capture (4 data + 4 index files) of part ``part``.

    A long recording is written as several parts, 0000, 0001, ..., one call each (timestamps
    continuing from part to part so that the reader can use them).

    cube : complex (frames, chirps, tx, 16, samples), or an iterable of (chirps, tx, 16, samples)
        frames (e.g. a frame source), written frame by frame.
    timestamps : (frames,) nanoseconds for the index entries; default ``f * frame_period_s`` if
        a period is given, else zeros.
    conversion : how values become int16 codes, see
        :func:`~blindspot.radar.capture.common.to_int16_iq` (default: they must be
        integers within int16 already, so the round trip is bit-exact).

    Files are written through :func:`blindspot.io.atomic_path` under temporary names and renamed
    into place only when all 8 are complete (index files last); on an error nothing is left.
    Raises ``ValueError`` for a frame of the wrong shape or no frame, :class:`CaptureError` for
    values ``conversion`` cannot turn into int16 codes. Returns the 8 paths written (data files,
    then index files).
    """
    data_paths, idx_paths = _cascade_paths(Path(folder), int(part))
    frame_shape: tuple[int, ...] | None = None
    # data files first, the index files (which readers trust) last; all 8 appear together
    with atomic_files(data_paths + idx_paths) as temps, contextlib.ExitStack() as files:
        # the 4 data files are written together so that an iterable of frames is consumed once
        fhs = [files.enter_context(open(tmp, "wb")) for tmp in temps[:len(data_paths)]]
        n_frames = 0
        for k, frame in enumerate(iter_frames_of(cube, 4)):
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
        if frame_shape is None:
            raise ValueError("cube holds no frame to write")
        n_chirps, n_tx, _, n_samples = frame_shape
        fb = cascade_frame_bytes(n_samples, n_chirps, n_tx)
        idx_bytes = _cascade_index_bytes(n_frames, fb, n_samples, n_chirps * n_tx, timestamps,
                                         frame_period_s)
        for tmp in temps[len(data_paths):]:
            tmp.write_bytes(idx_bytes)
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


# ---------------------------------------------------------------------------------- frame source
class TICascadeRecording(RecordingFrames):
    """A TI MMWCAS capture on disk as a frame source (frames read lazily, one at a time).

    radar : the capture's chirp profile: n_samples, n_chirps, n_tx and frame_period_s are read
        from it; n_rx must be 16 and adc_bits 16 (the MMWCAS stores 16-bit codes), else
        :class:`~blindspot.typed_config.ConfigError` naming the key; tx_order and the array keys
        shape ``array``.
    array : the virtual array; default ``array_for(radar)``.
    skip_first_frame, part, capture_index : as :func:`read_ti_cascade` (default: every part,
        joined in order, the recording's first frame skipped).
    times_s : index timestamps (ns, relative to the first frame read) when they increase and agree
        with ``radar.frame_period_s`` within 50 %; otherwise ``i * frame_period_s`` (with a
        warning if the timestamps were usable but disagreed).
    frame_numbers : (n_frames,) each frame's number within the whole recording.
    """

    def __init__(self, folder: str | os.PathLike, radar: RadarConfig, *,
                 array: VirtualArray | None = None, skip_first_frame: bool = True,
                 part: int | None = None, capture_index: int | None = None):
        if radar.n_rx != CASCADE_N_RX:
            raise ConfigError("radar.n_rx", radar.n_rx, f"{CASCADE_N_RX} (an MMWCAS capture holds "
                              f"{CASCADE_N_RX} RX, 4 per device; profile '{radar.name}')")
        check_adc_bits(radar.adc_bits, (16,), "MMWCAS")
        self.radar = radar
        self.array = array_for(radar) if array is None else array
        self.capture = TICascadeCapture(folder, radar.n_samples, radar.n_chirps, radar.n_tx,
                                        skip_first_frame=skip_first_frame,
                                        part=part, capture_index=capture_index)
        self._times = _frame_times(self.capture.timestamps_ns, radar.frame_period_s,
                                   self.capture.idx_paths[0])

    @property
    def times_s(self) -> np.ndarray:
        """(n_frames,) frame start times, s."""
        return self._times.copy()

    @property
    def frame_numbers(self) -> np.ndarray:
        """(n_frames,) int64 number of each frame within the whole recording."""
        return self.capture.frame_numbers


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
