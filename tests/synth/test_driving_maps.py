"""The driving scene to watch (issue 44): its range-Doppler maps are the ones the detection
stage's frames give, and scene_to_watch gathers a scene's artifacts, predicts its moving tracks
and refuses a scene that is not there (tiny profile: 19 frames)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from blindspot import config
from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig, EgoMotionConfig
from blindspot.radar.config import RadarConfig, SimConfig
from blindspot.radar.driving import car_polygons, scene_truth
from blindspot.radar.scenario import load_scenarios
from blindspot.synth.driving_detection import detect_driving_scene
from blindspot.synth.driving_maps import driving_scene_maps, scene_to_watch
from blindspot.track.config import TrackerConfig
from blindspot.track.tracker import track_points

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def tiny():
    cfg = config.compose(["profile=tiny", "watch.rd_every=12"], config_dir=REPO / "conf")
    group, named = load_scenarios(cfg.scenario)
    radar = RadarConfig.from_cfg(cfg, "driving_radar")
    chain = (CfarConfig.from_cfg(cfg, "driving_cfar"), DoaConfig.from_cfg(cfg),
             DetectConfig.from_cfg(cfg), EgoMotionConfig.from_cfg(cfg), SimConfig.from_cfg(cfg))
    return cfg, group, named, radar, chain


def test_a_kept_map_is_the_detection_stages_map_of_that_frame(tiny):
    cfg, group, named, radar, chain = tiny
    scene = named[group.figure_scene]
    maps = driving_scene_maps(scene, group, radar, *chain, [9])
    ref = detect_driving_scene(scene, group, radar, *chain, frames=[9], keep_frame=9)
    np.testing.assert_allclose(maps["power"][0], ref.kept.power[ref.kept_index], rtol=1e-6)
    assert maps["power"].shape[1:] == (len(maps["range_axis_m"]), len(maps["velocity_axis_mps"]))
    with pytest.raises(ValueError, match="outside scene"):
        driving_scene_maps(scene, group, radar, *chain, [10_000])


def test_scene_to_watch_gathers_the_scene_and_predicts_its_moving_tracks(tiny, tmp_path):
    cfg, group, named, radar, _ = tiny
    scene = named["cpnco"]
    truth = scene_truth(scene, group, radar.frame_period_s).assign(scene="cpnco")
    truth.to_parquet(tmp_path / "truth.parquet")
    (tmp_path / "scenes.json").write_text(json.dumps({"cpnco": {
        "speed_kmh": scene.speed_kmh, "car_polygons_xy_m": car_polygons(scene).tolist()}}))
    p0 = truth[(truth.pedestrian == "p0") & ~truth.occluded]
    pts = pd.DataFrame({"scene": "cpnco", "frame": p0.frame, "time_s": p0.time_s,
                        "x_m": p0.x_m, "y_m": p0.y_m, "static": False})
    pts.to_parquet(tmp_path / "points.parquet")
    tracks = track_points(pts.rename(columns={"scene": "group"}).drop(columns="static"),
                          TrackerConfig.from_cfg(cfg))
    tracks.assign(moving=True, extra_column=1.0).to_parquet(tmp_path / "tracks.parquet")
    (tmp_path / "models.json").write_text(json.dumps({"kalman": {"noise": None,
                                                                 "scale": [1.0] * 40}}))
    paths = {k: tmp_path / f for k, f in (
        ("truth", "truth.parquet"), ("scenes", "scenes.json"), ("points", "points.parquet"),
        ("tracks", "tracks.parquet"), ("models", "models.json"),
        ("outcomes", "scene_outcomes.parquet"))}          # no outcomes: no decision drawn
    s = scene_to_watch(cfg, paths)
    assert s.name == "cpnco_30kmh" and s.outcomes is None and len(s.rd["frame"]) == 2
    assert len(s.predictions) and s.predictions.track_id.isin(tracks.track_id).all()
    steps = s.predictions.step.max()
    assert steps == round(cfg.warning.horizon_s / radar.frame_period_s)
    bad = config.compose(["profile=tiny", "watch.ego_speed_kmh=50"], config_dir=REPO / "conf")
    with pytest.raises(ValueError, match="watch.ego_speed_kmh' = 50"):
        scene_to_watch(bad, paths)
