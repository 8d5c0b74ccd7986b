"""A turning ego car: its kinematics, the static world's Doppler seen from a turning radar, and
the speed and yaw rate from one radar's static detections (Kellner et al. 2013).

Truth used: rigid-body kinematics (a rear axle moving along its heading at v with yaw rate omega
stays on a circle of radius v / omega; a point l ahead of it moves at v heading + omega x l), the
radial velocity of a static point as the range rate seen from the moving radar (the radar's own
rotation does not change ranges), Kellner et al. 2013's single-radar model
v_r = omega l sin(theta) - v cos(theta), and least-squares theory: the fit's yaw-rate standard
deviation sigma sqrt([(X^T X)^-1]_xx) / l, checked against Monte-Carlo scatter."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from omegaconf import OmegaConf

from blindspot.dsp.ego_motion import EgoMotionError, ego_motion_std, estimate_ego_motion
from blindspot.radar.driving import (
    ego_pose, ego_velocity, load_scenarios, scatterers_in_vehicle_frame, scene_truth,
)

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def scenario():
    return load_scenarios(OmegaConf.load(REPO / "conf/scenario/euro_ncap.yaml"))


@settings(max_examples=25, deadline=None)
@given(kmh=st.floats(10.0, 60.0), yaw=st.floats(-20.0, 20.0))
def test_turning_pose_is_a_circle_driven_at_the_speed(scenario, kmh, yaw):
    group, named = scenario
    sc = replace(named["cpnco"], speed_kmh=kmh, yaw_rate_deg_s=yaw)
    t = np.linspace(0.0, 5.0, 2001)
    pose = ego_pose(sc, group, t)
    el = group.ego.rear_axle_to_radar_m
    heading = np.stack([-np.sin(pose[:, 2]), np.cos(pose[:, 2])], -1)
    rear = pose[:, :2] - el * heading
    # the rear axle moves along its heading at the speed (no side slip)
    d_rear = np.gradient(rear, t, axis=0)[1:-1]
    assert np.allclose(d_rear, sc.speed_mps * heading[1:-1], atol=1e-3)
    assert np.allclose(np.gradient(pose[:, 2], t), np.radians(yaw), atol=1e-9)
    # the radar's velocity is the derivative of its position
    assert np.allclose(np.gradient(pose[:, :2], t, axis=0)[1:-1],
                       ego_velocity(sc, group, t)[1:-1], atol=1e-3)
    # synchronised as the straight scene: the bumper at the walking line at lead_time_s
    straight = ego_pose(replace(sc, yaw_rate_deg_s=0.0), group, np.array([sc.lead_time_s]))
    assert np.allclose(ego_pose(sc, group, np.array([sc.lead_time_s])), straight, atol=1e-12)


@pytest.mark.parametrize("yaw", [-10.0, 5.0, 15.0])
@pytest.mark.parametrize("kmh", [10.0, 60.0])
def test_static_world_from_a_turning_radar_lies_on_the_kellner_curve(scenario, kmh, yaw):
    group, named = scenario
    sc = replace(named["cpnco"], speed_kmh=kmh, yaw_rate_deg_s=yaw)
    el = group.ego.rear_axle_to_radar_m
    for t in (0.5, 2.0, 3.5):
        pos, vel, _, _, label = scatterers_in_vehicle_frame(sc, group, t)
        st_ = label == -1
        p, v = pos[st_], vel[st_]
        r2 = np.linalg.norm(p[:, :2], axis=1)
        v_r = (p[:, :2] * v[:, :2]).sum(1) / r2          # range rate in the horizontal plane
        th = np.arctan2(p[:, 0], p[:, 1])
        kellner = np.radians(yaw) * el * np.sin(th) - sc.speed_mps * np.cos(th)
        assert st_.sum() > 20
        assert np.allclose(v_r, kellner, atol=1e-9)
        # and the range rate really is what the geometry gives: finite difference of ranges
        # of the same world points seen from the poses dt apart
        dt = 1e-4
        pose = ego_pose(sc, group, np.array([t - dt, t + dt]))
        mid = ego_pose(sc, group, np.array([t]))[0]
        cm, sm = np.cos(mid[2]), np.sin(mid[2])
        world = mid[:2] + np.stack([cm * p[:, 0] - sm * p[:, 1], sm * p[:, 0] + cm * p[:, 1]], -1)
        rr = np.linalg.norm(world[None] - pose[:, None, :2], axis=-1)
        assert np.allclose((rr[1] - rr[0]) / (2 * dt), v_r, atol=1e-5)


@pytest.mark.parametrize("yaw", [-10.0, 10.0])
@pytest.mark.parametrize("kmh", [10.0, 30.0, 60.0])
def test_speed_and_yaw_rate_from_static_detections_with_pedestrians_as_outliers(scenario, kmh, yaw):
    group, named = scenario
    sc = replace(named["cpnco_bystanders"], speed_kmh=kmh, yaw_rate_deg_s=yaw)
    el = group.ego.rear_axle_to_radar_m
    rng = np.random.default_rng(11)
    sd = 0.05                                            # ~ velocity bin / sqrt(12) + angle error
    errs_v, errs_w, theory = [], [], []
    for t in np.linspace(0.5, 4.5, 9):
        pos, vel, _, _, label = scatterers_in_vehicle_frame(sc, group, t)
        r = np.linalg.norm(pos[:, :2], axis=1)
        v_r = (pos[:, :2] * vel[:, :2]).sum(1) / r + sd * rng.standard_normal(len(r))
        az = np.degrees(np.arctan2(pos[:, 0], pos[:, 1]))
        v, w, inl = estimate_ego_motion(v_r, az, el, threshold_mps=0.25, seed=0)
        errs_v.append(v - sc.speed_mps)
        errs_w.append(np.degrees(w) - yaw)
        theory.append(np.degrees(ego_motion_std(az[inl], sd, el)[1]))
        off = (label >= 0) & (np.abs(v_r - (np.radians(yaw) * el * np.sin(np.radians(az))
                                            - sc.speed_mps * np.cos(np.radians(az)))) > 0.5)
        assert not inl[off].any()
    assert np.sqrt(np.mean(np.square(errs_v))) < 0.1
    # yaw rate within 4 theoretical standard deviations (RMS over frames)
    assert np.sqrt(np.mean(np.square(errs_w))) < 4 * np.median(theory), (errs_w, theory)


def test_yaw_rate_theory_matches_monte_carlo_scatter():
    """The least-squares variance formula against 4000 noisy fits of a fixed geometry."""
    rng = np.random.default_rng(5)
    az = rng.uniform(-60, 60, 25)
    th = np.radians(az)
    v, w, el, sd = 11.0, np.radians(8.0), 3.5, 0.06
    clean = w * el * np.sin(th) - v * np.cos(th)
    x = np.stack([np.sin(th), np.cos(th)], 1)
    noisy = clean[None] + sd * rng.standard_normal((4000, az.size))
    coef = np.linalg.lstsq(x, noisy.T, rcond=None)[0]     # (2, 4000): -v_x, -v_y
    w_hat = -coef[0] / el
    sd_v, sd_w = ego_motion_std(az, sd, el)
    assert np.std(w_hat) == pytest.approx(sd_w, rel=0.06)
    assert np.std(-coef[1]) == pytest.approx(sd_v, rel=0.06)
    # fewer angles spread -> larger yaw-rate error (the angular spread sets it)
    assert ego_motion_std(az / 4, sd, el)[1] > 3 * sd_w


def test_turning_scene_config_and_bad_lever_arm(scenario):
    group, named = scenario
    assert named["cpnco_turning"].yaw_rate_deg_s == 5.0
    assert group.ego.rear_axle_to_radar_m == 3.5
    tr = scene_truth(named["cpnco_turning"], group, 0.1)
    assert np.allclose(np.diff(np.radians(tr.ego_yaw_deg[tr.pedestrian == "p0"])),
                       np.radians(5.0) * 0.1)
    with pytest.raises(EgoMotionError, match="rear_axle_to_radar_m"):
        estimate_ego_motion(np.zeros(8), np.linspace(-30, 30, 8), 0.0)
    from blindspot.typed_config import ConfigError
    raw = OmegaConf.load(REPO / "conf/scenario/euro_ncap.yaml")
    raw.scenes.cpnco_turning.yaw_rate_deg_s = 400.0
    with pytest.raises(ConfigError, match="yaw_rate_deg_s"):
        load_scenarios(raw)
