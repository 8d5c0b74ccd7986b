"""Readers of real point-cloud logs nobody here wrote: TI's people-counting TLV log with its
gtrack targets, and RadHAR's ROS text dumps (../shared/data/radar/README.md), and the errors they
raise on broken copies made in tmp_path."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from blindspot.radar.capture import CaptureError
from blindspot.radar.capture.radhar import read_radhar
from blindspot.radar.capture.ti_gtrack import read_ti_gtrack

pytestmark = pytest.mark.real_data


@pytest.fixture(scope="module")
def gtrack_path(shared_dir):
    return shared_dir / "data" / "radar" / "ti-gtrack-people" / "fHistScene4_2d_0001.bin"


@pytest.fixture(scope="module")
def radhar_path(shared_dir):
    return shared_dir / "data" / "radar" / "radhar-walk" / "test_walk_20_walk_6.txt"


def test_gtrack_log_matches_its_documentation(gtrack_path):
    log = read_ti_gtrack(gtrack_path, frame_period_s=0.05)
    # the README's counts: 400 frames, 9,876 points (max 56 per frame), ids 0-3 first seen at
    # frames 21, 57, 87, 197 and never lost before the end
    assert len(log.frames) == 400 and (log.frames == np.arange(1, 401)).all()
    assert len(log.points) == 9876 and log.points.groupby("frame").size().max() == 56
    first = log.targets.groupby("track_id").frame.agg(["min", "max"])
    assert first["min"].tolist() == [21, 57, 87, 197] and (first["max"] == 400).all()
    assert (log.points.doppler_mps != 0).all()  # static clutter removed on the sensor
    # the points lie on TI's tracks: median distance to the nearest target ~0.13 m (README)
    p = log.points.merge(log.targets, on="frame", suffixes=("", "_t"))
    d = np.hypot(p.x_m - p.x_m_t, p.y_m - p.y_m_t).groupby([p.frame, p.range_m, p.azimuth_rad]).min()
    assert 0.10 < d.median() < 0.16 and (d < 1.0).mean() > 0.98
    # geometry: x = r sin(az), y = r cos(az)
    np.testing.assert_allclose(np.hypot(log.points.x_m, log.points.y_m), log.points.range_m,
                               rtol=1e-6)
    assert log.points.time_s.iloc[0] == pytest.approx((log.points.frame.iloc[0] - 1) * 0.05)


def test_gtrack_broken_copies_are_named(gtrack_path, tmp_path):
    data = gtrack_path.read_bytes()
    cut = tmp_path / "cut.bin"
    cut.write_bytes(data[:-5])
    with pytest.raises(CaptureError, match=r"cut.bin: cut TLV payload .* in frame 400"):
        read_ti_gtrack(cut, 0.05)
    garbled = bytearray(data)
    garbled[0:4] = struct.pack("<I", 7)  # frame 1 claims to be 7: frame 2 no longer follows
    bad = tmp_path / "garbled.bin"
    bad.write_bytes(bytes(garbled))
    with pytest.raises(CaptureError, match=r"garbled.bin: frame number at byte \d+ does not "
                                           r"follow .* \(found 2, expected 8\)"):
        read_ti_gtrack(bad, 0.05)
    header = tmp_path / "header.bin"
    header.write_bytes(data[:3])
    with pytest.raises(CaptureError, match=r"cut frame header .* \(found 3 bytes"):
        read_ti_gtrack(header, 0.05)
    empty = tmp_path / "empty.bin"
    empty.write_bytes(b"")
    with pytest.raises(CaptureError, match="empty file"):
        read_ti_gtrack(empty, 0.05)
    odd = tmp_path / "odd.bin"  # one frame whose points TLV is 20 bytes long
    odd.write_bytes(struct.pack("<IIII", 1, 1, 6, 20) + bytes(20))
    with pytest.raises(CaptureError, match=r"TLV type 6 length in frame 1 \(found 20, expected "
                                           r"a multiple of 16"):
        read_ti_gtrack(odd, 0.05)
    with pytest.raises(CaptureError, match="not found"):
        read_ti_gtrack(tmp_path / "missing.bin", 0.05)


def test_radhar_walk_matches_its_documentation(radhar_path):
    pts = read_radhar(radhar_path)
    # README: about 603 frames (20 s, ~30 frames/s), 15-33 points per frame, ~9 in 10 static
    assert pts.frame.nunique() == 603
    per_frame = pts.groupby("frame").size()
    assert per_frame.min() == 15 and per_frame.max() == 33
    assert 0.85 < (pts.velocity_mps == 0).mean() < 0.93
    assert pts.time_s.max() == pytest.approx(20.0, abs=0.2)
    rate = (pts.frame.nunique() - 1) / pts.time_s.max()
    assert 28 < rate < 32
    # the bearing is the point's own, atan2(y, x) in the ROS frame (x forward, y left)
    np.testing.assert_allclose(np.degrees(np.arctan2(pts.y_m, pts.x_m)), pts.bearing_deg,
                               atol=1e-4)


def test_radhar_broken_copies_are_named(radhar_path, tmp_path):
    lines = radhar_path.read_text().splitlines(keepends=True)[:1600]
    good = "".join(lines[: max(i for i, l in enumerate(lines) if l.startswith("---")) + 1])
    cut = tmp_path / "cut.txt"
    cut.write_text(good + "".join(lines[len(good.splitlines()):][:6]))
    with pytest.raises(CaptureError, match=r"cut.txt: record \d+ of \d+ has no 'point_id' field"):
        read_radhar(cut)
    bad = tmp_path / "bad.txt"
    bad.write_text(good.replace("velocity: 0.0", "velocity: O.0", 1))
    with pytest.raises(CaptureError, match=r"bad.txt: field 'velocity' .* not a number .*'O.0'"):
        read_radhar(bad)
    swapped = tmp_path / "swapped.txt"
    swapped.write_text(good.replace("point_id: 3\n", "point_id: 1\n", 1))
    with pytest.raises(CaptureError, match=r"point ids do not rise within frame 0"):
        read_radhar(swapped)
    empty = tmp_path / "empty.txt"
    empty.write_text("---\n")
    with pytest.raises(CaptureError, match="no point record"):
        read_radhar(empty)
