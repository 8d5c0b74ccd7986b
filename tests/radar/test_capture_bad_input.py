"""Bad DCA1000 and MMWCAS inputs (issue 9; handed cases c02, c03, c10 of shared/cases/bad-input).

Inputs are rebuilt here from the situations the cases describe: each RX of a DCA1000 frame carries
its own tone (bin 3 + 4 rx of 64), so a misaligned read shows as tones in the wrong bins.
"""

from __future__ import annotations

import struct
import warnings

import numpy as np
import pytest

from blindspot.radar.capture import (
    DCA1000_PAYLOAD_BYTES,
    CaptureError,
    DCA1000Capture,
    DCA1000PacketCapture,
    find_cascade_captures,
    read_dca1000,
    read_dca1000_packets,
    read_ti_cascade,
    write_dca1000,
    write_dca1000_packets,
    write_ti_cascade,
)
from blindspot.radar.capture.dca1000 import _dca_to_complex

L, T, R, S = 16, 2, 4, 64  # loops, TX, RX, samples: 32768-byte frames
FRAME = L * T * R * S * 4


def tone_cube(n_frames: int) -> np.ndarray:
    """complex64 (frames, L, T, R, S) int16 codes: RX r a tone at bin 3 + 4 r."""
    n = np.arange(S)
    tones = np.rint(1000 * np.exp(2j * np.pi * (3 + 4 * np.arange(R))[:, None] * n / S))
    return np.broadcast_to(tones, (n_frames, L, T, R, S)).astype(np.complex64)


def tones_right(cube: np.ndarray) -> np.ndarray:
    """(frames,) share of chirps with every RX's tone at its bin."""
    peak = np.abs(np.fft.fft(cube, axis=-1)).argmax(-1)
    return (peak == 3 + 4 * np.arange(R)).mean(axis=(1, 2, 3))


def caught(fn):
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        out = fn()
    return out, [str(x.message) for x in w]


# ---------------------------------------------------------------------------------- c02
def test_c02_zero_padding_at_either_end_is_found_not_read_as_frames(tmp_path):
    """Xiangyu-Gao/mmWave-radar-signal-processing-and-microDoppler-classification #5: 3 frames
    and 7,012 zero bytes at the end, then the same zeros at the start."""
    good = tone_cube(3)
    write_dca1000(tmp_path / "frames.bin", good)
    frames, pad = (tmp_path / "frames.bin").read_bytes(), bytes(7012)
    (tmp_path / "pad_end.bin").write_bytes(frames + pad)
    (tmp_path / "pad_begin.bin").write_bytes(pad + frames)

    cube, msgs = caught(lambda: read_dca1000(tmp_path / "pad_end.bin", S, L, T, R))
    assert np.array_equal(cube, good)
    assert len(msgs) == 1 and "dropped" not in msgs[0]
    assert "zero padding at the end: the last 7012 bytes are exact zeros" in msgs[0]

    cube, msgs = caught(lambda: read_dca1000(tmp_path / "pad_begin.bin", S, L, T, R))
    assert np.array_equal(cube, good) and tones_right(cube).tolist() == [1, 1, 1]
    assert len(msgs) == 1 and "begins with 7012 zero bytes; the first 7012 were skipped" in msgs[0]
    # read from byte 0 on request: every frame shifted, and still warned
    cube, msgs = caught(lambda: read_dca1000(tmp_path / "pad_begin.bin", S, L, T, R,
                                             skip_bytes=0))
    assert tones_right(cube).max() == 0 and "not a whole number of frames" in msgs[0]
    for name in ("pad_end.bin", "pad_begin.bin"):
        with pytest.raises(CaptureError, match=r"not a whole number of frames.*found 105316 "
                           r"bytes.*zero padding"):
            read_dca1000(tmp_path / name, S, L, T, R, strict=True)


# ---------------------------------------------------------------------------------- c03
def test_c03_lost_packet_in_a_headerless_file_is_named_as_a_possible_cause(tmp_path):
    """PreSenseRadar/OpenRadar #56: one 1456-byte payload missing inside frame 1 of 4."""
    write_dca1000(tmp_path / "whole.bin", tone_cube(4))
    raw = (tmp_path / "whole.bin").read_bytes()
    cut = FRAME + 6000
    (tmp_path / "adc_data.bin").write_bytes(raw[:cut] + raw[cut + DCA1000_PAYLOAD_BYTES:])
    path = tmp_path / "adc_data.bin"
    _, msgs = caught(lambda: read_dca1000(path, S, L, T, R))
    assert len(msgs) == 1
    assert ("lost packets: 1456 bytes missing to 4 whole frames = 1 DCA1000 packet(s) of 1456 "
            "bytes; every frame after a lost packet is shifted") in msgs[0]
    assert "a cut capture: the last frame incomplete (31312 of 32768 bytes" in msgs[0]
    assert "dropped" not in msgs[0]
    with pytest.raises(CaptureError, match=r"adc_data.bin: size is not a whole number.*lost "
                       r"packets: 1456 bytes"):
        read_dca1000(path, S, L, T, R, strict=True)
    with pytest.warns(UserWarning):
        report = DCA1000Capture(path, S, L, T, R).diagnose()
    assert (report.n_whole_frames, report.extra_bytes) == (3, FRAME - DCA1000_PAYLOAD_BYTES)
    assert any(c.startswith("lost packets") for c in report.causes) and not report.ok


