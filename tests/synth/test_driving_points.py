"""Every radar point of a driving frame (blindspot.synth.driving_measurement.measure_driving):
the columns a tracker reads, and points that agree with the scene's physics.

Truth used: the scene geometry (parked cars' faces and the roadside lines in the world frame,
the pedestrian's truth position), the Kellner et al. 2013 static-world Doppler curve
(v_r = omega l sin(theta) - v cos(theta)) and the frame transforms."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig, EgoMotionConfig
from blindspot.radar.config import RadarConfig, SimConfig
from blindspot.radar.scenario import load_scenarios
from blindspot.config import compose
from blindspot.radar.driving import ego_pose, scene_truth, static_scatterers
from blindspot.synth.driving_detection import ego_motion_metrics
from blindspot.synth.driving_measurement import MEASURED_COLUMNS, POINT_COLUMNS, measure_driving

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def turning_frames():
    cfg = compose(config_dir=REPO / "conf")
    group, named = load_scenarios(cfg.scenario)
    sc = replace(named["cpnco_turning"], speed_kmh=30.0)
    res = measure_driving([sc], group, RadarConfig.from_cfg(cfg, "driving_radar"), CfarConfig.from_cfg(cfg, "driving_cfar"), DoaConfig.from_cfg(cfg),
                          DetectConfig.from_cfg(cfg), EgoMotionConfig.from_cfg(cfg),
                          adc_headroom_db=SimConfig.from_cfg(cfg).adc_headroom_db,
                          frames={sc.name: np.array([20, 28, 33, 36])})
    return sc, group, EgoMotionConfig.from_cfg(cfg), res, RadarConfig.from_cfg(cfg, "driving_radar").max_velocity_mps


@pytest.mark.slow   # the first measured batch pays MUSIC's warm-up (33 s at load 9)
def test_every_point_has_the_tracker_columns(turning_frames):
    sc, _, ego, res, vmax = turning_frames
    p = res.points
    assert tuple(p.columns) == POINT_COLUMNS and tuple(res.measured.columns) == MEASURED_COLUMNS
    assert set(p.frame) == {20, 28, 33, 36} and len(p) >= 4 * 8
    assert p["static"].dtype == bool
    np.testing.assert_array_equal(p["static"],
                                  p.velocity_over_ground_mps.abs() <= ego.static_tolerance_mps)
    th = np.radians(p.angle_deg)
    np.testing.assert_allclose(p.x_vehicle_m, p.range_m * np.sin(th), atol=1e-9)
    np.testing.assert_allclose(p.y_vehicle_m, p.range_m * np.cos(th), atol=1e-9)
    # unwrapped = wrapped + 2 k v_max
    k = (p.velocity_mps - p.velocity_wrapped_mps) / (2 * vmax)
    np.testing.assert_allclose(k, np.rint(k), atol=2e-3)


@pytest.mark.slow   # the first measured batch pays MUSIC's warm-up (33 s at load 9)
def test_static_world_points_sit_on_the_static_world_and_on_its_doppler_curve(turning_frames):
    sc, group, _, res, _ = turning_frames
    p = res.points[res.points.source == "static"]
    xyz, _, _ = static_scatterers(sc, group)
    d = np.hypot(p.x_m.to_numpy()[:, None] - xyz[None, :, 0],
                 p.y_m.to_numpy()[:, None] - xyz[None, :, 1]).min(1)
    # a range bin is 0.5 m; MUSIC's angle error at 20 m is a few tenths of a metre
    assert np.median(d) < 0.5 and np.mean(d < 1.5) > 0.9
    # ego-compensated Doppler of the static world: within a velocity bin (0.17 m/s) mostly
    assert np.median(p.velocity_over_ground_mps.abs()) < 0.1
    assert p["static"].mean() > 0.9
    # the world frame follows the turning pose: same points in the vehicle frame
    pose = ego_pose(sc, group, p.time_s.to_numpy())
    c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
    xv = c * (p.x_m - pose[:, 0]) + s * (p.y_m - pose[:, 1])
    np.testing.assert_allclose(xv, p.x_vehicle_m, atol=1e-9)


@pytest.mark.slow   # the first measured batch pays MUSIC's warm-up (33 s at load 9)
def test_the_pedestrians_points_are_near_its_truth(turning_frames):
    sc, group, _, res, _ = turning_frames
    tr = scene_truth(sc, group, 0.1)
    own = res.points[res.points.source == "p0"].merge(tr[["frame", "x_m", "y_m"]], on="frame",
                                                      suffixes=("", "_t"))
    assert len(own) >= 2
    assert np.median(np.hypot(own.x_m - own.x_m_t, own.y_m - own.y_m_t)) < 1.0


def test_ego_motion_metrics_keep_the_speed_keys_and_gain_the_yaw_rate():
    rows = []
    for yaw in (0.0, 10.0):
        for kmh in (10.0, 60.0):
            rows.append(pd.DataFrame({
                "speed_kmh": kmh, "true_yaw_rate_deg_s": yaw, "error_mps": [0.03, -0.04],
                "odometry_error_mps": [0.3, 0.3], "yaw_rate_error_deg_s": [0.6, -0.8],
                "yaw_rate_sd_theory_deg_s": [0.5, 0.5], "speed_sd_theory_mps": [0.02, 0.02]}))
    m = ego_motion_metrics(pd.concat(rows, ignore_index=True))
    assert m["rms_error_mps"] == {"10": pytest.approx(0.05 / np.sqrt(2)),
                                  "60": pytest.approx(0.05 / np.sqrt(2))}
    assert m["rms_error_yaw_rate_deg_s"]["60"] == pytest.approx(np.sqrt(0.5))
    assert m["yaw_rate_sd_theory_deg_s"]["10"] == 0.5 and m["yaw_rate_deg_s"] == 10.0
