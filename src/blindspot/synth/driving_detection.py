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
    chain = DrivingChain(radar, array, cfar, doa, detect, ego,
                         rear_axle_to_radar_m=group.ego.rear_axle_to_radar_m)
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
    from blindspot.dsp.driving import DRIVING_DETECTION_COLUMNS, EGO_COLUMNS

    det = (pd.concat(dets, ignore_index=True) if dets
           else pd.DataFrame(columns=list(DRIVING_DETECTION_COLUMNS)).astype({"frame": np.int64}))
    ego_t = (pd.concat(egos, ignore_index=True) if egos
             else pd.DataFrame(columns=list(EGO_COLUMNS)).astype({"frame": np.int64}))
    pose = ego_pose(scene, group, times)
    f = det["frame"].to_numpy()
    world = vehicle_to_world(det[["x_vehicle_m", "y_vehicle_m"]].to_numpy(), pose[f])
    det = det.assign(scene=scene.name, time_s=times[f], x_m=world[:, 0], y_m=world[:, 1])
    ego_t = ego_t.assign(scene=scene.name, time_s=times[ego_t["frame"].to_numpy()],
                         true_speed_mps=scene.speed_mps,
                         true_yaw_rate_deg_s=scene.yaw_rate_deg_s)
    return DrivingDetections(det, ego_t, kept, kept_i)


def ego_speed_sweep(scene: DrivingScene, group: ScenarioGroup, radar: RadarConfig, cfar, doa,
                    detect, ego: EgoMotionConfig, sim: SimConfig, speeds_kmh, *,
                    yaw_rate_deg_s: float = 0.0, progress: bool = False) -> pd.DataFrame:
    """The radar's ego-motion estimate on ``ego.sweep_frames`` frames (evenly spread over the
    scene) of ``scene`` driven at each of ``speeds_kmh`` with the constant ``yaw_rate_deg_s``:
    one row per frame with speed_kmh, frame, true_speed_mps, true_yaw_rate_deg_s,
    odometry_mps, ego_speed_mps, yaw_rate_deg_s, the fit's theoretical standard deviations,
    error_mps (radar - truth), yaw_rate_error_deg_s, odometry_error_mps, n_detections,
    n_static."""
    from dataclasses import replace

    rows = []
    for kmh in speeds_kmh:
        sc = replace(scene, speed_kmh=float(kmh), yaw_rate_deg_s=float(yaw_rate_deg_s))
        n = len(frame_times(sc, radar.frame_period_s))
        idx = np.unique(np.linspace(0, n - 1, min(ego.sweep_frames, n)).round().astype(int))
        res = detect_driving_scene(sc, group, radar, cfar, doa, detect, ego, sim, frames=idx,
                                   progress=progress)
        rows.append(res.ego.assign(speed_kmh=float(kmh)))
    out = pd.concat(rows, ignore_index=True)
    return out.assign(error_mps=out.ego_speed_mps - out.true_speed_mps,
                      yaw_rate_error_deg_s=out.yaw_rate_deg_s - out.true_yaw_rate_deg_s,
                      odometry_error_mps=out.odometry_mps - out.true_speed_mps)


def _num(x: float) -> float | None:
    """A finite float, or None (JSON null) where there is no value."""
    return float(x) if np.isfinite(x) else None


