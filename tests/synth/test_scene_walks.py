"""Randomised walks of the paper's scene: the scene model's own walk and occlusion, the ranges
drawn, a random stream apart from the training paths', and the radar's points of a hidden walk."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from omegaconf import OmegaConf

from blindspot.radar.config import RadarConfig
from blindspot.radar.occlusion import segment_crosses_polygon, segment_crosses_polygons
from blindspot.radar.scene import load_scenes, walk, walks
from blindspot.synth.path_measurement import PedestrianModel
from blindspot.synth.scene_walks import (BENCHMARK_STREAM, WalksConfig, draw_scene_walks,
                                         measure_scene_walks)
from blindspot.typed_config import ConfigError

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def bench() -> WalksConfig:
    return WalksConfig.from_mapping(OmegaConf.load(REPO / "conf/walks/scene_walks.yaml"))


@pytest.fixture(scope="module")
def scenes():
    return load_scenes(OmegaConf.load(REPO / "conf/scene/paper.yaml"))


def test_batched_walks_are_the_scene_models_walks(scenes):
    """Every paper scene's walk (straight, +-45 deg arcs) from one batched call, to the bit."""
    t = np.arange(100) * 0.1
    peds = [s.pedestrian for s in scenes.values()]
    w = walks(np.array([p.start_xy_m for p in peds]), np.array([p.direction_xy for p in peds]),
              np.array([p.speed_mps for p in peds]), np.array([p.turn_after_m for p in peds]),
              np.radians([p.turn_deg for p in peds]), np.array([p.turn_radius_m for p in peds]), t)
    for i, p in enumerate(peds):
        one = walk(p, t)
        for a, b in zip(w, one):
            np.testing.assert_array_equal(a[i], b)


def test_walk_geometry_speed_and_turn(bench):
    """Constant speed along the path; the heading turns by the drawn angle (counter-clockwise
    positive), so the final heading is the initial one rotated by turn_deg."""
    w = draw_scene_walks(replace(bench, n_walks=40), 0.1, seed=3)
    step = np.linalg.norm(np.diff(w.truth, axis=1), axis=-1) / 0.1
    np.testing.assert_allclose(step, np.broadcast_to(w.speed_mps[:, None], step.shape),
                               rtol=1e-2)                              # chords on the arc
    assert np.isclose(step, w.speed_mps[:, None], rtol=1e-9).mean() > 0.9  # straight: exact
    assert np.all((w.speed_mps >= 1.0) & (w.speed_mps <= 1.5))
    assert np.all(np.abs(w.turn_deg) <= 60.0)
    d0 = w.truth[:, 1] - w.truth[:, 0]
    d1 = w.truth[:, -1] - w.truth[:, -2]
    turned = np.degrees(np.arctan2(d0[:, 0] * d1[:, 1] - d0[:, 1] * d1[:, 0],
                                   (d0 * d1).sum(axis=1)))
    np.testing.assert_allclose(turned, w.turn_deg, atol=1e-6)


def test_every_walk_is_seen_hidden_and_seen_again_before_its_prediction(bench):
    w = draw_scene_walks(bench, 0.1, seed=0)
    frames = np.arange(w.truth.shape[1])[None, :]
    past = frames < w.start[:, None]
    assert not w.hidden[:, :3].any()                       # in sight at the start (paper ~0.7 s)
    assert (w.hidden & past).sum(axis=1).min() >= 20       # hidden for >= 2 s
    last_hidden = w.truth.shape[1] - 1 - np.argmax(w.hidden[:, ::-1], axis=1)
    assert np.all(last_hidden + 5 < w.start)               # reappears >= 0.5 s before the start
    assert np.all(w.turn_frame > last_hidden)              # turns after stepping out
    # the occlusion flags are the scene module's own test, walk by walk
    for i in range(0, len(w), 37):
        np.testing.assert_array_equal(w.hidden[i], segment_crosses_polygon(w.truth[i], w.car[i]))
    np.testing.assert_array_equal(segment_crosses_polygons(w.truth, w.car), w.hidden)
    # cars are rectangles of the drawn size
    sides = np.linalg.norm(np.diff(w.car, axis=1, append=w.car[:, :1]), axis=-1)
    assert np.all((sides[:, 0] >= 1.7 - 1e-9) & (sides[:, 0] <= 1.9 + 1e-9))
    assert np.all((sides[:, 1] >= 4.0 - 1e-9) & (sides[:, 1] <= 5.0 + 1e-9))


def test_benchmark_streams_are_apart_from_the_training_paths():
    """The training paths draw from SeedSequence(seed) and its chunk seeds; the benchmark's walks
    and radar noise from SeedSequence([seed, BENCHMARK_STREAM]): no shared state."""
    for seed in range(5):
        train = set(np.random.SeedSequence(seed).generate_state(400, dtype=np.uint32).tolist())
        noise = int(np.random.SeedSequence([seed, BENCHMARK_STREAM, 1])
                    .generate_state(1, dtype=np.uint32)[0])
        bench = set(np.random.SeedSequence(noise).generate_state(400, dtype=np.uint32).tolist())
        assert noise not in train and not train & bench
        a = np.random.default_rng(np.random.SeedSequence(seed)).random(8)
        b = np.random.default_rng(np.random.SeedSequence([seed, BENCHMARK_STREAM])).random(8)
        assert not np.isclose(a[:, None], b[None, :]).any()


def test_a_bad_benchmark_setting_names_its_key(bench):
    with pytest.raises(ConfigError, match="speed_mps"):
        WalksConfig.from_mapping({**OmegaConf.to_container(
            OmegaConf.load(REPO / "conf/walks/scene_walks.yaml")), "speed_mps": [1.5, 1.0]})
    with pytest.raises(ConfigError, match="car_center_x_m"):
        replace(bench, car_center_x_m=(0.6, 1.0))


@pytest.mark.slow   # ~7 s on an idle machine; the tiny stage test measures walks in the default run
def test_the_radar_loses_the_pedestrian_behind_the_car(bench, scenes):
    """Four walks through the reduced radar chain with the car as occluder: points while in
    sight, (almost) none while hidden (50 dB, paper Fig. 7), none from the prediction start."""
    radar = RadarConfig.from_mapping(OmegaConf.load(REPO / "conf/radar/mmwcas.yaml"))
    groups = {g: OmegaConf.to_container(OmegaConf.load(REPO / f"conf/{g}/{o}.yaml"))
              for g, o in (("cfar", "paper"), ("doa", "music"), ("detect", "paper"))}
    car = scenes["straight_car"]
    w = draw_scene_walks(replace(bench, n_walks=4), radar.frame_period_s, seed=0)
    xy = measure_scene_walks(w, radar, groups["cfar"], groups["doa"], groups["detect"],
                             pedestrian=PedestrianModel.from_scene(car),
                             occlusion_db=car.occlusion_db, seed=0)
    seen = np.isfinite(xy[..., 0])
    past = np.arange(xy.shape[1])[None, :] < w.start[:, None]
    assert not seen[~past].any()
    assert seen[past & ~w.hidden].mean() > 0.7
    assert seen[past & w.hidden].mean() < 0.2
    err = np.linalg.norm(xy - w.truth, axis=-1)[seen]
    assert np.median(err) < 0.3
