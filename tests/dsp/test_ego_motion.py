"""Ego-motion and Doppler unwrapping on a moving car (blindspot.dsp.ego_motion, dsp.driving).

Truth used: the FMCW simulator's physics (a static scatterer seen from a radar moving at v has
v_r = -v cos(theta); the Doppler FFT measures it modulo 2 v_max = lambda / (2 T_loop)), Kellner
et al. 2013's model, and the TDM-MIMO phase model (a wrong ambiguity order leaves the phase
2 pi m t_k / T_loop across the TX slots).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from omegaconf import OmegaConf

from blindspot.dsp.doa import doa_angles
from blindspot.dsp.doppler_compensation import compensate_tdm_velocity
from blindspot.dsp.ego_motion import (
    EgoMotionError, estimate_ego_speed, estimate_sensor_velocity, odometry_speed,
    static_mask, static_radial_velocity, unwrap_doppler,
)
from blindspot.dsp.range_doppler import RangeDoppler, detection_map
from blindspot.radar.array import array_for
from blindspot.radar.config import RadarConfig
from blindspot.radar.driving import load_scenarios, scatterers_in_vehicle_frame
from blindspot.radar.simulator import FmcwSimulator

REPO = Path(__file__).resolve().parents[2]
SPEEDS_KMH = [10.0, 20.0, 30.0, 40.0, 50.0, 60.0]


@pytest.fixture(scope="module")
def radar() -> RadarConfig:
    return RadarConfig.from_mapping(OmegaConf.load(REPO / "conf/radar/mmwcas_driving.yaml"))


@pytest.fixture(scope="module")
def scenario():
    return load_scenarios(OmegaConf.load(REPO / "conf/scenario/euro_ncap.yaml"))


def test_driving_profile_is_what_its_file_says(radar):
    assert radar.max_velocity_mps == pytest.approx(5.41, abs=0.01)
    assert radar.velocity_resolution_mps == pytest.approx(0.169, abs=0.001)
    assert radar.range_resolution_m == pytest.approx(0.5, abs=0.001)
    a = array_for(radar)
    assert a.n_ula == 86 and a.ula_is_contiguous


def _static_frame(radar, speed_mps, az_deg, rng_m):
    """A noiseless frame of static point scatterers seen from the radar moving along +y."""
    th = np.radians(az_deg)
    pos = np.stack([rng_m * np.sin(th), rng_m * np.cos(th), np.zeros_like(th)], axis=1)
    vel = np.tile([0.0, -speed_mps, 0.0], (len(th), 1))
    sim = FmcwSimulator(radar, noise=False)
    return sim.frame(pos, vel, np.full(len(th), 1.0)), sim


@pytest.mark.parametrize("speed_kmh", SPEEDS_KMH)
def test_static_scatterer_lands_on_the_ego_motion_curve_after_unwrapping(radar, speed_kmh):
    """The simulator's cube, range-Doppler FFT, peak Doppler bin at each scatterer's range:
    wrapped for most of them, on -v cos(theta) within half a Doppler bin once unwrapped."""
    v = speed_kmh / 3.6
    az = np.array([-60.0, -35.0, -10.0, 0.0, 20.0, 45.0, 70.0])
    rng_m = np.array([9.0, 13.0, 17.0, 21.0, 25.0, 29.0, 33.0])
    cube, _ = _static_frame(radar, v, az, rng_m)
    rd = RangeDoppler(radar.n_chirps, radar.n_samples, "hann", "hann")
    power = detection_map(np.moveaxis(rd.native(cube[None]), -1, -4))[0]   # (range, doppler)
    rbin = np.rint(rng_m / radar.range_bin_m).astype(int)
    dbin = np.argmax(power[rbin], axis=1)
    wrapped = radar.velocity_axis_mps()[dbin]
    unwrapped = unwrap_doppler(wrapped, az, v, radar.max_velocity_mps)
    truth = -v * np.cos(np.radians(az))
    assert np.all(np.abs(unwrapped - truth) <= radar.velocity_resolution_mps / 2 + 1e-9)
    if speed_kmh >= 30:     # the static world wraps: the order matters
        assert np.any(np.abs(wrapped - truth) > radar.max_velocity_mps)


@settings(max_examples=100, deadline=None)
@given(st.floats(0.0, 30.0), st.floats(-89.0, 89.0), st.floats(-0.99, 0.99), st.floats(1.0, 10.0))
def test_unwrap_recovers_any_velocity_within_v_max_of_the_static_world(ego, az, frac, vmax):
    true = -ego * np.cos(np.radians(az)) + frac * vmax
    wrapped = (true + vmax) % (2 * vmax) - vmax
    got = unwrap_doppler(np.array([wrapped]), np.array([az]), ego, vmax)[0]
    assert got == pytest.approx(true, abs=1e-9)


def _detection_like_frame(scenario, name, speed_kmh, t, radar, rng, angle_sd_deg=0.3):
    """Detections of one frame from the scene's scatterers: every visible scatterer's true
    radial velocity quantised to the Doppler bins, wrapped into +-v_max, its azimuth with
    N(0, angle_sd) error; body parts are the outliers."""
    g, scenes = scenario
    sc = replace(scenes[name], speed_kmh=speed_kmh)
    pos, vel, _, att, label = scatterers_in_vehicle_frame(sc, g, t)
    seen = (att == 0) & (np.linalg.norm(pos, axis=1) < 60)
    pos, vel, label = pos[seen], vel[seen], label[seen]
    u = pos / np.linalg.norm(pos, axis=1, keepdims=True)
    vr = (vel * u).sum(1)
    res, vmax = radar.velocity_resolution_mps, radar.max_velocity_mps
    wrapped = (np.rint(vr / res) * res + vmax) % (2 * vmax) - vmax
    az = np.degrees(np.arctan2(pos[:, 0], pos[:, 1])) + angle_sd_deg * rng.standard_normal(len(vr))
    return wrapped, az, label, sc.speed_mps


@pytest.mark.parametrize("speed_kmh", SPEEDS_KMH)
def test_ego_speed_within_0p1_mps_rms_with_pedestrians_as_outliers(radar, scenario, speed_kmh):
    rng = np.random.default_rng(7)
    errs, outliers_rejected = [], []
    for t in np.linspace(1.0, 4.0, 7):
        v_w, az, label, v_true = _detection_like_frame(scenario, "cpnco_bystanders", speed_kmh,
                                                       t, radar, rng)
        odo = odometry_speed(np.array(v_true), 0.1, 0.3, rng)
        v = unwrap_doppler(v_w, az, float(odo), radar.max_velocity_mps)
        speed, inliers = estimate_ego_speed(v, az)
        errs.append(speed - v_true)
        moving = label >= 0
        if moving.any():
            off = np.abs(v[moving] - static_radial_velocity(az[moving], v_true)) > 0.5
            outliers_rejected.append(~inliers[moving][off])
    rms = float(np.sqrt(np.mean(np.square(errs))))
    assert rms < 0.1, (speed_kmh, errs)
    rejected = np.concatenate(outliers_rejected)
    assert rejected.size and rejected.all()   # body parts off the curve are never inliers


def test_sensor_velocity_with_a_misaligned_boresight():
    """Kellner: v_r = -v cos(theta - heading); a 4 deg mounting yaw is recovered."""
    rng = np.random.default_rng(3)
    az = rng.uniform(-70, 70, 60)
    v, heading = 12.0, 4.0
    vr = static_radial_velocity(az, v, heading) + 0.03 * rng.standard_normal(60)
    vr[:8] += rng.uniform(1.0, 3.0, 8)                      # moving targets
    vx, vy, inl = estimate_sensor_velocity(vr, az)
    assert np.hypot(vx, vy) == pytest.approx(v, abs=0.05)
    assert np.degrees(np.arctan2(vx, vy)) == pytest.approx(heading, abs=0.5)
    assert not inl[:8].any() and inl[8:].mean() > 0.9


def test_static_mask_is_the_doppler_curve_not_zero_doppler():
    az = np.array([0.0, 60.0, 0.0, 30.0])
    v = np.array([-10.0, -5.0, 0.0, -10 * np.cos(np.radians(30)) + 1.0])
    assert static_mask(v, az, 10.0, 0.3).tolist() == [True, True, False, False]


def test_no_consensus_gives_nan_and_bad_input_names_the_argument():
    speed, inl = estimate_ego_speed(np.array([1.0, 2.0]), np.array([0.0, 10.0]))
    assert np.isnan(speed) and not inl.any()
    with pytest.raises(EgoMotionError, match="azimuth_deg"):
        unwrap_doppler(np.zeros(3), np.zeros(2), 1.0, 2.0)
    with pytest.raises(EgoMotionError, match="v_max_mps"):
        unwrap_doppler(np.zeros(3), np.zeros(3), 1.0, 0.0)
    with pytest.raises(EgoMotionError, match="radial_velocity_mps"):
        estimate_ego_speed(np.array([np.nan, 1.0]), np.zeros(2))


def _one_target_snapshots(radar, v_ego, az_deg, r_m, own_radial=0.0):
    """The 3 x 3 cell snapshots on the ULA of one scatterer seen from the moving radar, and its
    wrapped and true radial velocity."""
    from blindspot.dsp.snapshots import cell_snapshots

    th = np.radians(az_deg)
    pos = np.array([[r_m * np.sin(th), r_m * np.cos(th), 0.0]])
    u = pos[0] / r_m
    vel = np.array([[0.0, -v_ego, 0.0]]) + own_radial * u
    sim = FmcwSimulator(radar, noise=False)
    cube = sim.frame(pos, vel, np.array([1.0]))
    rd = RangeDoppler(radar.n_chirps, radar.n_samples, "hann", "hann").native(cube[None])[0]
    power = detection_map(np.moveaxis(rd[None], -1, -4))[0]
    rb, db = np.unravel_index(np.argmax(power), power.shape)
    x = cell_snapshots(rd, np.array([rb]), np.array([db]))
    a = sim.array
    t, r = a.ula_index
    return x[:, t, r, :], radar.velocity_axis_mps()[db], float((vel[0] * u).sum()), a


@pytest.mark.parametrize("az_deg,own", [(20.0, 0.0), (-35.0, 0.0), (10.0, 1.4)])
def test_angle_within_0p2_deg_at_60_kmh_only_with_the_unwrapped_compensation(radar, az_deg, own):
    v = 60 / 3.6
    ula, v_wrapped, v_true, a = _one_target_snapshots(radar, v, az_deg, 15.0, own)
    v_un = unwrap_doppler(np.array([v_wrapped]), np.array([az_deg]), v, radar.max_velocity_mps)
    assert v_un[0] == pytest.approx(v_true, abs=radar.velocity_resolution_mps)
    tx = a.ula_index[0]
    slots = radar.tx_slot_times_s()

    def angle(vel):
        x = compensate_tdm_velocity(ula, np.array([vel]), radar.wavelength_m, slots, tx)
        return doa_angles(x, a.ula_positions_wl, 1, 3, np.arange(-90, 90.01, 0.25),
                          forward_backward=True, subarray=64)[0, 0]

    assert angle(v_un[0]) == pytest.approx(az_deg, abs=0.2)
    # the wrapped velocity (the Doppler bin alone) corrupts the angle
    wrong = angle(v_wrapped)
    assert not abs(wrong - az_deg) < 1.0, wrong
