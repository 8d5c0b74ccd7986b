"""TDM-MIMO Doppler compensation: a moving target's angle is biased without it and accurate with
it, on the 86-element MMWCAS array and on a 2 TX x 4 RX (AWR1843) array.

On the MMWCAS ULA the TX slot of the elements runs 0..8 twice across the aperture (a sawtooth),
so the uncompensated slot phase mostly scrambles rather than tilts the wavefront: the bias is
0.04-0.2 deg for 0.7-2.2 m/s, 20-1000x the compensated error and far above the CRB (~0.002 deg at
10 dB). On the 2 x 4 array the second half of the aperture carries the whole slot phase as one
step, and the bias reaches degrees."""

from __future__ import annotations

import numpy as np
import pytest

from blindspot.dsp.doa import music_angles
from blindspot.dsp.doppler_compensation import (
    compensate_tdm, doppler_frequency_hz, tdm_phase_correction,
)
from blindspot.dsp.range_doppler import RangeDoppler, detection_map
from blindspot.dsp.snapshots import cell_snapshots
from tests.dsp._synth import mmwcas, tone_cube


@pytest.fixture(scope="module")
def paper():
    return mmwcas()


def test_bin_to_frequency_matches_velocity_axis(paper):
    radar, _ = paper
    bins = np.arange(radar.n_chirps)
    fd = doppler_frequency_hz(bins, radar.n_chirps, radar.loop_period_s)
    np.testing.assert_allclose(fd, 2 * radar.velocity_axis_mps() / radar.wavelength_m, rtol=1e-12)
    assert fd[radar.n_chirps // 2] == 0.0
    corr = tdm_phase_correction(np.array([100.0]), radar.tx_slot_times_s())
    np.testing.assert_allclose(np.angle(corr[0, 1]), -2 * np.pi * 100.0 * radar.chirp_period_s)


def angle_of_moving_target(radar, array, velocity, angle, compensate, **doa):
    range_m = 40 * radar.range_bin_m
    cube = tone_cube(radar, array, [(range_m, velocity, angle, 1.0)], noise_power=1e-2,
                     rng=np.random.default_rng(1))
    rd = RangeDoppler(radar.n_chirps, radar.n_samples).native(cube)
    power = detection_map(np.moveaxis(rd, 3, 0))
    r, d = np.unravel_index(np.argmax(power), power.shape)
    x = cell_snapshots(rd, np.array([r]), np.array([d]))
    tx, rx = array.ula_index
    ula = x[:, tx, rx, :]
    if compensate:
        ula = compensate_tdm(ula, np.array([d]), radar.n_chirps, radar.loop_period_s,
                             radar.tx_slot_times_s(), tx)
    doa = doa or dict(subarray=64, forward_backward=True)
    return music_angles(ula, array.ula_positions_wl, n_signals=1, **doa)[0, 0]


@pytest.mark.parametrize(("velocity_bins", "angle"), [(25, 20.0), (-28, -35.0), (12, 5.0)])
def test_moving_target_angle_with_and_without_compensation(paper, velocity_bins, angle):
    radar, array = paper
    v = velocity_bins * radar.velocity_resolution_mps  # up to 2 m/s, below v_max = 2.3 m/s
    with_comp = angle_of_moving_target(radar, array, v, angle, True)
    without = angle_of_moving_target(radar, array, v, angle, False)
    assert abs(with_comp - angle) < 0.002
    # the uncompensated slot phase (0.08-0.18 rad per slot) biases the angle
    assert abs(without - angle) > 0.03
    assert abs(without - angle) > 20 * abs(with_comp - angle)


def test_two_tx_array_bias_is_degrees():
    from omegaconf import OmegaConf

    from blindspot.radar.array import array_for
    from blindspot.radar.config import RadarConfig
    from tests.conftest import REPO_ROOT

    radar = RadarConfig.from_mapping(OmegaConf.to_container(
        OmegaConf.load(REPO_ROOT / "conf/radar/dca1000_awr1843.yaml")))
    array = array_for(radar)
    v = 80 * radar.velocity_resolution_mps  # 5.1 m/s of the 8.1 m/s unambiguous
    opts = dict(subarray=None, forward_backward=False)
    with_comp = angle_of_moving_target(radar, array, v, 10.0, True, **opts)
    without = angle_of_moving_target(radar, array, v, 10.0, False, **opts)
    assert abs(with_comp - 10.0) < 0.05
    assert abs(without - 10.0) > 3.0


def test_static_target_needs_no_compensation(paper):
    radar, array = paper
    a = angle_of_moving_target(radar, array, 0.0, 12.0, False)
    b = angle_of_moving_target(radar, array, 0.0, 12.0, True)
    assert a == pytest.approx(b, abs=1e-9) and a == pytest.approx(12.0, abs=0.02)


def test_shape_errors(paper):
    radar, _ = paper
    with pytest.raises(ValueError, match="n_tx=12"):
        compensate_tdm(np.zeros((1, 3, 16, 9), complex), np.array([3]), 64, 1e-3,
                       radar.tx_slot_times_s())
