"""Capture readers and writers against the file formats as TI documents them.

The byte-level tests compute where each value must sit from the format description alone
(offset formulas, ``struct`` for the index), independently of the reader, so a reader and a writer
that agree on a wrong layout still fail.
"""

from __future__ import annotations

import os
import struct
import warnings

import numpy as np
import pytest

from blindspot.radar.capture import (
    RECORDING_KINDS,
    CaptureError,
    DCA1000PacketRecording,
    DCA1000Recording,
    OpenRadarRecording,
    TICascadeCapture,
    TICascadeRecording,
    find_cascade_parts,
    open_recording,
    read_dca1000,
    read_openradar_npy,
    read_ti_cascade,
    to_int16_iq,
    write_dca1000,
    write_dca1000_packets,
    write_ti_cascade,
)
from blindspot.radar.config import RadarConfig
from blindspot.radar.source import FrameSource

S, L, C = 8, 4, 3  # samples, loops, chirps per loop (TX slots) of the small test profile
DEVICES = ("master", "slave1", "slave2", "slave3")


def random_codes(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """complex64 cube of int16 codes over the full range, extremes included."""
    iq = rng.integers(-32768, 32768, size=shape + (2,))
    iq.reshape(-1)[:4] = [-32768, 32767, 0, -1]
    return (iq[..., 0] + 1j * iq[..., 1]).astype(np.complex64)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20240611)


@pytest.fixture
def cascade(tmp_path, rng):
    cube = random_codes(rng, (5, L, C, 16, S))
    folder = tmp_path / "cap"
    write_ti_cascade(folder, cube, timestamps=np.arange(5) * 100_000_000 + 7)
    return folder, cube


# ---------------------------------------------------------------------------------- cascade
def test_cascade_round_trip_is_bit_exact(cascade):
    folder, cube = cascade
    out = read_ti_cascade(folder, S, L, C, skip_first_frame=False)
    assert out.dtype == np.complex64 and out.shape == (5, L, C, 16, S)
    assert np.array_equal(out, cube)
    # TI's processing drops the first frame: that is the default
    assert np.array_equal(read_ti_cascade(folder, S, L, C), cube[1:])


def test_cascade_bytes_sit_where_ti_format_puts_them(cascade, rng):
    """Frame f, loop l, chirp c, sample s, device RX r: int16 I at byte
    f*S*C*L*16 + (((l*C + c)*S + s)*4 + r)*4 of that device's file, Q right after."""
    folder, cube = cascade
    fb = S * C * L * 4 * 2 * 2
    n = 200
    f, l, c, s, rx = (rng.integers(0, m, n) for m in (5, L, C, S, 16))
    dev, r = rx // 4, rx % 4
    byte = f * fb + (((l * C + c) * S + s) * 4 + r) * 4
    files = {d: (folder / f"{d}_0000_data.bin").read_bytes() for d in DEVICES}
    got = np.array([struct.unpack_from("<hh", files[DEVICES[d]], b) for d, b in zip(dev, byte)])
    want = cube[f, l, c, rx, s]
    assert np.array_equal(got[:, 0], want.real) and np.array_equal(got[:, 1], want.imag)
    for d in DEVICES:
        assert len(files[d]) == 5 * fb  # no header, no padding


def test_cascade_index_matches_ti_struct(cascade):
    folder, _ = cascade
    raw = (folder / "slave3_0000_idx.bin").read_bytes()
    fb = S * C * L * 16
    tag, version, flags, num_idx, data_size = struct.unpack_from("<IIIIQ", raw, 0)
    assert (num_idx, data_size) == (5, 5 * fb) and len(raw) == 24 + 48 * 5
    for k in range(5):
        e = struct.unpack_from("<HHIHH4IIQQ", raw, 24 + 48 * k)
        size, timestamp, offset = e[-3:]
        assert (size, offset, timestamp) == (fb, k * fb, k * 100_000_000 + 7)


