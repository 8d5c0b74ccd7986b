"""Range-Doppler FFTs: agreement with a plain numpy reference (one frame and a batch, full range
and a range window, both FFT back-ends), target placement on the physical axes, zero-Doppler
centring, scaling and noise level of the non-coherent map."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

from blindspot.dsp.range_doppler import (
    RangeDoppler, RangeDopplerError, WindowError, detection_map, range_doppler, signed_doppler_index,
)
from tests.dsp._synth import mmwcas, tone_cube


@pytest.fixture(scope="module")
def paper():
    return mmwcas()


def noise_cube(shape, seed=1):
    rng = np.random.default_rng(seed)
    return (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)).astype(np.complex64)


def numpy_reference(cube, range_window="hann", doppler_window="hamming"):
    """Plain float64 numpy: window, fft over samples, window, fft over chirps, fftshift.
    cube (..., chirps, tx, rx, samples) -> (..., range, doppler, tx, rx) complex128."""
    n_chirps, n_samples = cube.shape[-4], cube.shape[-1]
    wr = scipy.signal.get_window(range_window, n_samples, fftbins=True)
    wd = scipy.signal.get_window(doppler_window, n_chirps, fftbins=True)
    ref = np.fft.fft(cube.astype(np.complex128) * wr, axis=-1)
    ref = np.fft.fftshift(np.fft.fft(ref * wd[:, None, None, None], axis=-4), axes=-4)
    return np.moveaxis(ref, -1, -4)


def assert_float32_close(actual, ref):
    np.testing.assert_allclose(actual, ref, rtol=0, atol=2e-6 * np.abs(ref).max())


@pytest.mark.parametrize("n_chirps", [16, 15])
def test_matches_numpy_reference(n_chirps):
    cube = noise_cube((n_chirps, 3, 4, 32))
    ref = numpy_reference(cube)
    rd = range_doppler(cube, "hann", "hamming")
    assert rd.shape == (32, n_chirps, 3, 4) and rd.dtype == np.complex64
    assert_float32_close(rd, ref)
    power = detection_map(rd)
    assert power.shape == (32, n_chirps) and power.dtype == np.float64
    np.testing.assert_allclose(power, (np.abs(ref) ** 2).sum(axis=(2, 3)), rtol=1e-5)
    # a C-contiguous copy (not RangeDoppler's view) takes the general path: same map
    np.testing.assert_allclose(detection_map(np.ascontiguousarray(rd)), power, rtol=1e-6)


@pytest.mark.parametrize("n_range", [None, 32, 11, 1])
def test_every_method_matches_the_reference_on_one_frame_and_a_batch(n_range):
    """Full range (FFTW, in channel blocks) and range window (scipy), native / __call__ / range_profiles +
    doppler, one frame and a batch whose frames differ: all equal the numpy reference."""
    batch = noise_cube((3, 16, 3, 4, 32), seed=2)
    batch[1] *= 1000  # very different scales per frame: nothing mixes between frames
    ref = numpy_reference(batch)[:, :n_range]  # (frames, range, doppler, tx, rx)
    proc = RangeDoppler(16, 32, "hann", "hamming", 1, n_range)
    k = 32 if n_range is None else n_range
    for cube, want in [(batch[0], ref[0]), (batch, ref)]:
        lead = cube.shape[:-4]
        native = proc.native(cube)
        assert native.shape == (*lead, 16, 3, 4, k) and native.dtype == np.complex64
        assert proc.channel_major(cube).shape == (*lead, 3, 4, 16, k)
        rd = proc(cube)
        assert rd.shape == (*lead, k, 16, 3, 4)
        for f in range(len(batch) if lead else 1):
            sel = (f,) if lead else ()
            assert_float32_close(rd[sel], want[sel])
            assert_float32_close(np.moveaxis(native[sel], -1, -4), want[sel])
        profiles = proc.range_profiles(cube)
        assert profiles.shape == (*lead, 16, 3, 4, 32)
        before = profiles.copy()
        via_profiles = proc.doppler(profiles)
        np.testing.assert_array_equal(profiles, before)  # the input is left alone
        np.testing.assert_allclose(via_profiles, native, rtol=0, atol=2e-6 * np.abs(native).max())
        power = detection_map(rd)
        assert power.shape == (*lead, k, 16)
        np.testing.assert_allclose(power, (np.abs(want) ** 2).sum(axis=(-2, -1)), rtol=1e-5)
    # the batch is the frames one by one
    one_by_one = np.stack([proc.native(c) for c in batch])
    np.testing.assert_allclose(proc.native(batch), one_by_one, rtol=0,
                               atol=1e-6 * np.abs(one_by_one).max())
    maps = np.stack([detection_map(proc(c)) for c in batch])
    np.testing.assert_allclose(detection_map(proc(batch)), maps, rtol=1e-6)


@pytest.mark.parametrize("block_bytes", [1, 3 * 16 * 32 * 8, 2 * 12 * 16 * 32 * 8])
def test_large_batches_go_in_blocks_with_the_same_result(monkeypatch, block_bytes):
    """Blocks of one channel, of a divisor of the frame's channels (3 of 12), and of two
    whole frames (a batch of 3: the last block is short): equal to frame by frame."""
    import blindspot.dsp.range_doppler as rd_mod

    batch = noise_cube((3, 16, 3, 4, 32), seed=4)
    proc = RangeDoppler(16, 32, "hann", "hamming")
    one_by_one = np.stack([proc.channel_major(c) for c in batch])
    monkeypatch.setattr(rd_mod, "_BLOCK_BYTES", block_bytes)
    blocks = proc.channel_major(batch)
    assert blocks.shape == (3, 3, 4, 16, 32) and blocks.flags.c_contiguous
    np.testing.assert_allclose(blocks, one_by_one, rtol=0, atol=1e-6 * np.abs(one_by_one).max())
    assert_float32_close(np.moveaxis(proc.native(batch), -1, -4), numpy_reference(batch))


def test_an_empty_batch_gives_empty_maps():
    proc = RangeDoppler(16, 32, "hann", "hamming")
    rd = proc.native(np.zeros((0, 16, 3, 4, 32), np.complex64))
    assert rd.shape == (0, 16, 3, 4, 32)
    assert detection_map(np.moveaxis(rd, -1, -4)).shape == (0, 32, 16)


def test_range_window_keeps_the_first_bins_of_the_full_transform():
    cube = noise_cube((64, 2, 4, 256), seed=3)
    full = RangeDoppler(64, 256).native(cube)
    cut = RangeDoppler(64, 256, n_range=61).native(cube)
    assert cut.shape == (64, 2, 4, 61)
    np.testing.assert_allclose(cut, full[..., :61], rtol=0, atol=2e-6 * np.abs(full).max())


def test_unaligned_channel_blocks_give_the_same_result():
    """Odd chirp and sample counts (a channel block of 15 x 33 complex64 is not a multiple of
    64 bytes, so the blocks of the result are not SIMD-aligned) and several threads."""
    batch = noise_cube((2, 15, 3, 2, 33), seed=5)
    for workers in (1, 2):
        proc = RangeDoppler(15, 33, "hann", "hamming", workers)
        assert_float32_close(np.moveaxis(proc.native(batch), -1, -4), numpy_reference(batch))
        assert_float32_close(proc(batch[1]), numpy_reference(batch[1]))


@pytest.mark.parametrize(("range_bin", "vel_bin"), [(40, 0), (17, 5), (100, -7)])
def test_target_lands_on_its_physical_bin(paper, range_bin, vel_bin):
    radar, array = paper
    r_m = range_bin * radar.range_bin_m
    v = vel_bin * radar.velocity_resolution_mps
    cube = tone_cube(radar, array, [(r_m, v, 12.0, 1.0)])
    power = detection_map(range_doppler(cube))
    r, d = np.unravel_index(np.argmax(power), power.shape)
    assert radar.range_axis_m()[r] == pytest.approx(r_m)
    assert radar.velocity_axis_mps()[d] == pytest.approx(v)
    assert signed_doppler_index(d, radar.n_chirps) == vel_bin
    # unnormalised FFTs: an on-bin static tone of amplitude 1 peaks at sum(w_r) sum(w_d) per channel
    if vel_bin == 0:
        gain = np.hanning(radar.n_samples + 1)[:-1].sum() * np.hanning(radar.n_chirps + 1)[:-1].sum()
        assert power[r, d] == pytest.approx(radar.n_tx * radar.n_rx * gain ** 2, rel=1e-4)
    # with a range window that keeps the target (the other back-end): the same cell
    cut = RangeDoppler(radar.n_chirps, radar.n_samples, n_range=range_bin + 5)
    power_cut = detection_map(cut(cube))
    assert np.unravel_index(np.argmax(power_cut), power_cut.shape) == (r, d)


def test_noise_floor_of_the_map(paper):
    """White noise of power s2 per sample: E[map] = s2 * channels * sum(w_r^2) * sum(w_d^2)."""
    radar, array = paper
    cube = tone_cube(radar, array, [], noise_power=2.0, rng=np.random.default_rng(5))
    power = detection_map(range_doppler(cube))
    w_r = np.hanning(radar.n_samples + 1)[:-1]
    w_d = np.hanning(radar.n_chirps + 1)[:-1]
    expected = 2.0 * radar.n_tx * radar.n_rx * (w_r ** 2).sum() * (w_d ** 2).sum()
    assert power.mean() == pytest.approx(expected, rel=0.01)


def test_bad_input_is_named(paper):
    with pytest.raises(WindowError, match="unknown"):
        RangeDoppler(64, 256, range_window="kaiser-ish")
    with pytest.raises(RangeDopplerError, match=r"n_range must be in \[1, 256\]"):
        RangeDoppler(64, 256, n_range=0)
    with pytest.raises(RangeDopplerError, match=r"cube must be a cube \(chirps=64.*found complex64 "
                       r"array of shape \(32, 12, 16, 256\)"):
        RangeDoppler(64, 256)(np.zeros((32, 12, 16, 256), np.complex64))
    with pytest.raises(RangeDopplerError, match=r"must be a cube \(chirps=64"):
        RangeDoppler(64, 256).native(np.zeros((12, 16, 256), np.complex64))
    with pytest.raises(RangeDopplerError, match=r"must be range profiles \(chirps=64"):
        RangeDoppler(64, 256).doppler(np.zeros((2, 1, 32, 12, 16, 256), np.complex64))
    with pytest.raises(RangeDopplerError, match=r"cube must be .* of numbers"):
        RangeDoppler(4, 8)(np.full((4, 1, 1, 8), "a"))
    with pytest.raises(RangeDopplerError, match=r"rd must be range-Doppler data \(range, doppler, "
                       r"tx, rx\)"):
        detection_map(np.zeros((256, 64, 192), np.complex64))


@pytest.mark.parametrize("block_bytes", [1, 2 * 12 * 16 * 32 * 8])
def test_without_pyfftw_scipy_gives_the_same_transform(monkeypatch, block_bytes):
    """pyFFTW (FFTW is GPL) is optional: without it the blocks go through scipy.fft, to the
    same float32 reference, one channel or whole frames at a time."""
    import blindspot.dsp.range_doppler as rd_mod

    monkeypatch.setattr(rd_mod, "HAVE_FFTW", False)
    monkeypatch.setattr(rd_mod, "_BLOCK_BYTES", block_bytes)
    batch = noise_cube((3, 16, 3, 4, 32), seed=6)
    proc = RangeDoppler(16, 32, "hann", "hamming")
    assert_float32_close(np.moveaxis(proc.native(batch), -1, -4), numpy_reference(batch))
    assert_float32_close(proc(batch[0]), numpy_reference(batch[0]))
