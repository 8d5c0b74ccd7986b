"""TI people-counting logs: point clouds and TI's gtrack targets per frame (TLV binary).

Format (``../shared/data/radar/README.md``, ``ti-gtrack-people/``; TI's gtrack test vectors):
little-endian, no file header; each frame is ``u32 frame_number`` (1, 2, ...), ``u32 n_tlv``,
then ``n_tlv`` blocks of ``u32 type``, ``u32 length_bytes`` (payload only) and the payload.
Type 6: points, ``float32[n, 4]`` = range (m), azimuth (rad), Doppler (m/s, positive = moving
away), SNR (linear). Type 7: gtrack targets, per target ``u32 track_id`` + ``float32[6]`` = x, y
(m), vx, vy (m/s), ax, ay (m/s^2). Other types are skipped by their length. Geometry: x = range
sin(azimuth), y = range cos(azimuth) (the project's convention: boresight +y, x to the right).
"""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from blindspot.radar.capture.common import CaptureError

__all__ = ["GtrackLog", "POINTS_TLV", "TARGETS_TLV", "read_ti_gtrack"]

POINTS_TLV = 6
TARGETS_TLV = 7
_POINT = np.dtype([("range_m", "<f4"), ("azimuth_rad", "<f4"), ("doppler_mps", "<f4"),
                   ("snr", "<f4")])
_TARGET = np.dtype([("track_id", "<u4"), ("x_m", "<f4"), ("y_m", "<f4"), ("vx_mps", "<f4"),
                    ("vy_mps", "<f4"), ("ax_mps2", "<f4"), ("ay_mps2", "<f4")])
_MAX_TLV = 64  # far more TLV blocks than TI's demos send per frame: a larger count is garbage


@dataclass(frozen=True)
class GtrackLog:
    """One TI people-counting log.

    Attributes:
        points: one row per point: ``frame`` (int, the file's frame number), ``time_s``
            ((frame - first frame) x frame period), ``range_m``, ``azimuth_rad``,
            ``doppler_mps``, ``snr`` (linear), ``x_m``, ``y_m`` (m).
        targets: one row per TI gtrack target per frame: ``frame``, ``time_s``, ``track_id``,
            ``x_m``, ``y_m``, ``vx_mps``, ``vy_mps``, ``ax_mps2``, ``ay_mps2``.
        frames: (n_frames,) int64 frame numbers in the file, with or without points.
        frame_period_s: the period used for ``time_s``.
    """

    points: pd.DataFrame
    targets: pd.DataFrame
    frames: np.ndarray
    frame_period_s: float


def read_ti_gtrack(path: str | os.PathLike, frame_period_s: float) -> GtrackLog:
    """Read a TI people-counting TLV log (``fHistScene*_2d_*.bin``).

    Args:
        path: the ``.bin`` file.
        frame_period_s: the frame period (s; TI's replay program uses 0.05 for the test vectors,
            the file holds no timestamps).

    Returns:
        :class:`GtrackLog`.

    Raises:
        CaptureError: the file is missing or empty; a frame header, a TLV header or a payload
            runs past the end of the file (a cut log: the message gives the frame, the offset,
            the bytes left and the bytes needed); a frame number is not the previous one + 1;
            a TLV count above 64; a points/targets payload whose length is not a whole number
            of 16-/28-byte records.
        ValueError: ``frame_period_s`` not positive.
    """
    path = Path(path)
    if not frame_period_s > 0:
        raise ValueError(f"read_ti_gtrack: frame_period_s must be positive; found {frame_period_s}")
    if not path.is_file():
        raise CaptureError(path, "TI gtrack log not found")
    data = path.read_bytes()
    if not data:
        raise CaptureError(path, "empty file", found="0 bytes", expected="at least one frame")
    size = len(data)
    off, frames, pts, tgts = 0, [], [], []
    # One header per frame and per TLV block (variable lengths); the points and targets of a
    # block are decoded as whole arrays.
    while off < size:
        if size - off < 8:
            raise CaptureError(path, f"cut frame header after frame {frames[-1] if frames else None}"
                               f" at byte {off}", found=f"{size - off} bytes",
                               expected="8 (u32 frame number, u32 TLV count)")
        number, n_tlv = struct.unpack_from("<II", data, off)
        expected_number = frames[-1] + 1 if frames else number
        if number != expected_number or number == 0:
            raise CaptureError(path, f"frame number at byte {off} does not follow the previous "
                               "frame (garbled or not a gtrack log)", found=number,
                               expected=expected_number if frames else ">= 1")
        if n_tlv > _MAX_TLV:
            raise CaptureError(path, f"TLV count of frame {number} at byte {off}", found=n_tlv,
                               expected=f"at most {_MAX_TLV}")
        off += 8
        for _ in range(n_tlv):
            if size - off < 8:
                raise CaptureError(path, f"cut TLV header in frame {number} at byte {off}",
                                   found=f"{size - off} bytes", expected="8")
            kind, length = struct.unpack_from("<II", data, off)
            off += 8
            if size - off < length:
                raise CaptureError(path, f"cut TLV payload (type {kind}) in frame {number} at "
                                   f"byte {off}", found=f"{size - off} bytes",
                                   expected=f"{length} bytes")
            for want, dtype, sink in ((POINTS_TLV, _POINT, pts), (TARGETS_TLV, _TARGET, tgts)):
                if kind == want:
                    if length % dtype.itemsize:
                        raise CaptureError(path, f"TLV type {kind} length in frame {number}",
                                           found=length,
                                           expected=f"a multiple of {dtype.itemsize} bytes")
                    rec = np.frombuffer(data, dtype, length // dtype.itemsize, off)
                    sink.append((number, rec))
            off += length
        frames.append(number)
    frames_arr = np.asarray(frames, np.int64)
    first = frames_arr[0]

    def table(parts, dtype):
        if parts:
            rec = np.concatenate([r for _, r in parts])
            fr = np.repeat([f for f, _ in parts], [len(r) for _, r in parts]).astype(np.int64)
        else:
            rec, fr = np.empty(0, dtype), np.empty(0, np.int64)
        df = pd.DataFrame({name: rec[name].astype(np.float64 if rec.dtype[name].kind == "f"
                                                  else np.int64) for name in dtype.names})
        df.insert(0, "time_s", (fr - first) * frame_period_s)
        df.insert(0, "frame", fr)
        return df

    points = table(pts, _POINT)
    points["x_m"] = points.range_m * np.sin(points.azimuth_rad)
    points["y_m"] = points.range_m * np.cos(points.azimuth_rad)
    for name, df in (("points", points), ("targets", table(tgts, _TARGET))):
        values = df.select_dtypes("float").to_numpy()
        if not np.isfinite(values).all():
            raise CaptureError(path, f"non-finite values in the {name}",
                               found=f"{int((~np.isfinite(values)).sum())} NaN/inf",
                               expected="finite float32")
    return GtrackLog(points, table(tgts, _TARGET), frames_arr, float(frame_period_s))