def test_cascade_frame_count_comes_from_index_not_padding(cascade):
    folder, cube = cascade
    for d in DEVICES:  # the capture software may leave the data files longer than the frames
        with open(folder / f"{d}_0000_data.bin", "ab") as fh:
            fh.write(b"\x11" * (S * C * L * 16 * 2 + 6))
    assert np.array_equal(read_ti_cascade(folder, S, L, C, skip_first_frame=False), cube)


def test_cascade_part_selection_and_gaps(tmp_path, rng):
    a, b = random_codes(rng, (2, L, C, 16, S)), random_codes(rng, (3, L, C, 16, S))
    write_ti_cascade(tmp_path, a, part=3)
    write_ti_cascade(tmp_path, b, part=1)
    assert find_cascade_parts(tmp_path) == [1, 3]
    # parts 0000 and 0002 are missing: reading "everything" would silently drop their frames
    with pytest.raises(CaptureError, match=r"master_0000_data.bin: part 0000 missing.*parts "
                       r"found: 0001, 0003.*part=N.*found no file, expected parts 0000 to 0003"):
        read_ti_cascade(tmp_path, S, L, C)
    with pytest.warns(UserWarning, match=r"part 0001 cannot be numbered.*master_0000_data.bin"):
        cap = TICascadeCapture(tmp_path, S, L, C, part=1)
    # not the recording's first frame (parts before it exist): nothing skipped, numbered locally
    assert np.array_equal(cap.read(), b) and cap.frame_numbers.tolist() == [0, 1, 2]
    with pytest.warns(UserWarning, match="cannot be numbered"):
        assert np.array_equal(read_ti_cascade(tmp_path, S, L, C, part=3), a)
    with pytest.raises(CaptureError, match="master_0002_data.bin"):
        read_ti_cascade(tmp_path, S, L, C, part=2)


def test_cascade_missing_slave_file(cascade):
    folder, _ = cascade
    (folder / "slave2_0000_data.bin").unlink()
    with pytest.raises(CaptureError, match="slave2_0000_data.bin.*missing"):
        read_ti_cascade(folder, S, L, C)


def test_cascade_profile_that_does_not_fit(cascade):
    folder, _ = cascade
    data_size = 5 * S * C * L * 16  # 7680 bytes per device
    # 6 samples: 1152-byte frames, and 7680 bytes is no whole number of them
    with pytest.raises(CaptureError, match=r"master_0000_idx.bin: dataFileSize is not a whole "
                       r"number of 1152-byte frames \(6 samples.*found 7680 bytes, expected a "
                       r"multiple of 1152"):
        read_ti_cascade(folder, 6, L, C)
    # 10 samples: 1920-byte frames; 5 of them need 9600 bytes
    with pytest.raises(CaptureError) as err:
        read_ti_cascade(folder, S + 2, L, C)
    msg = str(err.value)
    assert "master_0000_idx.bin" in msg and f"{data_size} bytes" in msg and "9600" in msg


def test_cascade_truncated_data_file(cascade):
    folder, _ = cascade
    fb = S * C * L * 16
    path = folder / "slave1_0000_data.bin"
    os.truncate(path, 5 * fb - 100)
    with pytest.raises(CaptureError) as err:
        read_ti_cascade(folder, S, L, C)
    msg = str(err.value)
    assert "slave1_0000_data.bin" in msg and f"{5 * fb - 100} bytes" in msg
    assert f"{5 * fb} bytes" in msg


def _rewrite_header(path, **fields):
    raw = bytearray(path.read_bytes())
    names = ("tag", "version", "flags", "num_idx", "data_file_size")
    values = dict(zip(names, struct.unpack_from("<IIIIQ", raw, 0)))
    values.update(fields)
    struct.pack_into("<IIIIQ", raw, 0, *(values[n] for n in names))
    path.write_bytes(bytes(raw))
    return values