def ego_motion_metrics(sweep: pd.DataFrame) -> dict:
    """``{"rms_error_mps": {speed_kmh: ..}, "odometry_rms_error_mps": {..}, "bias_mps": {..},
    "n_frames": {..}, "failed_frames": {..}}`` of the straight frames (true yaw rate 0; speed
    keys as ``"10"``; a frame without a consensus counts as failed and is left out of the RMS),
    and from the turning frames (true yaw rate not 0, where the sweep has them; else the
    straight ones): ``"rms_error_yaw_rate_deg_s"``, ``"yaw_rate_sd_theory_deg_s"`` (median over
    frames of the least-squares theory, :func:`blindspot.dsp.ego_motion.ego_motion_std`),
    ``"rms_error_mps_turning"``, ``"speed_sd_theory_mps"`` and ``"yaw_rate_deg_s"`` (the
    turning sweep's true yaw rate)."""
    out: dict = {k: {} for k in ("rms_error_mps", "odometry_rms_error_mps", "bias_mps",
                                 "n_frames", "failed_frames", "rms_error_yaw_rate_deg_s",
                                 "yaw_rate_sd_theory_deg_s", "rms_error_mps_turning",
                                 "speed_sd_theory_mps")}
    yaw = sweep.get("true_yaw_rate_deg_s", pd.Series(0.0, index=sweep.index))
    straight, turning = sweep[yaw == 0], sweep[yaw != 0]
    if turning.empty:
        turning = straight
    out["yaw_rate_deg_s"] = float(turning.true_yaw_rate_deg_s.iloc[0]) if (
        len(turning) and "true_yaw_rate_deg_s" in turning) else 0.0
    rms = lambda e: _num(np.sqrt(np.mean(e**2))) if e.size else None  # noqa: E731
    for kmh, g in straight.groupby("speed_kmh"):
        key = f"{kmh:g}"
        ok = g.error_mps.notna()
        e = g.error_mps[ok].to_numpy()
        out["rms_error_mps"][key] = rms(e)
        out["bias_mps"][key] = _num(np.mean(e)) if e.size else None
        out["odometry_rms_error_mps"][key] = float(np.sqrt(np.mean(g.odometry_error_mps**2)))
        out["n_frames"][key] = int(len(g))
        out["failed_frames"][key] = int((~ok).sum())
    for kmh, g in turning.groupby("speed_kmh"):
        key = f"{kmh:g}"
        if "yaw_rate_error_deg_s" in g:
            out["rms_error_yaw_rate_deg_s"][key] = rms(g.yaw_rate_error_deg_s.dropna().to_numpy())
            out["yaw_rate_sd_theory_deg_s"][key] = _num(g.yaw_rate_sd_theory_deg_s.median())
            out["speed_sd_theory_mps"][key] = _num(g.speed_sd_theory_mps.median())
        out["rms_error_mps_turning"][key] = rms(g.error_mps.dropna().to_numpy())
    return out


def pedestrian_detection_stats(detections: pd.DataFrame, truth: pd.DataFrame,
                               gate_m: float = 1.5) -> dict:
    """How the chain sees each pedestrian of one scene: per frame, the moving detections within
    ``gate_m`` of its reference point (world frame); the frame counts as detected when there is
    one. Returns per pedestrian: n_frames_visible, detection_rate_visible (frames while not
    occluded and within the processed range), detected_while_occluded (frames),
    median_error_m (nearest moving detection, detected frames)."""
    out = {}
    mv = detections[~detections["static"].to_numpy(bool)]
    by_frame = {f: d[["x_m", "y_m"]].to_numpy() for f, d in mv.groupby("frame")}
    for name, tr in truth.groupby("pedestrian", sort=False):
        err = np.full(len(tr), np.nan)
        for i, (f, x, y) in enumerate(zip(tr.frame, tr.x_m, tr.y_m)):  # per frame: the frame's few moving detections
            pts = by_frame.get(f)
            if pts is not None and len(pts):
                err[i] = np.min(np.hypot(pts[:, 0] - x, pts[:, 1] - y))
        hit = err <= gate_m
        vis = ~tr.occluded.to_numpy(bool)
        out[str(name)] = {
            "n_frames_visible": int(vis.sum()),
            "detection_rate_visible": _num(hit[vis].mean()) if vis.any() else None,
            "detected_while_occluded": int(hit[~vis].sum()),
            "median_error_m": _num(np.median(err[hit])) if hit.any() else None,
        }
    return out


def points_from_detections(detections: pd.DataFrame, ego: pd.DataFrame, *, scene: str,
                           cluster_gap_m: float, static_tolerance_mps: float) -> pd.DataFrame:
    """The full chain's point per frame, grouped as the fast measurement groups it: detections
    off the static world's Doppler curve (the frame's true ego speed) by more than
    ``static_tolerance_mps``, clustered (single linkage, ``cluster_gap_m``), the largest cluster's
    SNR-weighted centroid (:func:`blindspot.dsp.points.group_points`). Columns: scene, frame,
    range_m, angle_deg, snr_db, n_detections, x_vehicle_m, y_vehicle_m."""
    from blindspot.dsp.ego_motion import static_radial_velocity
    from blindspot.dsp.points import group_points

    d = detections[detections.angle_deg.notna()]
    speed = ego.set_index("frame").true_speed_mps.reindex(d.frame).to_numpy()
    off = d.velocity_mps.to_numpy() - static_radial_velocity(d.angle_deg.to_numpy(), 1.0) * speed
    pts = group_points(d.frame.to_numpy(), d.range_m.to_numpy(), off, d.angle_deg.to_numpy(),
                       d.snr_db.to_numpy(), static_tolerance_mps, cluster_gap_m)
    th = np.radians(pts["angle_deg"])
    return pd.DataFrame({"scene": scene, "frame": pts["frame"], "range_m": pts["range_m"],
                         "angle_deg": pts["angle_deg"], "snr_db": pts["snr_db"],
                         "n_detections": pts["n_detections"],
                         "x_vehicle_m": pts["range_m"] * np.sin(th),
                         "y_vehicle_m": pts["range_m"] * np.cos(th)})


