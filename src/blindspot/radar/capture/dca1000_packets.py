"""DCA1000 packet-level recordings (``adc_data_Raw_0.bin``, ``adc_data_Raw_1.bin``, ...).

The DCA1000 CLI and mmWave Studio can store the UDP data packets as they arrive ("raw" record
files) instead of the headerless ADC stream of :mod:`.dca1000`. Framing, little-endian:

======  =====  ================================================================================
offset  bytes  field
======  =====  ================================================================================
0       4      sequence number (u32), 1 for the first packet, +1 per packet sent
4       6      byte count (u48): ADC bytes sent before this packet, i.e. the payload's offset in
               the ADC stream
10      P      payload: the next P bytes of the ADC stream (P = 1456 in a 1466-byte packet)
======  =====  ================================================================================

Sources: TI DCA1000EVM Data Capture Card user guide (SPRUIJ4), chapter "Data Format" (raw mode:
4-byte sequence number, 6-byte byte count, then the data; packets of 1466 bytes = 4 + 6 + 1456
as reported on TI's E2E forum, thread 754806); TI's DCA1000 CLI source (mmWave Studio 2.1,
``ReferenceCode/DCA1000/SourceCode``: ``u32CtPktNum`` from bytes 0-3,
``u64BytesSentTillCtPkt`` from bytes 4-9, data from byte 10, ``RECORD_DATA_BUF_INDEX 10``).
Public readers (OpenRadar's ``DCA1000``) parse the count as a 48-bit little-endian integer and
start a frame at the packet whose count is a multiple of the frame size, i.e. the count is the
offset of the payload, not of its end. The DCA1000 splits long records into files of about 1 GB;
the byte counts run on across them, so pass the files in order as a list.

Every payload is placed at its byte count, so a lost packet leaves a hole (zeros, flagged in the
``missing`` mask) instead of shifting every later frame; packets out of order are put in place;
duplicates (same byte count) keep the first copy. The stream is assumed to be carried in packets
of ``payload_bytes`` (every packet but possibly the last of a file: a cut record keeps the bytes
it has): byte counts must be multiples of it and agree with the sequence numbers
(``count = (seq - seq0) * payload_bytes``), else the file is not such a record and
:class:`CaptureError` names the first packet that disagrees.

Frames: frame f of the stream occupies stream bytes ``[f * F, (f + 1) * F)`` (F the frame size of
the profile, :func:`.dca1000.dca1000_frame_bytes`), laid out as in :mod:`.dca1000` (``layout``,
``adc_bits``). The frames read are those from the frame holding the first byte received to the
last frame the stream covers to its end (``first_frame`` is the stream number of frame 0); a
last frame that the stream does not reach the end of is not read, with a warning (the capture
was cut there or its last packets were lost; the byte counts cannot tell which). Lost packets
inside the frames read are reported with a warning (``strict=True``: :class:`CaptureError`), and
more than half of the span lost is an error (no usable capture, or not this format).
"""

from __future__ import annotations

import contextlib
import os
import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from blindspot.radar.capture.common import (
    CaptureError,
    Int16Conversion,
    atomic_files,
    check_adc_bits,
    check_dims,
    check_range,
)
from blindspot.radar.capture.dca1000 import (
    ADC_BITS_DCA,
    DCA1000_PAYLOAD_BYTES,
    DCA1000Recording,
    DcaLayout,
    _dca_file_shape,
    _dca_to_complex,
    _sign_compensate,
    dca1000_frame_bytes,
    encode_frames,
)
from blindspot.radar.source import check_frame_index

__all__ = [
    "PACKET_HEADER_BYTES",
    "DCA1000PacketCapture",
    "DCA1000PacketRecording",
    "PacketReport",
    "read_dca1000_packets",
    "write_dca1000_packets",
]

PACKET_HEADER_BYTES = 10  # u32 sequence number + u48 byte count