def test_cascade_index_claims_more_frames_than_data(cascade):
    folder, _ = cascade
    fb = S * C * L * 16
    path = folder / "master_0000_idx.bin"
    _rewrite_header(path, num_idx=6, data_file_size=6 * fb)
    with open(path, "ab") as fh:  # a well-formed 6th entry, pointing past the data
        fh.write(struct.pack("<HHIHH4IIQQ", 0, 1, 0, S, L * C, 0, 0, 0, 0, fb, 0, 5 * fb))
    with pytest.raises(CaptureError) as err:
        read_ti_cascade(folder, S, L, C)
    msg = str(err.value)
    assert "master_0000_data.bin" in msg and f"{5 * fb} bytes" in msg and f"{6 * fb}" in msg


def test_cascade_index_header_disagrees_with_itself(cascade):
    folder, _ = cascade
    fb = S * C * L * 16
    path = folder / "slave3_0000_idx.bin"
    _rewrite_header(path, data_file_size=4 * fb)  # 5 entries but room for 4 frames
    with pytest.raises(CaptureError, match=r"slave3_0000_idx.bin.*5 frames.*found dataFileSize"):
        read_ti_cascade(folder, S, L, C)
    _rewrite_header(path, num_idx=7, data_file_size=5 * fb)  # 5 entries on disk, header says 7
    with pytest.raises(CaptureError, match=r"numIdx = 7.*found 264 bytes.*360 bytes"):
        read_ti_cascade(folder, S, L, C)


def test_cascade_entry_offset_disagrees(cascade):
    folder, _ = cascade
    path = folder / "slave1_0000_idx.bin"
    raw = bytearray(path.read_bytes())
    struct.pack_into("<Q", raw, 24 + 48 * 2 + 40, 12345)  # entry 2's offset
    path.write_bytes(bytes(raw))
    with pytest.raises(CaptureError, match=r"entry 2 offset.*found 12345"):
        read_ti_cascade(folder, S, L, C)


def test_cascade_devices_with_different_frame_counts(cascade):
    """A device that indexed one frame fewer (its data file may still be longer): the capture
    is read up to the frames every device has, with a warning naming the counts."""
    folder, cube = cascade
    fb = S * C * L * 16
    path = folder / "slave3_0000_idx.bin"
    raw = path.read_bytes()
    path.write_bytes(raw[:24 + 48 * 4])
    _rewrite_header(path, num_idx=4, data_file_size=4 * fb)
    with pytest.warns(UserWarning, match=r"'slave2': 5, 'slave3': 4.*using the 4"):
        out = read_ti_cascade(folder, S, L, C, skip_first_frame=False)
    assert np.array_equal(out, cube[:4])


def test_cascade_writer_rejects_wrong_shapes(tmp_path, rng):
    with pytest.raises(ValueError, match=r"expected \(chirps, tx, 16, samples\)"):
        write_ti_cascade(tmp_path, random_codes(rng, (2, L, C, 8, S)))
    frames = [random_codes(rng, (L, C, 16, S)), random_codes(rng, (L, C, 16, S + 2))]
    with pytest.raises(ValueError, match="frame 1 has shape"):
        write_ti_cascade(tmp_path, frames)
    assert os.listdir(tmp_path) == []


def test_cascade_too_small_for_a_frame(tmp_path, rng):
    write_ti_cascade(tmp_path, random_codes(rng, (1, L, C, 16, S)))
    assert read_ti_cascade(tmp_path, S, L, C, skip_first_frame=False).shape[0] == 1
    with pytest.raises(CaptureError, match="no frame left"):
        read_ti_cascade(tmp_path, S, L, C)  # the only frame is the skipped one
    (tmp_path / "empty").mkdir()
    with pytest.raises(CaptureError, match="empty: no cascade capture"):
        read_ti_cascade(tmp_path / "empty", S, L, C)
    with pytest.raises(CaptureError, match="folder not found"):
        read_ti_cascade(tmp_path / "absent", S, L, C)


