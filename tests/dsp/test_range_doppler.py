"""Range-Doppler FFTs: agreement with a plain numpy reference, target placement on the physical
axes, zero-Doppler centring, scaling and noise level of the non-coherent map."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

from blindspot.dsp.range_doppler import (
    RangeDoppler, WindowError, detection_map, range_doppler, signed_doppler_index,
)
from tests.dsp._synth import mmwcas, tone_cube


@pytest.fixture(scope="module")
def paper():
    return mmwcas()


@pytest.mark.parametrize("n_chirps", [16, 15])
def test_matches_numpy_reference(n_chirps):
    rng = np.random.default_rng(1)
    cube = (rng.standard_normal((n_chirps, 3, 4, 32))
            + 1j * rng.standard_normal((n_chirps, 3, 4, 32))).astype(np.complex64)
    wr = scipy.signal.windows.hann(32, sym=False)
    wd = scipy.signal.windows.hamming(n_chirps, sym=False)
    ref = np.fft.fft(cube.astype(np.complex128) * wr, axis=-1)
    ref = np.fft.fftshift(np.fft.fft(ref * wd[:, None, None, None], axis=0), axes=0)
    ref = ref.transpose(3, 0, 1, 2)  # (range, doppler, tx, rx)
    rd = range_doppler(cube, "hann", "hamming")
    assert rd.shape == (32, n_chirps, 3, 4)
    np.testing.assert_allclose(rd, ref, rtol=0, atol=2e-5 * np.abs(ref).max())
    np.testing.assert_allclose(detection_map(rd), (np.abs(ref) ** 2).sum(axis=(2, 3)),
                               rtol=1e-4)
    # a C-contiguous copy (not RangeDoppler's view) gives the same map
    np.testing.assert_allclose(detection_map(np.ascontiguousarray(rd)), detection_map(rd),
                               rtol=1e-6)


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
    with pytest.raises(ValueError, match=r"expected a cube \(chirps=64"):
        RangeDoppler(64, 256)(np.zeros((32, 12, 16, 256), np.complex64))