def test_c03_zero_filled_lost_packet_is_flagged_in_its_frame(tmp_path):
    """mmWave Studio's packet reorder zero-fills lost packets: the size stays whole frames."""
    write_dca1000(tmp_path / "adc_data.bin", tone_cube(4))
    raw = bytearray((tmp_path / "adc_data.bin").read_bytes())
    raw[FRAME + 6000:FRAME + 6000 + DCA1000_PAYLOAD_BYTES] = bytes(DCA1000_PAYLOAD_BYTES)
    (tmp_path / "adc_data.bin").write_bytes(bytes(raw))
    path = tmp_path / "adc_data.bin"
    with pytest.warns(UserWarning, match=r"frame\(s\) \[1\] hold runs of exact-zero int16 codes "
                      r"\(frame 1: 728 codes in such runs, the longest 728 codes = 1456 bytes = "
                      r"1 DCA1000 packet\(s\)\)"):
        cube = read_dca1000(path, S, L, T, R)
    assert cube.shape[0] == 4
    q = DCA1000Capture(path, S, L, T, R).diagnose()
    assert q.ok is False and q.frames.suspect_frames.tolist() == [1]
    assert q.frames.zero_run_codes.tolist() == [0, 728, 0, 0]
    with pytest.raises(CaptureError, match=r"frame\(s\) \[1\] hold runs"):
        read_dca1000(path, S, L, T, R, strict=True)