def test_writer_rejects_codes_outside_int16_and_leaves_nothing(tmp_path):
    cube = np.zeros((2, L, C, 16, S), np.complex64)
    cube[1, 0, 0, 5, 3] = 40000 - 3j
    with pytest.raises(CaptureError, match=r"int16 range.*40000"):
        write_ti_cascade(tmp_path, cube)
    assert os.listdir(tmp_path) == []  # no half-written capture, no temporaries
    write_ti_cascade(tmp_path, cube, conversion="clip")
    out = read_ti_cascade(tmp_path, S, L, C, skip_first_frame=False)
    assert out[1, 0, 0, 5, 3] == 32767 - 3j


def test_int16_conversion_modes():
    z = np.array([1.5 - 2.5j, 2.4 + 0j, -40000.2 + 1j])
    with pytest.raises(CaptureError, match="not integer"):
        to_int16_iq(z[:2])
    assert to_int16_iq(z[:2], "round").tolist() == [[2, -2], [2, 0]]  # half to even
    with pytest.raises(CaptureError, match="int16 range"):
        to_int16_iq(z, "round")
    assert to_int16_iq(z, "clip")[2].tolist() == [-32768, 1]
    with pytest.raises(CaptureError, match="NaN"):
        to_int16_iq(np.array([np.nan + 0j]), "clip")


def test_writer_accepts_a_stream_of_frames(tmp_path, rng):
    cube = random_codes(rng, (4, L, C, 16, S))
    write_ti_cascade(tmp_path, (f for f in cube))  # a generator, consumed once
    assert np.array_equal(read_ti_cascade(tmp_path, S, L, C, skip_first_frame=False), cube)


# ---------------------------------------------------------------------------------- DCA1000
@pytest.mark.parametrize("layout", ["xwr16xx", "xwr14xx"])
def test_dca1000_round_trip(tmp_path, rng, layout):
    cube = random_codes(rng, (3, 5, 2, 4, 6))
    path = write_dca1000(tmp_path / "adc_data.bin", cube, layout=layout)
    out = read_dca1000(path, 6, 5, 2, 4, layout=layout)
    assert out.dtype == np.complex64 and np.array_equal(out, cube)


def test_dca1000_xwr16xx_bytes_follow_ti_document(tmp_path, rng):
    """SWRA581 (xWR16xx with DCA1000): per chirp, RX after RX; per RX, I(n) I(n+1) Q(n) Q(n+1)."""
    n_s, n_l, n_t, n_r = 4, 2, 2, 3
    cube = random_codes(rng, (1, n_l, n_t, n_r, n_s))
    raw = np.fromfile(write_dca1000(tmp_path / "a.bin", cube), "<i2")
    for l in range(n_l):
        for t in range(n_t):
            for r in range(n_r):
                start = (((l * n_t + t) * n_r + r) * n_s) * 2
                x = cube[0, l, t, r]
                want = [x[0].real, x[1].real, x[0].imag, x[1].imag,
                        x[2].real, x[3].real, x[2].imag, x[3].imag]
                assert raw[start:start + 8].tolist() == want


def test_dca1000_xwr14xx_bytes_follow_ti_document(tmp_path, rng):
    """Four lanes: per sample, I of RX0..3 then Q of RX0..3."""
    cube = random_codes(rng, (1, 1, 1, 4, 3))
    raw = np.fromfile(write_dca1000(tmp_path / "a.bin", cube, layout="xwr14xx"), "<i2")
    x = cube[0, 0, 0]
    want = np.concatenate([np.r_[x[:, s].real, x[:, s].imag] for s in range(3)])
    assert raw.tolist() == want.tolist()


