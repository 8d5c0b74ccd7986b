"""driving_detect: the figure driving scene (conf/scenario figure_scene, CPNCO at 30 km/h)
through the full FMCW simulator and the moving-car chain (Doppler unwrapping with odometry,
TDM compensation with the unwrapped velocity, RANSAC ego speed, static clutter on the
ego-motion curve), one frame's maps kept for the figure; and the ego-speed error of the radar
at every Monte-Carlo speed, driving straight and turning at ego_motion.sweep_yaw_rate_deg_s
(speed and yaw-rate errors, Kellner et al. 2013: reports/metrics/ego_motion.json)."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import numpy as np
import pandas as pd

from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig, EgoMotionConfig
from blindspot.radar.config import RadarConfig, SimConfig
from blindspot.radar.scenario import load_scenarios
from blindspot.cli import main_stage
from blindspot.io import atomic_path, write_json, write_parquet
from blindspot.radar.driving import scene_truth
from blindspot.stage import StageResult
from blindspot.synth.driving_detection import (
    detect_driving_scene, ego_motion_metrics, ego_speed_sweep, numeric_leaves,
    pedestrian_detection_stats,
)


def run(cfg, ctx):
    group, named = load_scenarios(cfg.scenario)
    radar = RadarConfig.from_cfg(cfg, "driving_radar")
    ego = EgoMotionConfig.from_cfg(cfg)
    chain = (CfarConfig.from_cfg(cfg, "driving_cfar"), DoaConfig.from_cfg(cfg), DetectConfig.from_cfg(cfg))
    sim = SimConfig.from_cfg(cfg)
    scene = named[group.figure_scene]
    truth = scene_truth(scene, group, radar.frame_period_s)
    lead = truth[truth.pedestrian == scene.pedestrians[0].name]
    # the kept frame: the middle one of those where the lead pedestrian is visible and walking
    walking = lead[~lead.occluded & (np.hypot(lead.vx_mps, lead.vy_mps) > 0.5)
                   & (lead.range_m < ego.max_range_m)]
    keep = int(walking.frame.iloc[len(walking) // 2]) if len(walking) else int(lead.frame.iloc[-1] // 2)
    res = detect_driving_scene(scene, group, radar, *chain, ego, sim, keep_frame=keep,
                               progress=cfg.progress)
    b, i = res.kept, res.kept_index
    with atomic_path(ctx.out("driving_frame.npz")) as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, power=b.power[i], threshold=b.threshold[i],
                     range_axis_m=np.asarray(radar.range_axis_m()[:b.power.shape[1]]),
                     velocity_axis_mps=radar.velocity_axis_mps(), frame=keep,
                     scene=scene.name, v_max_mps=radar.max_velocity_mps)
    write_parquet(ctx.out("driving_detections.parquet"), res.detections)
    write_parquet(ctx.out("driving_ego.parquet"), res.ego)
    sweep = ego_speed_sweep(scene, group, radar, *chain, ego, sim, group.monte_carlo.speeds_kmh,
                            progress=cfg.progress)
    if ego.sweep_yaw_rate_deg_s:       # the same frames with the ego car turning
        sweep = pd.concat([sweep, ego_speed_sweep(
            scene, group, radar, *chain, ego, sim, group.monte_carlo.speeds_kmh,
            yaw_rate_deg_s=ego.sweep_yaw_rate_deg_s, progress=cfg.progress)], ignore_index=True)
    write_parquet(ctx.out("ego_speed_sweep.parquet"), sweep)
    metrics = ego_motion_metrics(sweep)
    metrics["figure_scene"] = {"scene": scene.name, "speed_kmh": scene.speed_kmh, "kept_frame": keep,
                               "pedestrians": pedestrian_detection_stats(res.detections, truth),
                               "ego_speed_rms_error_mps": float(np.sqrt(np.nanmean(
                                   (res.ego.ego_speed_mps - res.ego.true_speed_mps) ** 2))),
                               "ego_speed_failed_frames": int(res.ego.ego_speed_mps.isna().sum())}
    write_json(ctx.out("ego_motion.json"), metrics)
    print("driving_detect: radar ego-speed RMS error (m/s) by speed: "
          + ", ".join(f"{k} km/h {v:.3f}" for k, v in metrics["rms_error_mps"].items()))
    print(f"driving_detect: turning at {metrics['yaw_rate_deg_s']:g} deg/s, yaw-rate RMS error "
          "(deg/s) by speed: " + ", ".join(
              f"{k} km/h {v:.3f} (theory {metrics['yaw_rate_sd_theory_deg_s'].get(k)})"
              for k, v in metrics["rms_error_yaw_rate_deg_s"].items() if v is not None))
    return StageResult(metrics=numeric_leaves(metrics))


if __name__ == "__main__":
    main_stage(run, "driving_detect")