def point_error_statistics(points: pd.DataFrame, truth: pd.DataFrame, gate_m: float = 1.5) -> dict:
    """Point-error statistics of one pedestrian's points (vehicle frame) against its truth rows
    (frames in range and in view): detection_rate (frames with a point within ``gate_m``),
    median_error_m, p90_error_m, range_error_sd_m, angle_error_sd_deg (points within the gate)."""
    j = truth.merge(points, on=["scene", "frame"], how="left", suffixes=("_t", ""))
    err = np.hypot(j.x_vehicle_m - j.x_vehicle_m_t, j.y_vehicle_m - j.y_vehicle_m_t).to_numpy()
    hit = err <= gate_m
    e = err[hit]
    return {
        "n_frames": int(len(j)),
        "detection_rate": float(hit.mean()) if len(j) else float("nan"),
        "median_error_m": float(np.median(e)) if e.size else float("nan"),
        "p90_error_m": float(np.percentile(e, 90)) if e.size else float("nan"),
        "range_error_sd_m": float(np.std((j.range_m - j.range_m_t).to_numpy()[hit])) if e.size else float("nan"),
        "angle_error_sd_deg": float(np.std((j.angle_deg - j.angle_deg_t).to_numpy()[hit])) if e.size else float("nan"),
    }


def _hit_frames(points: pd.DataFrame, truth: pd.DataFrame, gate_m: float) -> pd.MultiIndex:
    """(scene, frame) of the truth rows with a point within ``gate_m``."""
    j = truth.merge(points, on=["scene", "frame"], how="inner", suffixes=("_t", ""))
    hit = np.hypot(j.x_vehicle_m - j.x_vehicle_m_t, j.y_vehicle_m - j.y_vehicle_m_t) <= gate_m
    return pd.MultiIndex.from_frame(j.loc[hit, ["scene", "frame"]]).unique()


def paired_point_statistics(points_a: pd.DataFrame, points_b: pd.DataFrame,
                            truth: pd.DataFrame, gate_m: float = 1.5) -> dict:
    """Two chains' points of one pedestrian compared on the same frames (e.g. the full FMCW
    chain and the fast measurement).

    points_a, points_b: at most one row per (scene, frame), columns scene, frame,
    x_vehicle_m, y_vehicle_m, range_m (m), angle_deg (deg) (:func:`points_from_detections`);
    truth: ONE pedestrian's rows (one per scene and frame; duplicates would count twice), the
    same columns plus the scene truth's. Returns ``a`` and ``b``: :func:`point_error_statistics`
    of each on the truth rows where BOTH have a point within ``gate_m`` m (paired: the same
    truth frames, so a percentile compares like with like; their ``detection_rate`` is 1 by
    construction), ``n_union`` the frames where either has one, ``n_disagree`` those where only
    one has (a marginal detection, or another cluster chosen as the frame's moving point).
    Unpaired percentiles over each chain's own hit frames mix those few frames into the error
    tail: with ~70 errors, one or two of 0.5-1 m move a 90th percentile by a fifth
    (:func:`error_percentile_interval`)."""
    ha, hb = _hit_frames(points_a, truth, gate_m), _hit_frames(points_b, truth, gate_m)
    both = truth[pd.MultiIndex.from_frame(truth[["scene", "frame"]]).isin(ha.intersection(hb))]
    return {"a": point_error_statistics(points_a, both, gate_m),
            "b": point_error_statistics(points_b, both, gate_m),
            "n_union": len(ha.union(hb)), "n_disagree": len(ha.symmetric_difference(hb))}