def test_dca1000_extra_bytes_warn_with_their_possible_causes(tmp_path, rng):
    cube = random_codes(rng, (2, 5, 2, 4, 6))
    path = write_dca1000(tmp_path / "adc_data.bin", cube)
    with open(path, "ab") as fh:
        fh.write(b"\x01\x02" * 77)
    with pytest.warns(UserWarning, match=r"adc_data.bin: size is not a whole number of frames.*"
                      r"2074 bytes = 2 frames of 960 bytes \+ 154 bytes.*2 whole frames are read"
                      r".*cut capture.*154 of 960 bytes.*lost packets: 806 bytes missing") as w:
        out = read_dca1000(path, 6, 5, 2, 4)
    assert np.array_equal(out, cube)
    assert "dropped" not in str(w[0].message)  # a headerless file cannot prove a cut end
    with pytest.raises(CaptureError, match=r"not a whole number of frames.*found 2074 bytes"):
        read_dca1000(path, 6, 5, 2, 4, strict=True)


def test_dca1000_smaller_than_one_frame(tmp_path):
    path = tmp_path / "adc_data.bin"
    path.write_bytes(b"\0" * 958)
    with pytest.raises(CaptureError, match=r"adc_data.bin.*smaller than one frame.*958 bytes.*960"):
        read_dca1000(path, 6, 5, 2, 4)
    with pytest.raises(CaptureError, match="not found"):
        read_dca1000(tmp_path / "nope.bin", 6, 5, 2, 4)


def test_dca1000_layout_constraints(tmp_path):
    path = tmp_path / "a.bin"
    path.write_bytes(b"\0" * 4096)
    with pytest.raises(ValueError, match="even"):
        read_dca1000(path, 5, 2, 2, 4)
    with pytest.raises(ValueError, match="exactly 4 RX"):
        read_dca1000(path, 4, 2, 2, 3, layout="xwr14xx")
    with pytest.raises(ValueError, match="layout"):
        read_dca1000(path, 4, 2, 2, 4, layout="xwr99xx")  # type: ignore[arg-type]


# ---------------------------------------------------------------------------------- OpenRadar
def test_openradar_unsigned_codes_become_int16(tmp_path):
    signed = np.array([[0, 1, -1, 32767, -32768, -200]]) + 1j * np.array([[5, -5, 0, -32768,
                                                                          32767, 17]])
    stored = np.where(signed.real < 0, signed.real + 65536, signed.real) \
        + 1j * np.where(signed.imag < 0, signed.imag + 65536, signed.imag)
    np.save(tmp_path / "a.npy", stored)
    out = read_openradar_npy(tmp_path / "a.npy")
    assert out.dtype == np.complex64 and np.array_equal(out, signed)
    np.save(tmp_path / "b.npy", signed)
    with pytest.raises(CaptureError, match=r"outside the code range.*-32768"):
        read_openradar_npy(tmp_path / "b.npy")
    assert np.array_equal(read_openradar_npy(tmp_path / "b.npy", unsigned=False), signed)


def test_openradar_virtual_channels_split_tx_major(tmp_path, rng):
    cube = random_codes(rng, (1, 4, 2, 3, 5))  # (1, chirps, tx, rx, samples)
    stored = cube.reshape(4, 6, 5).astype(np.complex128)
    stored = np.where(stored.real < 0, stored.real + 65536, stored.real) \
        + 1j * np.where(stored.imag < 0, stored.imag + 65536, stored.imag)
    np.save(tmp_path / "a.npy", stored)
    assert np.array_equal(read_openradar_npy(tmp_path / "a.npy", n_tx=2), cube)
    with pytest.raises(CaptureError, match="4 TX"):
        read_openradar_npy(tmp_path / "a.npy", n_tx=4)


# ---------------------------------------------------------------------------------- sources
def small_profile(**over) -> RadarConfig:
    base = dict(name="small", start_freq_hz=77e9, bandwidth_hz=300e6, ramp_time_s=30e-6,
                idle_time_s=5e-6, adc_rate_hz=S / 30e-6, n_samples=S, n_chirps=L, n_tx=C,
                n_rx=16, tx_order=[11, 10, 9], frame_period_s=0.1, array="mmwcas",
                adc_bits=16)
    return RadarConfig.from_mapping({**base, **over})


