"""Issue 9, item 5: every capture-format field of a radar profile is honoured by each recording
kind, or rejected with an error naming the key, the value found and what is supported.

RadarConfig's fields that describe the bytes of a capture are n_samples, n_chirps, n_tx, n_rx and
adc_bits (the formats here have no complex/real, I/Q-order, lane or endianness key: the lane
layout is the DCA1000 readers' ``layout`` option, complex little-endian int16 is fixed by the
formats); tx_order and frame_period_s say how to interpret the frames (virtual array, times).
One test per field, each over the four kinds.
"""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

from blindspot.radar.array import array_for
from blindspot.radar.capture import (
    RECORDING_KINDS,
    CaptureError,
    open_recording,
    write_dca1000,
    write_dca1000_packets,
    write_ti_cascade,
)
from blindspot.radar.config import RadarConfig
from blindspot.typed_config import ConfigError

S, L = 8, 4
N_FRAMES = 4


def profile(kind: str, **over) -> RadarConfig:
    cascade = kind == "ti_cascade"
    n = over.get("n_samples", S)
    base = dict(name=kind, start_freq_hz=77e9, bandwidth_hz=300e6, ramp_time_s=30e-6,
                idle_time_s=5e-6, adc_rate_hz=n / 30e-6, n_samples=S, n_chirps=L,
                n_tx=3 if cascade else 2, n_rx=16 if cascade else 4,
                array="mmwcas" if cascade else "ula", frame_period_s=0.1, adc_bits=16)
    return RadarConfig.from_mapping({**base, **over})


def codes(shape, lo=-2048, hi=2048, seed=0) -> np.ndarray:
    iq = np.random.default_rng(seed).integers(lo, hi, size=shape + (2,))
    return (iq[..., 0] + 1j * iq[..., 1]).astype(np.complex64)


def record(kind: str, folder, cube: np.ndarray):
    """Write ``cube`` (frames, loops, tx, rx, samples) as a recording of ``kind``; its path."""
    if kind == "ti_cascade":
        write_ti_cascade(folder / "cas", cube, frame_period_s=0.1)
        return folder / "cas"
    if kind == "dca1000":
        return write_dca1000(folder / "adc_data.bin", cube)
    if kind == "dca1000_packets":
        return write_dca1000_packets(folder / "adc_data_Raw_0.bin", cube, payload_bytes=64)
    f, c, t, r, s = cube.shape
    stored = cube[0].reshape(c, t * r, s).astype(np.complex128)
    unsigned = (np.where(stored.real < 0, stored.real + 65536, stored.real)
                + 1j * np.where(stored.imag < 0, stored.imag + 65536, stored.imag))
    np.save(folder / "a.npy", unsigned)
    return folder / "a.npy"


def opened(kind: str, path, radar: RadarConfig):
    opts = {"payload_bytes": 64} if kind == "dca1000_packets" else {}
    if kind == "ti_cascade":
        opts["skip_first_frame"] = False
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # sizes that do not divide: tested in test_capture*.py
        return open_recording(kind, path, radar, **opts)


def written(kind: str, tmp_path, **over):
    """A recording written with the base profile of ``kind``: (path, cube, base profile)."""
    radar = profile(kind)
    n = 1 if kind == "openradar_npy" else N_FRAMES
    cube = codes((n, radar.n_chirps, radar.n_tx, radar.n_rx, radar.n_samples))
    return record(kind, tmp_path, cube), cube, radar


KINDS = pytest.mark.parametrize("kind", RECORDING_KINDS)


@pytest.mark.parametrize("key,factor", [("n_samples", 2), ("n_chirps", 2), ("n_tx", 2)])
@KINDS
def test_frame_dimensions_shape_every_frame_or_are_rejected(tmp_path, kind, key, factor):
    """A profile whose frames are twice as large: the frames read have the profile's shape (the
    same bytes, fewer frames), or the reader says which size does not fit."""
    path, cube, radar = written(kind, tmp_path)
    other = profile(kind, **{key: getattr(radar, key) * factor},
                    **({"tx_order": list(range(6))} if key == "n_tx" and kind == "ti_cascade"
                       else {}))
    try:
        src = opened(kind, path, other)
    except CaptureError as err:
        assert kind in ("ti_cascade", "openradar_npy"), err
        if kind == "openradar_npy":
            assert re.search(rf"radar.{key}|radar.n_tx \* radar.n_rx", str(err))
        return
    frame = src.frame(0)
    assert frame.shape == (other.n_chirps, other.n_tx, other.n_rx, other.n_samples)
    assert src.n_frames == N_FRAMES // factor
    # the same bytes, another frame size: the first frame holds the first two of the file
    assert np.array_equal(np.sort(np.abs(frame.ravel())), np.sort(np.abs(cube[:2].ravel())))


