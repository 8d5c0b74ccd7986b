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
"""

from __future__ import annotations

import contextlib
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
    check_dims,
    check_range,
    iter_frames_of,
    to_int16_iq,
)
from blindspot.radar.config import RadarConfig
from blindspot.radar.source import RecordingFrames, check_frame_index

__all__ = [
    "CASCADE_DEVICES",
    "CASCADE_N_RX",
    "IDX_HEADER_DTYPE",
    "IDX_ENTRY_DTYPE",
    "CascadeIndex",
    "TICascadeCapture",
    "TICascadeRecording",
    "cascade_frame_bytes",
    "find_cascade_captures",
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

_CAPTURE_RE = re.compile(r"^master_(\d+)_data\.bin$")


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
        self.n_samples, self.n_chirps, self.n_tx = check_dims(n_samples=n_samples,
                                                              n_chirps=n_chirps, n_tx=n_tx)
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
        start, stop = check_range(start, stop, self.n_frames)
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
        i = check_frame_index(index, self.n_frames)
        return self.read(i, i + 1)[0]

    def close(self) -> None:
        self._maps = None


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
    conversion : how values become int16 codes, see
        :func:`~blindspot.radar.capture.common.to_int16_iq` (default: they must be
        integers within int16 already, so the round trip is bit-exact).

    Files are written through :func:`blindspot.io.atomic_path` under temporary names and renamed
    into place only when all 8 are complete (index files last); on an error nothing is left.
    Raises ``ValueError`` for a frame of the wrong shape or no frame, :class:`CaptureError` for
    values ``conversion`` cannot turn into int16 codes. Returns the 8 paths written (data files,
    then index files).
    """
    data_paths, idx_paths = _cascade_paths(Path(folder), int(capture_index))
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