@dataclass(frozen=True)
class PacketReport:
    """What the packet headers of a raw record say.

    n_packets : records in the file(s); n_duplicates : records whose byte count came before
        (the first copy is used); n_out_of_order : records whose byte count is below one read
        earlier; n_lost : packets missing between the first and the last received.
    first_frame : stream number of the first frame read; n_frames : frames read.
    missing_bytes : (n_frames,) bytes of each frame read that never arrived.
    tail_bytes : bytes of the frame after the last one read that the stream holds (0: the
        stream ends on a frame boundary).
    """

    n_packets: int
    n_duplicates: int
    n_out_of_order: int
    n_lost: int
    first_frame: int
    n_frames: int
    missing_bytes: np.ndarray
    tail_bytes: int

    @property
    def damaged_frames(self) -> np.ndarray:
        """Indices (among the frames read) of frames with missing bytes."""
        return np.flatnonzero(self.missing_bytes)


def _as_paths(path: str | os.PathLike | Sequence[str | os.PathLike]) -> list[Path]:
    if isinstance(path, (str, os.PathLike)):
        return [Path(path)]
    paths = [Path(p) for p in path]
    if not paths:
        raise ValueError("no raw DCA1000 file given")
    return paths


class DCA1000PacketCapture:
    """An opened DCA1000 packet-level record (one file or the files of one record, in order).

    Parameters as :func:`read_dca1000_packets`. Attributes: ``n_frames``, ``first_frame``,
    ``report`` (:class:`PacketReport`), ``frame_bytes``, ``paths``.
    """

    def __init__(self, path: str | os.PathLike | Sequence[str | os.PathLike], n_samples: int,
                 n_chirps: int, n_tx: int, n_rx: int, *, layout: DcaLayout = "xwr16xx",
                 adc_bits: int | None = 16, payload_bytes: int = DCA1000_PAYLOAD_BYTES,
                 strict: bool = False):
        self.paths = _as_paths(path)
        self.n_samples, self.n_chirps, self.n_tx, self.n_rx = check_dims(
            n_samples=n_samples, n_chirps=n_chirps, n_tx=n_tx, n_rx=n_rx)
        self.layout, self.strict = layout, bool(strict)
        self.adc_bits = check_adc_bits(adc_bits, ADC_BITS_DCA, "DCA1000")
        _dca_file_shape(layout, self.n_samples, self.n_chirps, self.n_tx, self.n_rx)
        p = int(payload_bytes)
        if p < 2 or p % 2:
            raise ValueError(f"payload_bytes = {payload_bytes}: expected a positive even number "
                             f"of bytes (the DCA1000 sends {DCA1000_PAYLOAD_BYTES})")
        self.payload_bytes = p
        self.frame_bytes = dca1000_frame_bytes(self.n_samples, self.n_chirps, self.n_tx,
                                               self.n_rx)
        self._parse()
        self._maps: dict[int, np.memmap] = {}

    # ------------------------------------------------------------------------------ headers
    def _parse(self) -> None:
        """Read every header; sort the packets into stream order; check the framing."""
        p, rec = self.payload_bytes, PACKET_HEADER_BYTES + self.payload_bytes
        seq, count, length, file_no, rec_no = [], [], [], [], []
        self._tails: dict[int, int] = {}  # file -> payload bytes of its short last record
        for k, path in enumerate(self.paths):
            if not path.is_file():
                raise CaptureError(path, "DCA1000 raw capture file not found")
            size = path.stat().st_size
            n, tail = divmod(size, rec)
            if tail and tail <= PACKET_HEADER_BYTES:
                err = CaptureError(path, "file ends inside a packet header (a cut record)",
                                   f"{tail} trailing bytes", f"more than {PACKET_HEADER_BYTES}")
                if self.strict or n == 0:
                    raise err
                warnings.warn(f"{err}; the {tail} bytes are ignored", stacklevel=4)
            elif tail:
                self._tails[k] = (tail - PACKET_HEADER_BYTES) // 2 * 2
                n += 1
            if n == 0:
                raise CaptureError(path, "file holds no packet", f"{size} bytes",
                                   f"at least {PACKET_HEADER_BYTES + 2} bytes")
            head = np.zeros((n, 8), np.uint8)
            raw = np.memmap(path, np.uint8, mode="r", shape=(size,))
            full = (n - (k in self._tails)) * rec
            hdr = np.array(raw[:full].reshape(-1, rec)[:, :PACKET_HEADER_BYTES])
            if k in self._tails:
                hdr = np.concatenate([hdr, raw[full:full + PACKET_HEADER_BYTES][None]])
            del raw
            s4 = np.ascontiguousarray(hdr[:, :4]).view("<u4")[:, 0]
            head[:, :6] = hdr[:, 4:10]
            seq.append(s4.astype(np.int64))
            count.append(head.view("<u8")[:, 0].astype(np.int64))
            ln = np.full(n, p, np.int64)
            if k in self._tails:
                ln[-1] = self._tails[k]
            length.append(ln)
            file_no.append(np.full(n, k, np.int64))
            rec_no.append(np.arange(n, dtype=np.int64))
        seq_a, count_a = np.concatenate(seq), np.concatenate(count)
        length_a, file_a, rec_a = (np.concatenate(x) for x in (length, file_no, rec_no))
        bad = np.flatnonzero(count_a % p)
        if bad.size:
            self._framing_error(int(bad[0]), file_a, rec_a, "byte count is not a multiple of "
                                f"the {p}-byte payload", f"{int(count_a[bad[0]])}",
                                f"a multiple of {p}")
        slot = count_a // p
        offset = slot - seq_a
        bad = np.flatnonzero(offset != offset[0])
        if bad.size:
            k = int(bad[0])
            self._framing_error(k, file_a, rec_a, "sequence number and byte count disagree "
                                "(count = (seq - seq0) * payload)",
                                f"seq {int(seq_a[k])}, count {int(count_a[k])}",
                                f"count {int((seq_a[k] + offset[0]) * p)}")
        n_packets = slot.size
        out_of_order = int(np.count_nonzero(slot[1:] < np.maximum.accumulate(slot)[:-1]))
        uniq, first = np.unique(slot, return_index=True)  # stream order, first copy of each
        self._slot, self._file, self._rec = uniq, file_a[first], rec_a[first]
        self._len = length_a[first]
        start = uniq * p
        end = start + self._len
        self._cum = np.concatenate([[0], np.cumsum(self._len)])
        fb = self.frame_bytes
        first_byte, end_byte = int(start[0]), int(end.max())
        self.first_frame = first_byte // fb
        last = end_byte // fb
        self.n_frames = last - self.first_frame
        received = int(self._cum[-1])
        span = end_byte - first_byte
        n_lost = int(uniq[-1] - uniq[0] + 1 - uniq.size)
        where = (self.paths[0] if len(self.paths) == 1
                 else f"{self.paths[0]} (+{len(self.paths) - 1} files)")
        if 2 * received < span:
            raise CaptureError(where, "more than half of the stream between the first and the "
                               "last packet never arrived: not a DCA1000 raw record with "
                               f"{p}-byte packets, or too damaged to use",
                               f"{received} of {span} bytes", "most of them")
        if self.n_frames < 1:
            raise CaptureError(where, f"the packets cover no whole frame ({self._profile()})",
                               f"stream bytes [{first_byte}, {end_byte})",
                               f"a span of frame boundaries {fb} bytes apart")
        bounds = np.arange(self.first_frame, last + 2, dtype=np.int64) * fb
        covered = self._covered(bounds)
        got = np.diff(covered)
        missing = fb - got[:-1]
        tail = int(got[-1])
        self.report = PacketReport(n_packets, n_packets - uniq.size, out_of_order, n_lost,
                                   self.first_frame, self.n_frames, missing, tail)
        self._report(where)

    def _profile(self) -> str:
        return (f"{self.n_samples} samples x {self.n_chirps} loops x {self.n_tx} TX x "
                f"{self.n_rx} RX, {self.frame_bytes} bytes per frame")

    def _framing_error(self, k: int, file_a: np.ndarray, rec_a: np.ndarray, problem: str,
                       found: str, expected: str) -> None:
        path = self.paths[int(file_a[k])]
        raise CaptureError(path, f"packet {int(rec_a[k])}: {problem}", found, expected,
                           f"not a DCA1000 raw record (adc_data_Raw_N.bin) with "
                           f"{self.payload_bytes}-byte payloads; a headerless adc_data.bin is "
                           "read by read_dca1000")

    def _covered(self, x: np.ndarray) -> np.ndarray:
        """Bytes received in stream bytes [0, x) for each x (vectorised over the packets)."""
        start = self._slot * self.payload_bytes
        i = np.searchsorted(start, x, side="right") - 1
        ic = np.clip(i, 0, None)
        part = np.clip(x - start[ic], 0, self._len[ic])
        return np.where(i >= 0, self._cum[ic] + part, 0)

    def _report(self, where: str | Path) -> None:
        r, fb = self.report, self.frame_bytes
        if r.tail_bytes:
            msg = (f"{where}: the stream ends {r.tail_bytes} bytes into frame "
                   f"{self.first_frame + self.n_frames} ({fb} bytes per frame): a cut capture "
                   "or lost final packets (the byte counts cannot tell); that frame is not "
                   f"read, {self.n_frames} frames are")
            if self.strict:
                raise CaptureError(where, "stream ends inside a frame", f"{r.tail_bytes} bytes "
                                   f"of frame {self.first_frame + self.n_frames}",
                                   f"{fb} bytes", msg)
            warnings.warn(msg, stacklevel=4)
        damaged = r.damaged_frames
        if damaged.size:
            lost = int(r.missing_bytes.sum())
            err = CaptureError(where, f"{lost} bytes of {damaged.size} frame(s) never arrived "
                               f"({r.n_lost} packet(s) of {self.payload_bytes} bytes lost in the "
                               "stream)", f"frames {damaged.tolist()[:10]}"
                               + (" ..." if damaged.size > 10 else ""), "no missing bytes",
                               "the missing samples are zero in the cube and True in missing()")
            if self.strict:
                raise err
            warnings.warn(str(err), stacklevel=4)

    # ------------------------------------------------------------------------------ reading
    def _records(self, k: int) -> np.memmap:
        if k not in self._maps:
            rec = PACKET_HEADER_BYTES + self.payload_bytes
            n = self.paths[k].stat().st_size // rec
            self._maps[k] = np.memmap(self.paths[k], np.uint8, mode="r", shape=(n, rec))
        return self._maps[k]

    def _stream(self, start: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
        """int16 codes and a received mask (both (stop - start, frame_int16)) of frames
        [start, stop) of those read."""
        p, fb = self.payload_bytes, self.frame_bytes
        a, b = (self.first_frame + start) * fb, (self.first_frame + stop) * fb
        s0, s1 = a // p, -(-b // p)
        buf = np.zeros((s1 - s0, p), np.uint8)
        got = np.zeros(s1 - s0, np.int64)
        lo, hi = np.searchsorted(self._slot, [s0, s1])
        sel = np.arange(lo, hi)
        for k in np.unique(self._file[sel]):  # one gather per file of the record
            mine = sel[self._file[sel] == k]
            whole = mine[self._len[mine] == p]
            short = mine[self._len[mine] != p]
            if whole.size:
                buf[self._slot[whole] - s0] = self._records(k)[self._rec[whole],
                                                               PACKET_HEADER_BYTES:]
            for j in short:  # at most one short (last) record per file
                with open(self.paths[k], "rb") as fh:
                    fh.seek(int(self._rec[j]) * (PACKET_HEADER_BYTES + p) + PACKET_HEADER_BYTES)
                    data = np.frombuffer(fh.read(int(self._len[j])), np.uint8)
                buf[self._slot[j] - s0, :data.size] = data
        got[self._slot[sel] - s0] = self._len[sel]
        have = np.arange(p)[None, :] < got[:, None]
        off = a - s0 * p
        codes = buf.reshape(-1)[off:off + b - a].view("<i2").reshape(stop - start, -1)
        rec16 = have.reshape(-1)[off:off + b - a].reshape(-1, 2).all(axis=1)
        return codes, rec16.reshape(stop - start, -1)

    def read_masked(self, start: int = 0, stop: int | None = None) -> tuple[np.ndarray,
                                                                            np.ndarray]:
        """``(cube, missing)`` of frames [start, stop): complex64 and bool, both (frames, loops,
        tx, rx, samples); a sample is missing (and zero) if its I or Q never arrived."""
        start, stop = check_range(start, stop, self.n_frames)
        codes, have = self._stream(start, stop)
        path = self.paths[0]
        cube = _dca_to_complex(_sign_compensate(np.where(have, codes, 0).astype(np.int16),
                                                self.adc_bits, path), self.layout,
                               self.n_samples, self.n_chirps, self.n_tx, self.n_rx)
        gone = _dca_to_complex((~have).astype(np.int16), self.layout, self.n_samples,
                               self.n_chirps, self.n_tx, self.n_rx)
        missing = (gone.real != 0) | (gone.imag != 0)
        cube[missing] = 0
        return cube, missing

    def read(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """complex64 (stop - start, loops, tx, rx, samples); missing samples are zero."""
        return self.read_masked(start, stop)[0]

    def missing(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """bool (stop - start, loops, tx, rx, samples): True where a sample never arrived."""
        return self.read_masked(start, stop)[1]

    def frame(self, index: int) -> np.ndarray:
        """complex64 (loops, tx, rx, samples) of one frame (missing samples zero)."""
        i = check_frame_index(index, self.n_frames)
        return self.read(i, i + 1)[0]

    @property
    def frame_numbers(self) -> np.ndarray:
        """(n_frames,) int64 stream frame number of each frame read."""
        return np.arange(self.n_frames, dtype=np.int64) + self.first_frame

    def close(self) -> None:
        self._maps = {}


def read_dca1000_packets(path: str | os.PathLike | Sequence[str | os.PathLike], n_samples: int,
                         n_chirps: int, n_tx: int, n_rx: int, *,
                         layout: DcaLayout = "xwr16xx", adc_bits: int | None = 16,
                         payload_bytes: int = DCA1000_PAYLOAD_BYTES,
                         strict: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Read a DCA1000 packet-level record (``adc_data_Raw_0.bin``, or its files in order).

    Returns ``(cube, missing)``: complex64 and bool, both (frames, n_chirps, n_tx, n_rx,
    n_samples); samples whose bytes never arrived (lost packets) are zero in ``cube`` and True
    in ``missing``. Framing and frame selection: module docstring; ``layout`` and ``adc_bits``
    as :func:`~blindspot.radar.capture.dca1000.read_dca1000`.

    Warnings (``UserWarning``; each a :class:`CaptureError` with ``strict=True``): lost packets
    in the frames read; a stream that ends inside a frame (not read); a file cut inside a header.
    Errors: :class:`CaptureError` (file, found, expected) for a missing file, a file with no
    packet, byte counts that are not multiples of ``payload_bytes`` or disagree with the
    sequence numbers, more than half the span lost, no whole frame, codes outside ``adc_bits``;
    ``ValueError`` for a profile the layout cannot carry or a bad ``payload_bytes``;
    ``ConfigError`` for an unsupported ``adc_bits``.
    """
    with contextlib.closing(DCA1000PacketCapture(
            path, n_samples, n_chirps, n_tx, n_rx, layout=layout, adc_bits=adc_bits,
            payload_bytes=payload_bytes, strict=strict)) as cap:
        return cap.read_masked()


def write_dca1000_packets(path: str | os.PathLike, cube: np.ndarray | Iterable[np.ndarray], *,
                          layout: DcaLayout = "xwr16xx",
                          payload_bytes: int = DCA1000_PAYLOAD_BYTES,
                          order: np.ndarray | Sequence[int] | None = None,
                          first_seq: int = 1,
                          conversion: Int16Conversion = "exact") -> Path:
    """Write complex (frames, loops, tx, rx, samples) as a DCA1000 packet-level record, for tests.

    The ADC stream (as :func:`~blindspot.radar.capture.dca1000.write_dca1000` writes it) is cut
    into packets of ``payload_bytes`` (the last one shorter if the stream ends inside one),
    packet k with sequence number ``first_seq + k`` and byte count ``k * payload_bytes``.
    ``order`` lists the packets to store, in file order: leave some out to simulate lost
    packets, permute them for packets out of order, repeat one for a duplicate (default: all, in
    order). Written through :func:`blindspot.io.atomic_path`. Returns the path.
    """
    p = int(payload_bytes)
    if p < 2 or p % 2:
        raise ValueError(f"payload_bytes = {payload_bytes}: expected a positive even number")
    stream = np.concatenate([s.astype("<i2") for s in encode_frames(cube, layout, conversion)])
    data = stream.view(np.uint8)
    n = -(-data.size // p)
    padded = np.zeros(n * p, np.uint8)
    padded[:data.size] = data
    records = np.zeros((n, PACKET_HEADER_BYTES + p), np.uint8)
    records[:, :4] = (first_seq + np.arange(n, dtype=np.int64)).astype("<u4").view(
        np.uint8).reshape(n, 4)
    records[:, 4:10] = (np.arange(n, dtype=np.int64) * p).astype("<u8").view(
        np.uint8).reshape(n, 8)[:, :6]
    records[:, PACKET_HEADER_BYTES:] = padded.reshape(n, p)
    idx = np.arange(n) if order is None else np.asarray(order, dtype=np.int64)
    if idx.size and (idx.min() < 0 or idx.max() >= n):
        raise ValueError(f"order lists packets outside [0, {n})")
    last_len = data.size - (n - 1) * p
    path = Path(path)
    with atomic_files([path]) as (tmp,), open(tmp, "wb") as fh:
        for run in np.split(idx, np.flatnonzero(idx == n - 1) + 1):  # the short last packet
            body = records[run]
            if run.size and run[-1] == n - 1:
                fh.write(body[:-1].tobytes())
                fh.write(body[-1, :PACKET_HEADER_BYTES + last_len].tobytes())
            else:
                fh.write(body.tobytes())
    return path


class DCA1000PacketRecording(DCA1000Recording):
    """A DCA1000 packet-level record as a frame source (lazy; times from the stream frame
    numbers, ``frame_numbers * radar.frame_period_s``, so lost whole frames keep their time).

    path : the record's file, or its files in order.
    radar : the chirp profile (n_samples, n_chirps, n_tx, n_rx, adc_bits, frame_period_s).
    layout, strict, options : as :func:`read_dca1000_packets` (options: ``payload_bytes``).
    ``missing(i)`` : bool (loops, tx, rx, samples) of frame i.
    """

    _capture_class = DCA1000PacketCapture

    @property
    def times_s(self) -> np.ndarray:
        """(n_frames,) frame start times, s (frame 0 of the stream at 0)."""
        return self.capture.frame_numbers * self.radar.frame_period_s

    def missing(self, index: int) -> np.ndarray:
        """bool (loops, tx, rx, samples): samples of frame ``index`` that never arrived."""
        i = check_frame_index(index, self.n_frames)
        return self.capture.missing(i, i + 1)[0]
