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
import numpy as np
import pandas as pd

from blindspot import experiment
from blindspot.cli import main_stage
from blindspot.io import write_json, write_parquet
from blindspot.radar.driving import draw_scenarios
from blindspot.safety.ncap import nominal_scenes
from blindspot.stage import StageResult
from blindspot.synth.driving_detection import numeric_leaves
from blindspot.synth.driving_measurement import measure_driving


def run(cfg, ctx):
    group, named = experiment.scenarios(cfg)
    radar = experiment.driving_radar(cfg)
    scenes = (list(named.values()) + nominal_scenes(named, group.monte_carlo.speeds_kmh)
              + draw_scenarios(group, named[group.figure_scene]))
    res = measure_driving(scenes, group, radar, experiment.driving_cfar(cfg),
                          experiment.doa(cfg), experiment.detect(cfg), experiment.ego_motion(cfg),
                          adc_headroom_db=experiment.sim(cfg).adc_headroom_db,
                          jobs=experiment.jobs(cfg), progress=cfg.progress)
    measured, points = res.measured, res.points
    write_parquet(ctx.out("measured.parquet"), measured)
    write_parquet(ctx.out("points.parquet"), points)
    truth = pd.read_parquet(ctx.dep("truth.parquet"))
    # the pedestrian's own returns among every point (truth label, for scoring only), static-
    # looking ones included: the first within 1.5 m of the truth is when a world-frame tracker
    # could first see it
    own = points[points.source == "p0"].merge(
        truth[truth.pedestrian == "p0"][["scene", "frame", "x_m", "y_m", "ttc_s", "behaviour",
                                         "ego_speed_mps"]],
        on=["scene", "frame"], suffixes=("", "_t"))
    own = own[np.hypot(own.x_m - own.x_m_t, own.y_m - own.y_m_t) <= 1.5]
    mc_names = set(truth.scene[truth.set == "monte_carlo"])
    own = own[own.scene.isin(mc_names) & (own.behaviour == "cross") & (own.ttc_s > 0)]
    first_kept = own.groupby("scene").ttc_s.max()
    first_dropped = own[~own.static].groupby("scene").ttc_s.max()
    static_share = own.groupby("scene").static.mean()
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
        kept = first_kept.reindex(intr.scene.unique()).dropna()
        dropped = first_dropped.reindex(intr.scene.unique()).dropna()
        per_speed[f"{kmh:.0f}"] = {
            "n_scenes_intruding": int(n_sc),
            "first_seen_ttc_s_median_static_dropped": (float(dropped.median()) if len(dropped)
                                                       else None),
            "first_seen_ttc_s_median_static_kept": float(kept.median()) if len(kept) else None,
            "seen_before_collision_rate_static_kept": float(len(kept) / n_sc) if n_sc else None,
            "static_share_of_own_points": (float(static_share.reindex(kept.index).mean())
                                           if len(kept) else None),
            "seen_before_collision_rate": float(len(first) / n_sc) if n_sc else None,
            "first_seen_ttc_s_median": float(first.median()) if len(first) else None,
            "detection_rate_visible": float(vis.hit.mean()) if len(vis) else None,
            "median_error_m": float(g.error_m[g.hit].median()) if g.hit.any() else None,
        }
    n_frames = points.groupby("scene").frame.nunique().sum()
    metrics = {"n_scenes": len(scenes), "n_points": int(len(measured)),
               "n_radar_points": int(len(points)),
               "static_points_per_frame": float(points.static.sum() / max(n_frames, 1)),
               "by_speed_kmh": per_speed}
    write_json(ctx.out("driving_measure.json"), metrics)
    print("driving_measure: first seen (median TTC, s) by speed, static-looking points dropped / "
          "kept: " + ", ".join(f"{k} km/h {v['first_seen_ttc_s_median']} / "
                               f"{v['first_seen_ttc_s_median_static_kept']}"
                               for k, v in per_speed.items()))
    return StageResult(metrics=numeric_leaves(metrics))


if __name__ == "__main__":
    main_stage(run, "driving_measure")
