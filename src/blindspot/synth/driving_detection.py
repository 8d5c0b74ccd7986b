"""Driving scenes through the full FMCW simulator and the moving-car detection chain.

Each frame of a :class:`~blindspot.radar.driving.DrivingScene` is simulated at its time
(``blindspot.radar.driving.scatterers_in_vehicle_frame``: static world moving at -v_ego relative
to the radar, pedestrians' body parts, occlusion by the parked cars) with the noise stream
(scene seed, frame), and processed by :class:`blindspot.dsp.driving.DrivingChain` in batches.
Odometry readings (true speed + bias + noise, ``ego_motion`` group) are drawn from the scene's
seed. Detections get world coordinates from the ego pose.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from blindspot.dsp.driving import DrivingBatch, DrivingChain
from blindspot.dsp.ego_motion import EgoMotionConfig, odometry_speed
from blindspot.radar.array import array_for
from blindspot.radar.config import RadarConfig, SimConfig
from blindspot.radar.driving import (
    DrivingScene, ScenarioGroup, ego_pose, frame_times, scatterers_in_vehicle_frame,
    vehicle_to_world,
)
from blindspot.radar.simulator import FmcwSimulator, frame_bit_generator

BATCH_FRAMES = 4


@dataclass
class DrivingDetections:
    """detections: the chain's columns + scene, time_s, x_m, y_m (world frame);
    ego: per frame + scene, time_s, true_speed_mps; kept: the batch holding ``keep_frame``
    with its maps (or None) and that frame's row in it."""

    detections: pd.DataFrame
    ego: pd.DataFrame
    kept: DrivingBatch | None
    kept_index: int | None


def simulate_frame(scene: DrivingScene, group: ScenarioGroup, simulator: FmcwSimulator,
                   t: float, frame: int) -> np.ndarray:
    """complex64 (chirps, tx, rx, samples) of one driving frame (noise stream (seed, frame))."""
    pos, vel, rcs, att, _ = scatterers_in_vehicle_frame(scene, group, t)
    bits = frame_bit_generator(scene.seed, frame) if simulator.noise else None
    return simulator.frame(pos, vel, rcs, att, bit_generator=bits)


def detect_driving_scene(scene: DrivingScene, group: ScenarioGroup, radar: RadarConfig,
                         cfar, doa, detect, ego: EgoMotionConfig, sim: SimConfig, *,
                         frames: np.ndarray | None = None, keep_frame: int | None = None,
                         progress: bool = False) -> DrivingDetections:
    """Simulate and detect the given frames (default all) of a driving scene."""
    from tqdm.auto import tqdm

    times = frame_times(scene, radar.frame_period_s)
    idx = np.arange(len(times)) if frames is None else np.asarray(frames, dtype=np.int64)
    if idx.size and (idx.min() < 0 or idx.max() >= len(times)):
        raise ValueError(f"frames {idx.min()}..{idx.max()} outside scene {scene.name!r} "
                         f"(0..{len(times) - 1})")
    array = array_for(radar)
    chain = DrivingChain(radar, array, cfar, doa, detect, ego)
    simulator = FmcwSimulator(radar, array, noise=sim.noise, adc_headroom_db=sim.adc_headroom_db)
    rng = np.random.default_rng(np.random.SeedSequence([scene.seed, 21]))
    odo_all = odometry_speed(np.full(len(times), scene.speed_mps), ego.odometry_noise_mps,
                             ego.odometry_bias_mps, rng)
    dets, egos, kept, kept_i = [], [], None, None
    for lo in tqdm(range(0, len(idx), BATCH_FRAMES), disable=not progress, desc=scene.name):
        batch = idx[lo:lo + BATCH_FRAMES]
        cubes = np.stack([simulate_frame(scene, group, simulator, times[i], int(i)) for i in batch])
        want = keep_frame is not None and keep_frame in batch
        res = chain.process_batch(cubes, odo_all[batch], batch, keep_maps=want)
        if want:
            kept, kept_i = res, int(np.flatnonzero(batch == keep_frame)[0])
        dets.append(res.detections)
        egos.append(res.ego)
    det = pd.concat(dets, ignore_index=True)
    ego_t = pd.concat(egos, ignore_index=True)
    pose = ego_pose(scene, group, times)
    f = det["frame"].to_numpy()
    world = vehicle_to_world(det[["x_vehicle_m", "y_vehicle_m"]].to_numpy(), pose[f])
    det = det.assign(scene=scene.name, time_s=times[f], x_m=world[:, 0], y_m=world[:, 1])
    ego_t = ego_t.assign(scene=scene.name, time_s=times[ego_t["frame"].to_numpy()],
                         true_speed_mps=scene.speed_mps)
    return DrivingDetections(det, ego_t, kept, kept_i)