def test_cascade_recording_is_a_lazy_frame_source(tmp_path, rng):
    cube = random_codes(rng, (100, L, C, 16, S))
    write_ti_cascade(tmp_path, cube, frame_period_s=0.1)
    src = TICascadeRecording(tmp_path, small_profile())
    assert isinstance(src, FrameSource)
    assert src.n_frames == len(src) == 99 and src.array.n_tx == C
    assert np.array_equal(src.frame(57), cube[58]) and np.array_equal(src.frame(-1), cube[-1])
    assert np.array_equal(np.stack(list(src)), cube[1:])
    np.testing.assert_allclose(src.times_s, np.arange(99) * 0.1, atol=1e-9)
    with pytest.raises(IndexError):
        src.frame(99)
    with pytest.raises(ValueError, match="radar.n_rx.* = 4.*expected 16"):
        TICascadeRecording(tmp_path, small_profile(n_rx=4))


def test_cascade_recording_times_from_index(tmp_path, rng):
    cube = random_codes(rng, (4, L, C, 16, S))
    jitter = np.array([0, 100_200_000, 199_900_000, 300_000_000]) + 10**12
    write_ti_cascade(tmp_path / "a", cube, timestamps=jitter)
    src = TICascadeRecording(tmp_path / "a", small_profile(), skip_first_frame=False)
    np.testing.assert_allclose(src.times_s, (jitter - jitter[0]) * 1e-9)
    # timestamps 1000x too far apart for the profile's period: warn, use the period
    write_ti_cascade(tmp_path / "b", cube, timestamps=jitter * 1000)
    with pytest.warns(UserWarning, match="frame interval"):
        src = TICascadeRecording(tmp_path / "b", small_profile(), skip_first_frame=False)
    np.testing.assert_allclose(src.times_s, np.arange(4) * 0.1)
    write_ti_cascade(tmp_path / "c", cube)  # no timestamps: the period
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        src = TICascadeRecording(tmp_path / "c", small_profile(), skip_first_frame=False)
    np.testing.assert_allclose(src.times_s, np.arange(4) * 0.1)


def test_dca1000_recording_frame_source(tmp_path, rng):
    radar = small_profile(n_tx=2, n_rx=4, tx_order=[0, 1], array="ula", n_samples=6,
                          adc_rate_hz=6 / 30e-6, frame_period_s=0.05)
    cube = random_codes(rng, (3, L, 2, 4, 6))
    path = write_dca1000(tmp_path / "adc_data.bin", cube)
    src = DCA1000Recording(path, radar)
    assert isinstance(src, FrameSource) and src.n_frames == 3 and src.array.n_ula == 8
    assert np.array_equal(src.frame(1), cube[1])
    assert np.array_equal(np.stack(list(src)), cube)
    np.testing.assert_allclose(src.times_s, [0, 0.05, 0.1])


def test_recording_reads_one_frame_without_loading_the_capture(tmp_path):
    """A 100-frame paper-profile capture (315 MB per device file, sparse on disk): reading a frame
    allocates about one frame, not the capture. Index entries left zero (offset/size unknown)
    are accepted."""
    import tracemalloc

    from omegaconf import OmegaConf

    from tests.conftest import REPO_ROOT

    radar = RadarConfig.from_mapping(OmegaConf.load(REPO_ROOT / "conf/radar/mmwcas.yaml"))
    n, fb = 100, radar.n_samples * radar.n_tx * radar.n_chirps * 16
    for d in DEVICES:
        with open(tmp_path / f"{d}_0000_data.bin", "wb") as fh:
            fh.truncate(n * fb)
        (tmp_path / f"{d}_0000_idx.bin").write_bytes(
            struct.pack("<IIIIQ", 0, 1, 0, n, n * fb) + bytes(48 * n))
    src = TICascadeRecording(tmp_path, radar)
    frame_bytes = radar.n_chirps * radar.n_tx * 16 * radar.n_samples * 8  # complex64
    tracemalloc.start()
    try:
        frame = src.frame(50)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert frame.shape == (64, 12, 16, 256) and not frame.any()
    assert src.n_frames == 99
    assert peak < 2 * frame_bytes  # one frame plus temporaries; the capture is 100 frames