def error_percentile_interval(points: pd.DataFrame, truth: pd.DataFrame, q: float = 90.0, *,
                              gate_m: float = 1.5, n_bootstrap: int = 4000, level: float = 0.95,
                              seed: int = 0) -> tuple[float, float]:
    """Percentile-bootstrap interval (``level``) of the ``q``-th percentile of the Euclidean
    point errors (m) within ``gate_m`` (the errors of :func:`point_error_statistics`),
    resampling the errors with replacement ``n_bootstrap`` times (vectorised; Efron &
    Tibshirani 1993, ch. 13). (NaN, NaN) without errors."""
    j = truth.merge(points, on=["scene", "frame"], how="inner", suffixes=("_t", ""))
    e = np.hypot(j.x_vehicle_m - j.x_vehicle_m_t, j.y_vehicle_m - j.y_vehicle_m_t).to_numpy()
    e = e[e <= gate_m]
    if not e.size:
        return float("nan"), float("nan")
    rng = np.random.default_rng(seed)
    boot = np.percentile(e[rng.integers(0, e.size, (n_bootstrap, e.size))], q, axis=1)
    lo, hi = np.percentile(boot, [50 * (1 - level), 50 * (1 + level)])
    return float(lo), float(hi)


def numeric_leaves(tree: dict) -> dict:
    """The finite numeric leaves of a nested metrics mapping (what MLflow can log); names and
    nulls (no value) stay in the stage's JSON file only."""
    out = {}
    for k, v in tree.items():
        if isinstance(v, dict):
            sub = numeric_leaves(v)
            if sub:
                out[k] = sub
        elif isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v):
            out[k] = v
    return out


def figure_scene_detection(scene: DrivingScene, group: ScenarioGroup, radar: RadarConfig, cfar,
                           doa, detect, ego, sim, *, progress: bool = False) -> dict:
    """The driving_detect stage's science: ``scene`` (the figure scene) through the full FMCW
    simulator and the moving-car chain (:func:`detect_driving_scene`), one frame's maps kept
    for the figure (the middle one of those where the lead pedestrian is visible and walking),
    and the ego-speed sweep (:func:`ego_speed_sweep`) at every Monte-Carlo speed, driving
    straight and turning at ``ego.sweep_yaw_rate_deg_s``. Returns a dict: ``frame`` (the
    arrays of the kept frame's map, for an .npz), ``detections``, ``ego``, ``sweep`` (tables)
    and ``metrics`` (:func:`ego_motion_metrics` plus the figure scene's)."""
    from blindspot.radar.driving import scene_truth

    chain = (cfar, doa, detect)
    truth = scene_truth(scene, group, radar.frame_period_s)
    lead = truth[truth.pedestrian == scene.pedestrians[0].name]
    walking = lead[~lead.occluded & (np.hypot(lead.vx_mps, lead.vy_mps) > 0.5)
                   & (lead.range_m < ego.max_range_m)]
    keep = (int(walking.frame.iloc[len(walking) // 2]) if len(walking)
            else int(lead.frame.iloc[-1] // 2))
    res = detect_driving_scene(scene, group, radar, *chain, ego, sim, keep_frame=keep,
                               progress=progress)
    b, i = res.kept, res.kept_index
    frame = dict(power=b.power[i], threshold=b.threshold[i],
                 range_axis_m=np.asarray(radar.range_axis_m()[:b.power.shape[1]]),
                 velocity_axis_mps=radar.velocity_axis_mps(), frame=keep, scene=scene.name,
                 v_max_mps=radar.max_velocity_mps)
    sweep = ego_speed_sweep(scene, group, radar, *chain, ego, sim, group.monte_carlo.speeds_kmh,
                            progress=progress)
    if ego.sweep_yaw_rate_deg_s:       # the same frames with the ego car turning
        sweep = pd.concat([sweep, ego_speed_sweep(
            scene, group, radar, *chain, ego, sim, group.monte_carlo.speeds_kmh,
            yaw_rate_deg_s=ego.sweep_yaw_rate_deg_s, progress=progress)], ignore_index=True)
    metrics = ego_motion_metrics(sweep)
    metrics["figure_scene"] = {"scene": scene.name, "speed_kmh": scene.speed_kmh,
                               "kept_frame": keep,
                               "pedestrians": pedestrian_detection_stats(res.detections, truth),
                               "ego_speed_rms_error_mps": float(np.sqrt(np.nanmean(
                                   (res.ego.ego_speed_mps - res.ego.true_speed_mps) ** 2))),
                               "ego_speed_failed_frames": int(res.ego.ego_speed_mps.isna().sum())}
    return {"frame": frame, "detections": res.detections, "ego": res.ego, "sweep": sweep,
            "metrics": metrics}
