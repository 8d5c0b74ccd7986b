"""RadHAR point clouds: text dumps of the TI ROS driver's ``PointCloud`` messages.

Format (``../shared/data/radar/README.md``, ``radhar-walk/``; Singh et al. 2019, "RadHAR: Human
Activity Recognition from Point Clouds Generated through a Millimeter-wave Radar", data set at
https://github.com/nesl/RadHAR): one YAML-like record per point, records separated by ``---``;
fields ``header.seq``, ``header.stamp.secs``/``nsecs``, ``header.frame_id``, ``point_id``
(restarts at 0 with each radar frame), ``x`` (forward, m), ``y`` (left, m), ``z`` (m), ``range``
(m), ``velocity`` (m/s), ``doppler_bin``, ``bearing`` (deg), ``intensity`` (dB).

Coordinates are kept in the recording's own sensor frame (ROS: x forward, y left), as the
recording's tracks are reported in it.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pandas as pd

from blindspot.radar.capture.common import CaptureError

__all__ = ["RADHAR_FIELDS", "read_radhar"]

#: Field names in record order, and the column each becomes.
RADHAR_FIELDS = {"seq": "seq", "secs": "stamp_secs", "nsecs": "stamp_nsecs",
                 "point_id": "point_id", "x": "x_m", "y": "y_m", "z": "z_m", "range": "range_m",
                 "velocity": "velocity_mps", "doppler_bin": "doppler_bin",
                 "bearing": "bearing_deg", "intensity": "intensity_db"}
_INTEGER = {"seq", "secs", "nsecs", "point_id", "doppler_bin"}


def _first_bad_record(records: list[str], field: str) -> int:
    pattern = re.compile(rf"^\s*{field}:\s*\S+\s*$", re.M)
    return next(i for i, rec in enumerate(records) if not pattern.search(rec))


def read_radhar(path: str | os.PathLike) -> pd.DataFrame:
    """Read one RadHAR ``.txt`` point-cloud dump.

    Every field is pulled out of the whole text with one regular expression (no loop per
    point); a record missing a field (a cut or garbled file) is found and named only then.

    Args:
        path: the ``.txt`` file.

    Returns:
        DataFrame, one row per point: ``frame`` (int, 0, 1, ...: a new frame where
        ``point_id`` restarts at 0), ``time_s`` (s since the file's first frame, from the ROS
        stamp of each frame's first point), ``point_id``, ``x_m`` (forward), ``y_m`` (left),
        ``z_m``, ``range_m``, ``velocity_mps``, ``doppler_bin``, ``bearing_deg``,
        ``intensity_db``, ``seq``.

    Raises:
        CaptureError: the file is missing or holds no record; a record lacks a field (the
            message names the record, counted from 1, and the field: e.g. a file cut in the
            middle of its last record); a value is not a number; point ids do not count up
            within a frame; a frame's time stamp goes backwards.
    """
    path = Path(path)
    if not path.is_file():
        raise CaptureError(path, "RadHAR point-cloud file not found")
    text = path.read_text(errors="replace")
    records = [r for r in re.split(r"^---\s*$", text, flags=re.M) if r.strip()]
    if not records:
        raise CaptureError(path, "no point record", found="0 records",
                           expected="records separated by '---'")
    n = len(records)
    cols = {}
    for field, column in RADHAR_FIELDS.items():
        values = re.findall(rf"^\s*{field}:\s*(\S+)\s*$", text, flags=re.M)
        if len(values) != n:
            bad = _first_bad_record(records, field)
            raise CaptureError(path, f"record {bad + 1} of {n} has no '{field}' field (cut or "
                               "garbled file)", found=f"{len(values)} '{field}' values",
                               expected=f"{n}, one per record")
        try:
            arr = np.asarray(values, dtype=np.float64)
        except ValueError:
            bad = next(v for v in values if not re.fullmatch(r"[-+.\deE]+|nan|inf", v))
            raise CaptureError(path, f"field '{field}' holds a value that is not a number",
                               found=repr(bad), expected="a decimal number") from None
        if not np.isfinite(arr).all():
            raise CaptureError(path, f"field '{field}' holds NaN or infinite values",
                               found=int((~np.isfinite(arr)).sum()), expected=0)
        cols[column] = arr.astype(np.int64) if field in _INTEGER else arr
    df = pd.DataFrame(cols)
    start = df.point_id.to_numpy() == 0
    if not start[0]:
        raise CaptureError(path, "the first record does not start a frame",
                           found=f"point_id {df.point_id.iloc[0]}", expected="point_id 0")
    frame = np.cumsum(start) - 1
    ids = df.point_id.to_numpy()
    # ids rise within a frame; the driver skips some (e.g. 0..14, 16, 17, 19 in radhar-walk)
    wrong = np.flatnonzero(~start[1:] & (ids[1:] <= ids[:-1])) + 1
    if len(wrong):
        i = wrong[0]
        raise CaptureError(path, f"point ids do not rise within frame {frame[i]} (record "
                           f"{i + 1})", found=int(ids[i]), expected=f"> {int(ids[i - 1])}")
    stamp = df.stamp_secs.to_numpy() + 1e-9 * df.stamp_nsecs.to_numpy()
    frame_stamp = stamp[start]
    back = np.flatnonzero(np.diff(frame_stamp) < 0)
    if len(back):
        raise CaptureError(path, f"time stamp of frame {back[0] + 1} is before frame {back[0]}'s",
                           found=f"{frame_stamp[back[0] + 1]:.6f} s",
                           expected=f">= {frame_stamp[back[0]]:.6f} s")
    df.insert(0, "time_s", (frame_stamp - frame_stamp[0])[frame])
    df.insert(0, "frame", frame.astype(np.int64))
    return df.drop(columns=["stamp_secs", "stamp_nsecs"])[
        ["frame", "time_s", "point_id", "x_m", "y_m", "z_m", "range_m", "velocity_mps",
         "doppler_bin", "bearing_deg", "intensity_db", "seq"]]