def test_c03_packet_level_record_masks_the_lost_samples_and_shifts_nothing(tmp_path):
    """The same capture as the DCA1000 sends it: packet 30 (inside frame 1) lost, two packets
    swapped, one repeated. Frames 0, 2, 3 come back exact; frame 1 exact but for the 364 samples
    the lost 1456 bytes carried, zero and masked."""
    cube = tone_cube(4)
    n = -(-4 * FRAME // DCA1000_PAYLOAD_BYTES)
    order = [k for k in range(n) if k != 30]
    order[40], order[41] = order[41], order[40]
    order.insert(60, 59)
    path = write_dca1000_packets(tmp_path / "adc_data_Raw_0.bin", cube, order=order)
    with pytest.warns(UserWarning, match=r"1456 bytes of 1 frame\(s\) never arrived \(1 "
                      r"packet\(s\) of 1456 bytes lost.*frames \[1\]"):
        got, missing = read_dca1000_packets(path, S, L, T, R)
    assert got.shape == missing.shape == cube.shape
    assert missing.sum(axis=(1, 2, 3, 4)).tolist() == [0, 364, 0, 0]
    assert np.array_equal(got[~missing], cube[~missing]) and not got[missing].any()
    assert tones_right(got)[[0, 2, 3]].tolist() == [1, 1, 1]
    # the masked samples are exactly those of stream bytes [30 * 1456, 31 * 1456) of frame 1
    codes = np.arange(FRAME // 2) + FRAME // 2          # int16 index in the stream
    lost = (codes * 2 >= 30 * 1456) & (codes * 2 < 31 * 1456)
    ref = np.zeros((1, FRAME // 2), np.int16)
    ref[0, lost] = 1
    z = _dca_to_complex(ref, "xwr16xx", S, L, T, R)[0]
    assert np.array_equal(missing[1], (z.real != 0) | (z.imag != 0))
    with pytest.warns(UserWarning, match="never arrived"):
        cap = DCA1000PacketCapture(path, S, L, T, R)
    assert (cap.report.n_lost, cap.report.n_duplicates, cap.report.n_out_of_order) == (1, 1, 2)
    with pytest.raises(CaptureError, match="never arrived"):
        DCA1000PacketCapture(path, S, L, T, R, strict=True)


def test_packet_record_split_over_files_and_cut_at_the_end(tmp_path):
    cube = tone_cube(3).copy()
    cube[1] *= 2
    rec = 10 + 96
    path = write_dca1000_packets(tmp_path / "all.bin", cube, payload_bytes=96)
    raw = path.read_bytes()
    (tmp_path / "adc_data_Raw_0.bin").write_bytes(raw[:200 * rec])
    (tmp_path / "adc_data_Raw_1.bin").write_bytes(raw[200 * rec:])
    files = [tmp_path / "adc_data_Raw_0.bin", tmp_path / "adc_data_Raw_1.bin"]
    got, missing = read_dca1000_packets(files, S, L, T, R, payload_bytes=96, strict=True)
    assert np.array_equal(got, cube) and not missing.any()
    # the second file alone: the frames it covers, numbered in the stream
    with pytest.warns(UserWarning, match="never arrived"):
        cap = DCA1000PacketCapture(files[1], S, L, T, R, payload_bytes=96)
    assert cap.first_frame == 200 * 96 // FRAME and cap.frame_numbers[-1] == 2
    assert np.array_equal(cap.read(cap.n_frames - 1), cube[2:])
    # a record cut inside the last packet's payload: that frame is incomplete, not read
    (tmp_path / "cut.bin").write_bytes(raw[:-40])
    with pytest.warns(UserWarning, match=r"stream ends 32728 bytes into frame 2.*cut capture or "
                      "lost final packets"):
        got, missing = read_dca1000_packets(tmp_path / "cut.bin", S, L, T, R, payload_bytes=96)
    assert np.array_equal(got, cube[:2]) and not missing.any()


def test_headerless_file_is_not_taken_for_a_packet_record(tmp_path):
    write_dca1000(tmp_path / "adc_data.bin", tone_cube(2))
    with pytest.raises(CaptureError, match=r"adc_data.bin: packet \d+: (byte count is not a "
                       r"multiple|sequence number and byte count disagree).*read_dca1000"):
        read_dca1000_packets(tmp_path / "adc_data.bin", S, L, T, R)


# ---------------------------------------------------------------------------------- c10
def test_c10_multipart_cascade_with_an_empty_last_part(tmp_path):
    """azinke/mmwave-repack, RaDelft-Dataset #6: parts 0000 (frames 0-3), 0001 (4-6) and an
    empty 0002; every I code of frame g is g."""
    s, loops, ntx = 16, 4, 3
    frames = np.arange(7)[:, None, None, None, None] * np.ones((1, loops, ntx, 16, s))
    write_ti_cascade(tmp_path, frames[:4], part=0, frame_period_s=0.1)
    write_ti_cascade(tmp_path, frames[4:], part=1, timestamps=np.arange(4, 7) * 100_000_000)
    for dev in ("master", "slave1", "slave2", "slave3"):
        (tmp_path / f"{dev}_0002_data.bin").write_bytes(b"")
        (tmp_path / f"{dev}_0002_idx.bin").write_bytes(struct.pack("<IIIIQ", 0, 1, 0, 0, 0))
    assert find_cascade_captures(tmp_path) == [0, 1, 2]
    with pytest.warns(UserWarning, match=r"part 0002 of the recording holds no frame"):
        cube = read_ti_cascade(tmp_path, s, loops, ntx)
    assert np.unique(cube.real, axis=None).tolist() == [1, 2, 3, 4, 5, 6]
    assert cube.shape[0] == 6 and np.array_equal(cube[:, 0, 0, 0, 0].real, np.arange(1, 7))
    one = read_ti_cascade(tmp_path, s, loops, ntx, capture_index=1, skip_first_frame=False)
    assert np.array_equal(one, read_ti_cascade(tmp_path, s, loops, ntx, part=1))
    assert one[:, 0, 0, 0, 0].real.tolist() == [4, 5, 6]
    with pytest.raises(CaptureError, match="master_0002_data.bin: capture holds no whole frame"):
        read_ti_cascade(tmp_path, s, loops, ntx, capture_index=2, skip_first_frame=False)
    with pytest.raises(TypeError, match="capture_index is an alias of part"):
        read_ti_cascade(tmp_path, s, loops, ntx, part=1, capture_index=1)


def test_reader_options_reach_the_recording_by_config(tmp_path):
    """conf/recordings entries pass ``options`` to open_recording: strict mode refuses the cut
    file the default only warns about, and an option the kind does not take is named."""
    from blindspot.radar.capture import open_recording
    from blindspot.radar.config import RadarConfig
    from tests.dsp._synth import mmwcas

    base, _ = mmwcas()
    radar = RadarConfig.from_mapping({**base.__dict__, "n_samples": S, "n_chirps": L, "n_tx": T,
                                      "n_rx": R, "tx_order": None, "array": "ula"})
    write_dca1000(tmp_path / "whole.bin", tone_cube(2))
    path = tmp_path / "adc_data.bin"
    path.write_bytes((tmp_path / "whole.bin").read_bytes()[:-DCA1000_PAYLOAD_BYTES])
    with pytest.warns(UserWarning, match="not a whole number of frames"):
        assert open_recording("dca1000", path, radar).n_frames == 1
    with pytest.raises(CaptureError, match="not a whole number of frames"):
        open_recording("dca1000", path, radar, strict=True)
    with pytest.raises(ValueError, match=r"'dca1000' has no option\(s\) \['stict'\]: it takes "
                                         r"\[.*'strict'.*\]"):
        open_recording("dca1000", path, radar, stict=True)