@KINDS
def test_n_rx_is_honoured_or_rejected_by_name(tmp_path, kind):
    path, cube, radar = written(kind, tmp_path)
    if kind == "ti_cascade":
        with pytest.raises(ConfigError, match=r"radar.n_rx' = 8.*expected 16"):
            opened(kind, path, profile(kind, n_rx=8, array="mmwcas"))
        return
    if kind == "openradar_npy":
        with pytest.raises(CaptureError, match=r"radar.n_tx \* radar.n_rx.*found 8 in the "
                           r"file, expected 4"):
            opened(kind, path, profile(kind, n_rx=2))
        return
    src = opened(kind, path, profile(kind, n_rx=2))  # DCA1000 (xwr16xx): RX blocks of a chirp
    assert src.frame(0).shape == (L, 2, 2, S) and src.n_frames == 2 * N_FRAMES
    assert np.array_equal(src.frame(0)[0, 0], cube[0, 0, 0, :2])


@KINDS
def test_adc_bits_is_honoured_or_rejected_by_name(tmp_path, kind):
    path, cube, radar = written(kind, tmp_path)
    for bits in (None, 10):
        with pytest.raises(ConfigError, match=rf"radar.adc_bits' = {bits}.*expected one of"):
            opened(kind, path, profile(kind, adc_bits=bits))
    if kind.startswith("dca1000"):
        # 12-bit codes as TI's scripts find them in 16-bit words (SWRA581 section 9)
        tmp = tmp_path / "twelve"
        tmp.mkdir()
        signed = codes((N_FRAMES, L, 2, 4, S), -2048, 2048, seed=3)
        stored = (np.where(signed.real < 0, signed.real + 4096, signed.real)
                  + 1j * np.where(signed.imag < 0, signed.imag + 4096, signed.imag))
        src = opened(kind, record(kind, tmp, stored), profile(kind, adc_bits=12))
        assert np.array_equal(np.stack(list(src)), signed)
        src14 = opened(kind, record(kind, tmp, stored), profile(kind, adc_bits=14))
        assert np.array_equal(np.stack(list(src14)), stored)  # below 2**13: unchanged
        bad = opened(kind, path, profile(kind, adc_bits=12))  # codes down to -2048 fit, but
        with pytest.raises(CaptureError, match="outside the range of a 12-bit ADC"):
            opened(kind, record(kind, tmp, stored * 8), profile(kind, adc_bits=12)).frame(0)
        assert bad.frame(0).shape == (L, 2, 4, S)
    else:
        with pytest.raises(ConfigError, match=r"radar.adc_bits' = 12.*expected one of \[16\]"):
            opened(kind, path, profile(kind, adc_bits=12))


@KINDS
def test_tx_order_shapes_the_virtual_array(tmp_path, kind):
    path, _, radar = written(kind, tmp_path)
    order = [2, 0, 1] if kind == "ti_cascade" else [1, 0]
    other = profile(kind, tx_order=order)
    src = opened(kind, path, other)
    assert np.array_equal(src.array.tx_pos, array_for(other).tx_pos)
    assert not np.array_equal(src.array.tx_pos, array_for(radar).tx_pos)


@KINDS
def test_frame_period_gives_the_frame_times(tmp_path, kind):
    path, _, radar = written(kind, tmp_path)
    src = opened(kind, path, profile(kind, frame_period_s=0.25))
    if kind == "ti_cascade":  # the index holds 0.1 s timestamps: those win, with a warning
        with pytest.warns(UserWarning, match="profile's frame_period_s is 0.25"):
            src = open_recording(kind, path, profile(kind, frame_period_s=0.25),
                                 skip_first_frame=False)
        np.testing.assert_allclose(src.times_s, np.arange(N_FRAMES) * 0.25)
        return
    np.testing.assert_allclose(src.times_s, np.arange(src.n_frames) * 0.25)
