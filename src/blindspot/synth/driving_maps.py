"""A driving scene's artifacts for the scene you can watch (issue 44): its rows of the pipeline's
outputs, the predicted paths of its tracks and the range-Doppler maps of chosen frames.

The frames are simulated exactly as :func:`blindspot.synth.driving_detection.detect_driving_scene`
simulates them (:func:`~blindspot.synth.driving_detection.simulate_frame`, the scene's noise
stream per frame), so a kept map is the one the detections of that frame came from; only the
frames asked for are simulated (a decimated subset: the full simulator costs about a second a
frame on one core).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig, EgoMotionConfig
from blindspot.dsp.driving import DrivingChain
from blindspot.radar.array import array_for
from blindspot.radar.config import RadarConfig, SimConfig
from blindspot.radar.driving import frame_times
from blindspot.radar.scenario import load_scenarios
from blindspot.radar.simulator import FmcwSimulator
from blindspot.safety.recording import predict_tracks
from blindspot.synth.driving_detection import BATCH_FRAMES, simulate_frame
from blindspot.traj.baselines import kalman_baseline
from blindspot.traj.calibration import from_record
from blindspot.traj.config import EvalConfig

__all__ = ["SceneToWatch", "driving_scene_maps", "scene_to_watch"]


def driving_scene_maps(scene, group, radar, cfar, doa, detect, ego, sim, frames,
                       *, progress: bool = False) -> dict:
    """The detection maps of ``frames`` of ``scene``: ``{"frame": (n,), "power": (n, R, D)
    float32 (|X|^2 after the chain's integration), "range_axis_m": (R,),
    "velocity_axis_mps": (D,)}``. Raises ValueError for a frame outside the scene."""
    from tqdm.auto import tqdm

    times = frame_times(scene, radar.frame_period_s)
    idx = np.unique(np.asarray(frames, dtype=np.int64))
    if idx.size and (idx.min() < 0 or idx.max() >= len(times)):
        raise ValueError(f"frames {idx.min()}..{idx.max()} outside scene {scene.name!r} "
                         f"(0..{len(times) - 1})")
    array = array_for(radar)
    chain = DrivingChain(radar, array, cfar, doa, detect, ego,
                         rear_axle_to_radar_m=group.ego.rear_axle_to_radar_m)
    simulator = FmcwSimulator(radar, array, noise=sim.noise, adc_headroom_db=sim.adc_headroom_db)
    power = []
    for lo in tqdm(range(0, len(idx), BATCH_FRAMES), disable=not progress, desc=scene.name):
        batch = idx[lo:lo + BATCH_FRAMES]
        cubes = np.stack([simulate_frame(scene, group, simulator, times[i], int(i)) for i in batch])
        res = chain.process_batch(cubes, np.full(len(batch), scene.speed_mps), batch,
                                  keep_maps=True)
        power.append(np.asarray(res.power, np.float32))
    n_range = power[0].shape[1] if power else 0
    return {"frame": idx,
            "power": np.concatenate(power) if power else np.zeros((0, 0, 0), np.float32),
            "range_axis_m": np.asarray(radar.range_axis_m()[:n_range]),
            "velocity_axis_mps": np.asarray(radar.velocity_axis_mps())}


@dataclass
class SceneToWatch:
    """One driving scene's artifacts for its animation (:func:`scene_to_watch`)."""

    name: str
    title: str
    truth: pd.DataFrame
    cars: list
    points: pd.DataFrame
    tracks: pd.DataFrame
    predictions: pd.DataFrame
    outcomes: pd.DataFrame | None
    rd: dict
    ego_size_m: tuple[float, float]


def scene_to_watch(cfg, paths: dict, *, progress: bool = False) -> SceneToWatch:
    """The driving scene ``cfg.watch.scene`` at ``cfg.watch.ego_speed_kmh`` from the pipeline's
    artifacts (``paths``: truth, scenes (scenes.json), points, tracks (driving_track), models
    (calibration records), outcomes (safety's scene_outcomes)): its rows of each, every moving
    track's predicted path with the calibrated distribution of ``cfg.watch.predictor``
    (:func:`blindspot.safety.recording.predict_tracks`, ``warning.horizon_s`` ahead) and the
    range-Doppler maps of every ``cfg.watch.rd_every``-th frame (:func:`driving_scene_maps`).
    Raises ValueError naming the keys for a scene that is not a named one at that speed."""
    w = cfg.watch           # the watch stage has typed it (blindspot.report.animation.WatchConfig)
    group, named = load_scenarios(cfg.scenario)
    meta = json.loads(Path(paths["scenes"]).read_text())
    if w.scene not in named or w.scene not in meta or abs(
            meta[w.scene]["speed_kmh"] - w.ego_speed_kmh) > 1e-6:
        raise ValueError(f"config keys 'watch.scene' = {w.scene!r}, 'watch.ego_speed_kmh' = "
                         f"{w.ego_speed_kmh}: expected a named driving scene at its speed, one "
                         f"of {[(n, meta[n]['speed_kmh']) for n in named if n in meta]}")
    radar = RadarConfig.from_cfg(cfg, "driving_radar")
    dt, sel = float(radar.frame_period_s), [("scene", "==", w.scene)]
    truth = pd.read_parquet(paths["truth"], filters=sel)
    tracks = pd.read_parquet(paths["tracks"], filters=[("group", "==", w.scene)])
    records = json.loads(Path(paths["models"]).read_text())
    if w.predictor not in records:
        raise ValueError(f"config key 'watch.predictor' = {w.predictor!r}: no calibration "
                         f"record in {Path(paths['models']).name} ({sorted(records)})")
    pred = from_record(records[w.predictor], kalman_baseline(EvalConfig.from_cfg(cfg), dt),
                       w.predictor)
    predictions, _, _ = predict_tracks(tracks, pred, int(round(cfg.warning.horizon_s / dt)), dt,
                                       int(round(cfg.warning.max_history_s / dt)),
                                       max_coast_s=cfg.warning.max_coast_s)
    rd = driving_scene_maps(named[w.scene], group, radar, CfarConfig.from_cfg(cfg, "driving_cfar"),
                            DoaConfig.from_cfg(cfg), DetectConfig.from_cfg(cfg),
                            EgoMotionConfig.from_cfg(cfg), SimConfig.from_cfg(cfg),
                            np.sort(truth.frame.unique())[::int(w.rd_every)], progress=progress)
    outcomes = (pd.read_parquet(paths["outcomes"], filters=sel)
                if Path(paths["outcomes"]).is_file() else None)
    return SceneToWatch(f"{w.scene}_{w.ego_speed_kmh:g}kmh",
                        f"{w.scene} at {w.ego_speed_kmh:g} km/h", truth,
                        meta[w.scene]["car_polygons_xy_m"],
                        pd.read_parquet(paths["points"], filters=sel), tracks, predictions,
                        outcomes, rd, (group.ego.width_m, group.ego.length_m))