def test_open_recording_gives_a_frame_source_for_every_kind(tmp_path, rng):
    cascade_cube = random_codes(rng, (3, L, C, 16, S))
    write_ti_cascade(tmp_path / "cas", cascade_cube)
    dca_radar = small_profile(n_tx=2, n_rx=4, tx_order=[0, 1], array="ula")
    dca_cube = random_codes(rng, (2, L, 2, 4, S))
    write_dca1000(tmp_path / "adc_data.bin", dca_cube)
    write_dca1000_packets(tmp_path / "adc_data_Raw_0.bin", dca_cube, payload_bytes=96)
    npy_cube = random_codes(rng, (1, L, 2, 4, S))
    stored = npy_cube.reshape(L, 8, S).astype(np.complex128)
    np.save(tmp_path / "a.npy", np.where(stored.real < 0, stored.real + 65536, stored.real)
            + 1j * np.where(stored.imag < 0, stored.imag + 65536, stored.imag))
    opened = {
        "ti_cascade": (open_recording("ti_cascade", tmp_path / "cas", small_profile(),
                                      skip_first_frame=False), cascade_cube, TICascadeRecording),
        "dca1000": (open_recording("dca1000", tmp_path / "adc_data.bin", dca_radar), dca_cube,
                    DCA1000Recording),
        "dca1000_packets": (open_recording("dca1000_packets", tmp_path / "adc_data_Raw_0.bin",
                                           dca_radar, payload_bytes=96, strict=True), dca_cube,
                            DCA1000PacketRecording),
        "openradar_npy": (open_recording("openradar_npy", tmp_path / "a.npy", dca_radar),
                          npy_cube, OpenRadarRecording),
    }
    assert set(opened) == set(RECORDING_KINDS)
    for kind, (src, cube, cls) in opened.items():
        assert isinstance(src, cls) and isinstance(src, FrameSource), kind
        assert len(src) == src.n_frames == len(cube) == len(src.times_s), kind
        assert np.array_equal(np.stack(list(src)), cube), kind
        assert np.array_equal(src.frame(-1), cube[-1]), kind
    with pytest.raises(ValueError, match=r"kind 'bag' unknown.*ti_cascade"):
        open_recording("bag", tmp_path / "a.npy", dca_radar)


def test_failed_write_keeps_the_previous_file_and_leaves_no_temporaries(tmp_path, rng):
    cube = random_codes(rng, (2, L, 2, 4, S))
    path = write_dca1000(tmp_path / "adc_data.bin", cube)
    before = path.read_bytes()
    bad = cube.astype(np.complex128)
    bad[1, 0, 0, 0, 0] = 0.5
    with pytest.raises(CaptureError, match="cube frame 1.*not integer"):
        write_dca1000(path, bad)
    assert path.read_bytes() == before and os.listdir(tmp_path) == ["adc_data.bin"]
    write_ti_cascade(tmp_path / "cas", random_codes(rng, (2, L, C, 16, S)))
    files = sorted(os.listdir(tmp_path / "cas"))
    with pytest.raises(ValueError, match="frame 1 has shape"):
        write_ti_cascade(tmp_path / "cas", [random_codes(rng, (L, C, 16, S)),
                                            random_codes(rng, (L, C, 16, S + 2))])
    assert sorted(os.listdir(tmp_path / "cas")) == files
