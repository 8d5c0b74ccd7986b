"""driving_measure: every pedestrian of every Monte-Carlo driving scene (and the named scenes)
through the fast driving measurement (blindspot.synth.driving_measurement: the reduced chain's
patches with Doppler unwrapping, TDM compensation with the unwrapped velocity, MUSIC and static
clutter removal on the ego-motion curve), and how early each intruding pedestrian is first seen
(time to collision without braking at the first point within 1.5 m of its truth)."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import numpy as np
import pandas as pd

from blindspot import experiment
from blindspot.cli import main_stage
from blindspot.io import write_json, write_parquet
from blindspot.radar.driving import draw_scenarios
from blindspot.stage import StageResult
from blindspot.synth.driving_detection import numeric_leaves
from blindspot.synth.driving_measurement import measure_driving_scenes


def run(cfg, ctx):
    group, named = experiment.scenarios(cfg)
    radar = experiment.driving_radar(cfg)
    scenes = list(named.values()) + draw_scenarios(group, named[group.figure_scene])
    measured = measure_driving_scenes(scenes, group, radar, experiment.cfar(cfg),
                                      experiment.doa(cfg), experiment.detect(cfg),
                                      experiment.ego_motion(cfg),
                                      adc_headroom_db=experiment.sim(cfg).adc_headroom_db,
                                      progress=cfg.progress)
    write_parquet(ctx.out("measured.parquet"), measured)
    truth = pd.read_parquet(ctx.dep("truth.parquet"))
    j = truth.merge(measured, on=["scene", "pedestrian", "frame"], how="left", suffixes=("", "_m"))
    err = np.hypot(j.x_m_m - j.x_m, j.y_m_m - j.y_m)
    j = j.assign(hit=err <= 1.5, error_m=err)
    mc = j[(j.set == "monte_carlo") & (j.pedestrian == "p0")]
    per_speed = {}
    for kmh, g in mc.groupby(mc.ego_speed_mps * 3.6):
        intr = g[(g.behaviour == "cross") & (g.ttc_s > 0)]
        first = intr[intr.hit].groupby("scene").ttc_s.max()          # earliest hit = largest TTC
        n_sc = intr.scene.nunique()
        vis = g[~g.occluded]
        per_speed[f"{kmh:.0f}"] = {
            "n_scenes_intruding": int(n_sc),
            "seen_before_collision_rate": float(len(first) / n_sc) if n_sc else None,
            "first_seen_ttc_s_median": float(first.median()) if len(first) else None,
            "detection_rate_visible": float(vis.hit.mean()) if len(vis) else None,
            "median_error_m": float(g.error_m[g.hit].median()) if g.hit.any() else None,
        }
    metrics = {"n_scenes": len(scenes), "n_points": int(len(measured)), "by_speed_kmh": per_speed}
    write_json(ctx.out("driving_measure.json"), metrics)
    print("driving_measure: first seen (median TTC, s) by speed: "
          + ", ".join(f"{k} km/h {v['first_seen_ttc_s_median']}" for k, v in per_speed.items()))
    return StageResult(metrics=numeric_leaves(metrics))


if __name__ == "__main__":
    main_stage(run, "driving_measure")
