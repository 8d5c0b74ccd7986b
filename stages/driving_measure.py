"""driving_measure: every frame of every Monte-Carlo driving scene (and the named scenes) through
the fast driving measurement (blindspot.synth.driving_measurement: the whole range-Doppler map
synthesised analytically with the parked cars, the roadside and the pedestrians, the chain's
CFAR, Doppler unwrapping, TDM compensation with the unwrapped velocity, MUSIC, static test on
the ego-motion curve). Writes every detection as a point (data/driving/points.parquet, the
static world included) and each pedestrian's point (measured.parquet), and how early each
intruding pedestrian is first seen (time to collision without braking at the first point
within 1.5 m of its truth): from its off-curve points only (static-looking ones dropped, as
the clutter filter does) and from every point it returns (static-looking ones kept, what a
tracker in the world frame can use)."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import pandas as pd

from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig, EgoMotionConfig
from blindspot.radar.config import RadarConfig, SimConfig
from blindspot.radar.scenario import load_scenarios
from blindspot.typed_config import jobs
from blindspot.cli import main_stage
from blindspot.io import write_json, write_parquet
from blindspot.radar.driving import draw_scenarios
from blindspot.safety.ncap import nominal_scenes
from blindspot.stage import StageResult
from blindspot.synth.driving_detection import numeric_leaves
from blindspot.synth.driving_measurement import first_seen_metrics, measure_driving


def run(cfg, ctx):
    group, named = load_scenarios(cfg.scenario)
    radar = RadarConfig.from_cfg(cfg, "driving_radar")
    scenes = (list(named.values()) + nominal_scenes(named, group.monte_carlo.speeds_kmh)
              + draw_scenarios(group, named[group.figure_scene]))
    res = measure_driving(scenes, group, radar, CfarConfig.from_cfg(cfg, "driving_cfar"),
                          DoaConfig.from_cfg(cfg), DetectConfig.from_cfg(cfg), EgoMotionConfig.from_cfg(cfg),
                          adc_headroom_db=SimConfig.from_cfg(cfg).adc_headroom_db,
                          jobs=jobs(cfg), progress=cfg.progress)
    measured, points = res.measured, res.points
    write_parquet(ctx.out("measured.parquet"), measured)
    write_parquet(ctx.out("points.parquet"), points)
    truth = pd.read_parquet(ctx.dep("truth.parquet"))
    metrics = first_seen_metrics(points, measured, truth, len(scenes))
    write_json(ctx.out("driving_measure.json"), metrics)
    print("driving_measure: first seen (median TTC, s) by speed, static-looking points dropped / "
          "kept: " + ", ".join(f"{k} km/h {v['first_seen_ttc_s_median']} / "
                               f"{v['first_seen_ttc_s_median_static_kept']}"
                               for k, v in metrics["by_speed_kmh"].items()))
    return StageResult(metrics=numeric_leaves(metrics))


if __name__ == "__main__":
    main_stage(run, "driving_measure")
