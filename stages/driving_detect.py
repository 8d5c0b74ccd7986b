"""driving_detect: the figure driving scene (conf/scenario figure_scene, CPNCO at 30 km/h)
through the full FMCW simulator and the moving-car chain (Doppler unwrapping with odometry,
TDM compensation with the unwrapped velocity, RANSAC ego speed, static clutter on the
ego-motion curve), one frame's maps kept for the figure; and the ego-speed error of the radar
at every Monte-Carlo speed, driving straight and turning at ego_motion.sweep_yaw_rate_deg_s
(speed and yaw-rate errors, Kellner et al. 2013: reports/metrics/ego_motion.json)."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import numpy as np

from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig, EgoMotionConfig
from blindspot.radar.config import RadarConfig, SimConfig
from blindspot.radar.scenario import load_scenarios
from blindspot.cli import main_stage
from blindspot.io import atomic_path, write_json, write_parquet
from blindspot.stage import StageResult
from blindspot.synth.driving_detection import figure_scene_detection, numeric_leaves


def run(cfg, ctx):
    group, named = load_scenarios(cfg.scenario)
    radar = RadarConfig.from_cfg(cfg, "driving_radar")
    ego = EgoMotionConfig.from_cfg(cfg)
    chain = (CfarConfig.from_cfg(cfg, "driving_cfar"), DoaConfig.from_cfg(cfg), DetectConfig.from_cfg(cfg))
    out = figure_scene_detection(named[group.figure_scene], group, radar, *chain, ego,
                                 SimConfig.from_cfg(cfg), progress=cfg.progress)
    with atomic_path(ctx.out("driving_frame.npz")) as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, **out["frame"])
    write_parquet(ctx.out("driving_detections.parquet"), out["detections"])
    write_parquet(ctx.out("driving_ego.parquet"), out["ego"])
    write_parquet(ctx.out("ego_speed_sweep.parquet"), out["sweep"])
    metrics = out["metrics"]
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
