"""Paths through the radar chain: the walker model, and the reduced chain against the full one."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from omegaconf import OmegaConf

from blindspot.dsp.path_measurement import (
    PedestrianModel,
    body_scatterers,
    path_kinematics,
    point_scatterers,
)
from blindspot.radar.config import RadarConfig
from blindspot.radar.scene import Scene, load_scenes, walk

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def radar() -> RadarConfig:
    return RadarConfig.from_mapping(OmegaConf.load(REPO / "conf" / "radar" / "mmwcas.yaml"))


@pytest.fixture(scope="module")
def scenes():
    return load_scenes(OmegaConf.load(REPO / "conf" / "scene" / "paper.yaml"))


@pytest.mark.parametrize("name", ["straight_nocar", "approach_nocar"])
def test_body_matches_the_scene_model(scenes, name):
    """On the scene's own route (straight, and through the 45 deg arc) the detached walker puts
    every body part where the scene model does, with the same velocity."""
    cfg = scenes[name]
    scene = Scene(cfg)
    t = np.linspace(0.0, 9.9, 100)
    pos_ref, vel_ref, w = scene.pedestrian_parts_at(t)
    model = PedestrianModel.from_scene(cfg)
    gait = 2 * np.pi * cfg.pedestrian.speed_mps * t / cfg.pedestrian.stride_length_m
    pos, vel = body_scatterers(w.position_m, w.velocity_mps, w.turn_rate_rps, gait, model)
    np.testing.assert_allclose(pos, pos_ref, atol=1e-12)
    np.testing.assert_allclose(vel, vel_ref, atol=1e-12)


def test_path_kinematics_of_a_circle():
    """Constant speed on a circle: speed, turn rate = v / r (counter-clockwise), distance."""
    r, v, dt = 5.0, 1.2, 0.1
    t = np.arange(200) * dt
    phi = v * t / r
    xy = np.stack([r * np.cos(phi), r * np.sin(phi)], axis=-1)[None]
    vel, turn, dist = path_kinematics(xy, dt)
    np.testing.assert_allclose(np.linalg.norm(vel, axis=-1), v, rtol=2e-3)
    np.testing.assert_allclose(turn, v / r, rtol=5e-3)
    np.testing.assert_allclose(dist[0, -1], v * t[-1], rtol=1e-3)
    with pytest.raises(ValueError, match="finite"):
        path_kinematics(np.where(np.arange(200)[None, :, None] == 3, np.nan, xy), dt)


def test_point_scatterers_radar_equation(radar):
    """Amplitude^2 is the radar-equation power; direction and radial velocity from geometry."""
    pos = np.array([[[3.0, 4.0, 0.0], [0.0, 10.0, 1.0]]])
    vel = np.array([[[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]])
    sc = point_scatterers(pos, vel, np.array([1.0, 0.5]), radar)
    lam = radar.wavelength_m
    p_t = 1e-3 * 10 ** (radar.tx_power_dbm / 10)
    g = 10 ** ((radar.tx_gain_dbi + radar.rx_gain_dbi) / 10)
    expected = p_t * g * lam**2 * 1.0 / ((4 * np.pi) ** 3 * 5.0**4)
    assert abs(sc.amplitude[0, 0]) ** 2 == pytest.approx(expected, rel=1e-12)
    assert sc.range_m[0, 1] == pytest.approx(np.sqrt(101.0))
    assert sc.velocity_mps[0, 0] == pytest.approx(0.8)
    assert np.degrees(sc.azimuth_rad[0, 0]) == pytest.approx(np.degrees(np.arctan2(3, 4)))
    assert sc.velocity_mps[0, 1] == pytest.approx(0.0)
