"""The fast measurement of driving scenes: every pedestrian of every frame of many scenes through
the reduced chain of :mod:`blindspot.synth.path_measurement` (analytic range-Doppler patches
around the pedestrian, the chain's own CFAR, snapshots with the FFTs' noise statistics), with
the moving-car steps of :class:`blindspot.dsp.driving.DrivingChain`: every detection in the
angle budget gets its Doppler ambiguity order chosen with the odometry speed (candidate orders,
TDM compensation with the unwrapped velocity, MUSIC, the order whose velocity lies nearest the
static world's at its own angle), and the detections off the static world's Doppler curve by
more than ``static_tolerance_mps`` are grouped into the pedestrian's point
(:func:`blindspot.dsp.points.group_points`).

Approximations beyond those of the reduced chain (see ``measure_paths``): (1) each pedestrian
is measured in its own patch (no other scatterer in its cells: the static world's returns lie on
the ego-motion Doppler curve, elsewhere in the map, unless at the same range and Doppler);
(2) the static test uses the true ego speed (the full chain uses its RANSAC estimate, within
0.1 m/s RMS, well inside the 0.35 m/s tolerance); (3) occlusion by the parked cars attenuates
each body part by ``occlusion_db`` (as in the full simulation). Validated against the full FMCW
simulation of the same frames (tests/synth/test_driving_measurement.py, slow;
``benchmarks/bench_driving.py`` prints both statistics).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from blindspot.dsp.chain import DetectionChain
from blindspot.dsp.driving import unwrap_and_angles
from blindspot.dsp.ego_motion import odometry_speed, static_radial_velocity
from blindspot.dsp.points import group_points
from blindspot.radar.array import array_for
from blindspot.radar.config import RadarConfig
from blindspot.radar.driving import (
    DrivingScene, ScenarioGroup, body_parts, car_polygons, ego_pose, frame_times,
    vehicle_to_world, world_to_vehicle,
)
from blindspot.radar.occlusion import segments_blocked
from blindspot.synth.path_measurement import (
    _reduced_detections, _reduced_setup, _reduced_snapshots, point_scatterers,
)

MEASURED_COLUMNS = ("scene", "pedestrian", "frame", "time_s", "range_m", "angle_deg",
                    "velocity_mps", "snr_db", "n_detections", "x_vehicle_m", "y_vehicle_m",
                    "x_m", "y_m")


def _frames_of(scene: DrivingScene, group: ScenarioGroup, radar: RadarConfig, max_range_m: float,
               frames: np.ndarray | None):
    """Every pedestrian's body parts at the scene's frames, relative to the radar, with the
    occlusion loss: rows (frame, pedestrian) inside the field of view and the range window."""
    t = frame_times(scene, radar.frame_period_s)
    idx = np.arange(len(t)) if frames is None else np.asarray(frames, dtype=np.int64)
    t = t[idx]
    pose = ego_pose(scene, group, t)                                     # (F, 3)
    pos, vel, rcs, who = body_parts(scene, group, t)                      # (F, Q, 3)
    rel = world_to_vehicle(pos[..., :2], pose[:, None, :])
    c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
    dv = vel[..., :2] - (np.stack([-s, c], -1) * scene.speed_mps)[:, None, :]
    rel_v = np.stack([c[:, None] * dv[..., 0] + s[:, None] * dv[..., 1],
                      -s[:, None] * dv[..., 0] + c[:, None] * dv[..., 1]], -1)
    r = np.linalg.norm(rel, axis=-1, keepdims=True)
    short = pos[..., :2] - (pos[..., :2] - pose[:, None, :2]) * (1e-3 / np.maximum(r, 1e-9))
    hidden = segments_blocked(short, pose[:, None, :2], car_polygons(scene))      # (F, Q)
    att = np.where(hidden, group.occlusion_db, 0.0)
    xyz = np.concatenate([rel, pos[..., 2:]], -1)
    v3 = np.concatenate([rel_v, np.zeros_like(pos[..., 2:])], -1)
    out = []
    for p in range(len(scene.pedestrians)):   # a few pedestrians per scene
        q = who == p
        rng = np.linalg.norm(xyz[:, q, :2], axis=-1).mean(1)
        az = np.degrees(np.arctan2(rel[:, q, 0], rel[:, q, 1])).mean(1)
        ok = (rel[:, q, 1].min(1) > 0.2) & (np.abs(az) < 75) & (rng < max_range_m - 2)
        out.append((p, idx[ok], t[ok], pose[ok], xyz[ok][:, q], v3[ok][:, q], rcs[q], att[ok][:, q]))
    return out


def measure_driving_scenes(scenes: list[DrivingScene], group: ScenarioGroup, radar: RadarConfig,
                           cfar, doa, detect, ego, *, adc_headroom_db: float = 60.0,
                           frames: dict[str, np.ndarray] | None = None,
                           rows_per_batch: int = 512, progress: bool = False) -> pd.DataFrame:
    """The measured point of every pedestrian in every frame (where the chain finds one) of
    ``scenes``, by the reduced chain with the moving-car steps (module docstring).

    Args:
        scenes, group: driving scenes and their ``scenario`` group.
        radar: the driving profile; cfar, doa, detect: the chain's groups; ego: the
            ``ego_motion`` group (odometry model, budget, range, static tolerance, seed).
        frames: optional {scene name: frame indices} to measure (default every frame).
        rows_per_batch: (frame, pedestrian) rows processed together.

    Returns:
        DataFrame ``MEASURED_COLUMNS``: one row per (scene, pedestrian, frame) with a point
        (nothing is invented where the chain finds none); x_m, y_m in the world frame.
    """
    from tqdm.auto import tqdm

    from dataclasses import replace

    array = array_for(radar)
    base = DetectionChain.from_config(radar, array, cfar, doa, detect)
    chain = DetectionChain(radar, array, base.cfar, base.doa,
                           replace(base.detect, max_range_m=ego.max_range_m,
                                   max_detections=ego.max_detections))
    setup = _reduced_setup(chain, 8, adc_headroom_db)
    vmax = radar.max_velocity_mps
    # gather all rows
    rows = []
    for si, sc in enumerate(scenes):
        odo = odometry_speed(np.full(1, sc.speed_mps), ego.odometry_noise_mps,
                             ego.odometry_bias_mps,
                             np.random.default_rng(np.random.SeedSequence([sc.seed, 21])))
        sel = None if frames is None else frames.get(sc.name)
        for p, fidx, t, pose, xyz, v3, rcs, att in _frames_of(sc, group, radar, ego.max_range_m, sel):
            rows.append((si, p, fidx, t, pose, xyz, v3, rcs, att,
                         np.full(len(fidx), sc.speed_mps), np.full(len(fidx), odo[0])))
    if not rows:
        return pd.DataFrame(columns=list(MEASURED_COLUMNS))
    # one flat table of rows; the scatterer count differs between bodies: pad with zero amplitude
    n_s = max(r[5].shape[1] for r in rows)
    cat = lambda k: np.concatenate([r[k] for r in rows])  # noqa: E731
    meta_scene = np.concatenate([np.full(len(r[2]), r[0]) for r in rows])
    meta_ped = np.concatenate([np.full(len(r[2]), r[1]) for r in rows])
    fidx, t, pose, speed, odo = cat(2), cat(3), cat(4), cat(9), cat(10)

    def pad(a, fill=0.0):
        return np.concatenate([np.pad(r_a, [(0, 0), (0, n_s - r_a.shape[1])] + [(0, 0)] * (r_a.ndim - 2),
                                      constant_values=fill) for r_a in a])

    xyz = pad([r[5] for r in rows], 1.0)
    v3 = pad([r[6] for r in rows])
    att = pad([r[8] for r in rows], 400.0)          # padding: no signal
    rcs = pad([np.broadcast_to(r[7], r[8].shape) for r in rows], 1e-30)
    n = len(fidx)
    out = {k: np.full(n, np.nan) for k in ("range_m", "angle_deg", "velocity_mps", "snr_db")}
    out["n_detections"] = np.zeros(n, dtype=np.int64)
    gap, tol = chain.detect.cluster_gap_m, ego.static_tolerance_mps
    for b, lo in enumerate(tqdm(range(0, n, rows_per_batch), disable=not progress,
                                desc="driving scenes (fast)")):
        hi = min(lo + rows_per_batch, n)
        sc = point_scatterers(xyz[lo:hi], v3[lo:hi], rcs[lo:hi], radar,
                              output_scale=setup.output_scale)
        amp = sc.amplitude * 10 ** (-att[lo:hi] / 20)
        sc = type(sc)(sc.range_m, sc.velocity_mps, sc.azimuth_rad, amp, sc.elevation_rad)
        rng = np.random.default_rng(np.random.SeedSequence([ego.seed, 31, b]))
        red = _reduced_detections(setup, sc, rng)
        keep = chain.doa_budget(red.bi)
        sel = np.flatnonzero(keep)
        if not sel.size:
            continue
        x = _reduced_snapshots(setup, red, sel, rng)
        bi = red.bi[sel]
        v_w = chain.velocity_axis_mps[red.di[sel]]
        _, v, angle = unwrap_and_angles(x, v_w, odo[lo:hi][bi], chain, vmax)
        off = v - static_radial_velocity(np.nan_to_num(angle), 1.0) * speed[lo:hi][bi]
        rng_m = chain.range_axis_m[np.clip(red.first[bi] + red.ki[sel], 0, chain.range_axis_m.size - 1)]
        pts = group_points(bi, rng_m, off, angle, red.snr_db[sel], tol, gap)
        f = pts["frame"] + lo
        for k in ("range_m", "angle_deg", "snr_db", "n_detections"):
            out[k][f] = pts[k]
        # the point's velocity: its off-curve velocity back on the radial axis
        out["velocity_mps"][f] = pts["velocity_mps"] + static_radial_velocity(
            pts["angle_deg"], 1.0) * speed[f]
    ok = np.isfinite(out["range_m"])
    th = np.radians(out["angle_deg"])
    xv, yv = out["range_m"] * np.sin(th), out["range_m"] * np.cos(th)
    world = vehicle_to_world(np.stack([xv, yv], -1), pose)
    df = pd.DataFrame({
        "scene": [scenes[i].name for i in meta_scene],
        "pedestrian": [scenes[i].pedestrians[p].name for i, p in zip(meta_scene, meta_ped)],
        "frame": fidx, "time_s": t, **out, "x_vehicle_m": xv, "y_vehicle_m": yv,
        "x_m": world[:, 0], "y_m": world[:, 1]}, columns=list(MEASURED_COLUMNS))
    return df[ok].reset_index(drop=True)
