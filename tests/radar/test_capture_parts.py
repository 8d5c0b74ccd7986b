"""Multi-part MMWCAS recordings: TI's capture splits a long recording into parts
``master_0000_data.bin``, ``master_0001_data.bin``, ... (each with its slave and index files).

The folder is built with the project's own cascade writer, one call per part; the empty part is
written byte by byte from the index format (a 24-byte header with numIdx 0, empty data files), as
the capture leaves it when it stops right after opening a new part.
"""

from __future__ import annotations

import os
import struct
import warnings

import numpy as np
import pytest

from blindspot.radar.capture import (
    CaptureError,
    TICascadeCapture,
    TICascadeRecording,
    open_recording,
    read_ti_cascade,
    write_ti_cascade,
)
from blindspot.radar.source import FrameSource
from tests.radar.test_capture import DEVICES, C, L, S, random_codes, small_profile

PERIOD_NS = 100_000_000  # the small profile's frame_period_s = 0.1 s
FB = S * C * L * 16  # bytes of one frame in one device file


def write_empty_part(folder, part: int) -> None:
    for d in DEVICES:
        (folder / f"{d}_{part:04d}_data.bin").write_bytes(b"")
        (folder / f"{d}_{part:04d}_idx.bin").write_bytes(struct.pack("<IIIIQ", 0, 1, 0, 0, 0))


@pytest.fixture
def recording(tmp_path):
    """Parts 0000 (frames 0-3), 0001 (frames 4-6) and an empty 0002; index timestamps continue
    from part to part."""
    cube = random_codes(np.random.default_rng(7), (7, L, C, 16, S))
    ts = np.arange(7) * PERIOD_NS + 10**12
    write_ti_cascade(tmp_path, cube[:4], part=0, timestamps=ts[:4])
    write_ti_cascade(tmp_path, cube[4:], part=1, timestamps=ts[4:])
    write_empty_part(tmp_path, 2)
    return tmp_path, cube


def test_all_parts_read_in_order_as_one_recording(recording):
    folder, cube = recording
    with pytest.warns(UserWarning, match=r"master_0002_idx.bin: part 0002 .*no frame.*skipped"):
        cap = TICascadeCapture(folder, S, L, C)
    # the first frame is skipped once, for the recording, not once per part
    assert cap.n_frames == 6 and np.array_equal(cap.read(), cube[1:])
    assert cap.frame_numbers.tolist() == [1, 2, 3, 4, 5, 6]
    assert cap.part_numbers.tolist() == [0, 0, 0, 1, 1, 1]
    assert [p.number for p in cap.parts] == [0, 1] and cap.skipped_parts == (2,)
    # frames across the part boundary, one at a time and as a range
    assert np.array_equal(cap.read(2, 5), cube[3:6])
    assert np.array_equal(cap.frame(3), cube[4]) and np.array_equal(cap.frame(-1), cube[6])
    with pytest.raises(IndexError):
        cap.frame(6)
    with pytest.warns(UserWarning, match="part 0002"):
        out = read_ti_cascade(folder, S, L, C, skip_first_frame=False)
    assert np.array_equal(out, cube)


def test_recording_source_spans_the_parts(recording):
    folder, cube = recording
    with pytest.warns(UserWarning, match="part 0002"):
        src = TICascadeRecording(folder, small_profile())
    assert isinstance(src, FrameSource) and len(src) == 6
    assert np.array_equal(np.stack(list(src)), cube[1:])
    # timestamps continue across the parts, so the index timing is used end to end
    np.testing.assert_allclose(src.times_s, np.arange(6) * 0.1, atol=1e-9)
    assert src.frame_numbers.tolist() == [1, 2, 3, 4, 5, 6]


def test_one_part_selected_explicitly(recording):
    folder, cube = recording
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the other parts are counted, not read: no warning
        first = TICascadeCapture(folder, S, L, C, part=0)
        second = TICascadeCapture(folder, S, L, C, part=1)
        src = open_recording("ti_cascade", folder, small_profile(), part=1)
    # part 0000 holds the recording's first frame: skipped; part 0001's frames are all kept
    assert np.array_equal(first.read(), cube[1:4]) and first.frame_numbers.tolist() == [1, 2, 3]
    assert np.array_equal(second.read(), cube[4:]) and second.frame_numbers.tolist() == [4, 5, 6]
    assert isinstance(src, TICascadeRecording) and np.array_equal(src.frame(0), cube[4])
    assert src.frame_numbers.tolist() == [4, 5, 6]
    with pytest.raises(CaptureError, match=r"master_0002_data.bin: capture holds no whole frame"
                       rf".*found 0 bytes, 0 indexed, expected at least {FB} bytes"):
        read_ti_cascade(folder, S, L, C, part=2)


def test_first_frame_skipped_in_the_first_part_that_holds_frames(tmp_path):
    cube = random_codes(np.random.default_rng(8), (3, L, C, 16, S))
    write_empty_part(tmp_path, 0)
    write_ti_cascade(tmp_path, cube, part=1)
    with pytest.warns(UserWarning, match="part 0000"):
        cap = TICascadeCapture(tmp_path, S, L, C)
    assert np.array_equal(cap.read(), cube[1:]) and cap.frame_numbers.tolist() == [1, 2]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.array_equal(read_ti_cascade(tmp_path, S, L, C, part=1), cube[1:])


def test_every_part_empty(tmp_path):
    write_empty_part(tmp_path, 0)
    write_empty_part(tmp_path, 1)
    with pytest.raises(CaptureError, match=r"master_0000_data.bin: capture holds no whole frame"):
        read_ti_cascade(tmp_path, S, L, C)


def test_bad_part_names_the_file_the_sizes_and_the_part(recording):
    folder, cube = recording
    path = folder / "slave1_0001_data.bin"
    os.truncate(path, 3 * FB - 10)
    with pytest.raises(CaptureError) as err:
        read_ti_cascade(folder, S, L, C)
    msg = str(err.value)
    assert str(path) in msg and f"found {3 * FB - 10} bytes" in msg
    assert f"expected at least {3 * FB} bytes" in msg
    assert msg.endswith("; in part 0001 of the recording's parts 0000, 0001, 0002 (pass part=N "
                        "to read another part alone)")
    assert err.value.path == path and err.value.found == f"{3 * FB - 10} bytes"
    # the good part is still readable on its own
    assert np.array_equal(read_ti_cascade(folder, S, L, C, part=0), cube[1:4])
    write_ti_cascade(folder, cube[4:], part=1)
    # a device file of the empty part missing: that part is broken, not empty
    (folder / "slave2_0002_idx.bin").unlink()
    with pytest.raises(CaptureError,
                       match=r"slave2_0002_idx.bin: device file missing.*; in part 0002"):
        read_ti_cascade(folder, S, L, C)


def test_a_part_whose_devices_disagree_warns_with_the_part(recording):
    folder, cube = recording
    path = folder / "slave3_0001_idx.bin"
    raw = path.read_bytes()
    path.write_bytes(struct.pack("<IIIIQ", 0, 1, 0, 2, 2 * FB) + raw[24:24 + 48 * 2])
    with pytest.warns(UserWarning) as record:
        cap = TICascadeCapture(folder, S, L, C)
    messages = [str(w.message) for w in record]
    assert any("part 0001: devices index different frame counts" in m and "'slave3': 2" in m
               for m in messages)
    assert np.array_equal(cap.read(), cube[1:6]) and cap.frame_numbers.tolist() == [1, 2, 3, 4, 5]
