"""Fast driving measurement against the full FMCW chain (issue 11): the same frames of the
figure scene (CPNCO, child crossing from behind the parked cars) at several ego speeds through
both, and the point-error statistics of each; then the time of the fast measurement on the
whole Monte-Carlo set.

    PYTHONPATH=src python benchmarks/bench_driving.py [--speeds 20 40 60] [--scene cpfa ...] [--mc]
    PYTHONPATH=src python benchmarks/bench_driving.py --stage-times [--tracking-uri URI]
    PYTHONPATH=src python benchmarks/bench_driving.py --every 23 [--jobs 2]

Prints one line per statistic (full, fast, relative difference; both chains' detections
grouped alike), over each chain's own frames with a point and paired (on the frames both have
one: :func:`blindspot.synth.driving_detection.paired_point_statistics`), and, with --mc, the wall time of the fast measurement of every Monte-Carlo scene.
``--stage-times`` instead prints the wall time of the last run of each driving stage, from the
MLflow runs the stage runner records (start and end of each stage run; default store: the
repository's mlflow.db), with the machine's load average now. ``--every N`` times the
driving_measure stage's work (:func:`measure_driving`) on every N-th of its scenes (named and
Monte-Carlo, in the stage's order; every frame) with ``--jobs`` worker processes: wall, CPU of
this process and of its workers, frames and points, and the load average.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace

import numpy as np
import pandas as pd

from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig, EgoMotionConfig
from blindspot.radar.config import RadarConfig, SimConfig
from blindspot.radar.scenario import load_scenarios
from blindspot.config import compose
from blindspot.radar.driving import draw_scenarios, scene_truth
from blindspot.synth.driving_detection import (
    detect_driving_scene, error_percentile_interval, paired_point_statistics,
    point_error_statistics,
    points_from_detections,
)
from blindspot.synth.driving_measurement import measure_driving


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--speeds", type=float, nargs="+", default=[20.0, 40.0, 60.0])
    ap.add_argument("--scene", nargs="+", default=None,
                    help="scenes of conf/scenario (default: the figure scene, CPNCO)")
    ap.add_argument("--mc", action="store_true", help="also time the whole Monte-Carlo set")
    ap.add_argument("--stage-times", action="store_true",
                    help="print the last MLflow-recorded wall time of each driving stage")
    ap.add_argument("--tracking-uri", default="sqlite:///mlflow.db")
    ap.add_argument("--every", type=int, default=None,
                    help="time the stage's measurement of every N-th of its scenes")
    ap.add_argument("--jobs", type=int, default=1, help="worker processes (with --every)")
    args = ap.parse_args()
    if args.stage_times:
        stage_times(args.tracking_uri)
        return
    if args.every:
        stage_subset_time(args.every, args.jobs)
        return
    cfg = compose(config_dir="conf")
    group, named = load_scenarios(cfg.scenario)
    radar, ego = RadarConfig.from_cfg(cfg, "driving_radar"), EgoMotionConfig.from_cfg(cfg)
    chain = (CfarConfig.from_cfg(cfg, "driving_cfar"), DoaConfig.from_cfg(cfg), DetectConfig.from_cfg(cfg))
    full_pts, fast_pts, patch_pts, truths, counts = [], [], [], [], []
    for base, kmh in ((named[n], v) for n in (args.scene or [group.figure_scene])
                      for v in args.speeds):
        sc = replace(base, speed_kmh=kmh, name=f"{base.name}_{kmh:g}")
        tr = scene_truth(sc, group, radar.frame_period_s)
        tr = tr[(tr.pedestrian == sc.pedestrians[0].name) & (tr.range_m < ego.max_range_m - 2)
                & (tr.y_vehicle_m > 0.2) & (tr.angle_deg.abs() < 75) & ~tr.occluded]
        frames = tr.frame.to_numpy()
        t0 = time.perf_counter()
        res = detect_driving_scene(sc, group, radar, *chain, ego, SimConfig.from_cfg(cfg), frames=frames)
        t_full = time.perf_counter() - t0
        full_pts.append(points_from_detections(res.detections, res.ego, scene=sc.name,
                                               cluster_gap_m=DetectConfig.from_cfg(cfg).cluster_gap_m,
                                               static_tolerance_mps=ego.static_tolerance_mps))
        t0 = time.perf_counter()
        res_fast = measure_driving([sc], group, radar, *chain, ego,
                                   adc_headroom_db=SimConfig.from_cfg(cfg).adc_headroom_db,
                                   frames={sc.name: frames})
        t_fast = time.perf_counter() - t0
        # both chains' detections grouped the same way (points_from_detections: the largest
        # off-curve cluster of the frame), so the comparison is of the chains, not of grouping
        ego_fast = pd.DataFrame({"frame": frames, "true_speed_mps": sc.speed_mps})
        fast = points_from_detections(res_fast.points, ego_fast, scene=sc.name,
                                      cluster_gap_m=DetectConfig.from_cfg(cfg).cluster_gap_m,
                                      static_tolerance_mps=ego.static_tolerance_mps)
        fast_pts.append(fast)
        patch_pts.append(res_fast.measured[res_fast.measured.pedestrian == sc.pedestrians[0].name])
        # every point per frame (static world and pedestrian), both chains
        det = res.detections[res.detections.angle_deg.notna()]
        counts.append({"full_points": len(det) / len(frames),
                       "full_static": det.static.sum() / len(frames),
                       "fast_points": len(res_fast.points) / len(frames),
                       "fast_static": res_fast.points.static.sum() / len(frames),
                       "n_frames": len(frames)})
        truths.append(tr)
        print(f"{sc.name}: {len(frames)} frames; full chain {t_full:.1f} s, fast {t_fast:.1f} s")
    truth = pd.concat(truths)
    full = point_error_statistics(pd.concat(full_pts), truth)
    fast = point_error_statistics(pd.concat(fast_pts), truth)
    patch = point_error_statistics(pd.concat(patch_pts).drop(columns=["pedestrian", "x_m", "y_m"]),
                                   truth)
    print("fast measured.parquet (off-curve detections within 8 range bins of the pedestrian): "
          + ", ".join(f"{k} {v:.4g}" for k, v in patch.items()))
    out = {"full": full, "fast": fast, "relative_difference": {
        k: (fast[k] - full[k]) / full[k] if full[k] else float("nan")
        for k in full if k != "n_frames"}}
    cnt = pd.DataFrame(counts)
    w = cnt.n_frames / cnt.n_frames.sum()
    for what in ("points", "static"):
        f_, s_ = float((cnt[f"full_{what}"] * w).sum()), float((cnt[f"fast_{what}"] * w).sum())
        full[f"{what}_per_frame"], fast[f"{what}_per_frame"] = f_, s_
        out["relative_difference"][f"{what}_per_frame"] = (s_ - f_) / f_ if f_ else float("nan")
    for k in full:
        print(f"{k:>22}: full {full[k]:.4g}  fast {fast[k]:.4g}"
              + (f"  ({out['relative_difference'][k]:+.1%})" if k != "n_frames" else ""))
    paired = paired_point_statistics(pd.concat(full_pts), pd.concat(fast_pts), truth)
    out["paired"] = paired
    print(f"paired, on the {paired['a']['n_frames']} frames both chains have a point "
          f"(of {paired['n_union']} either has; {paired['n_disagree']} only one):")
    for k in ("median_error_m", "p90_error_m", "range_error_sd_m", "angle_error_sd_deg"):
        a, b = paired["a"][k], paired["b"][k]
        print(f"{k:>22}: full {a:.4g}  fast {b:.4g}  ({(b - a) / a:+.1%})")
    for name, pts in (("full", full_pts), ("fast", fast_pts)):
        lo, hi = error_percentile_interval(pd.concat(pts), truth, 90.0)
        out[f"{name}_p90_ci95"] = [lo, hi]
        print(f"unpaired p90, {name}: 95 % bootstrap interval [{lo:.3f}, {hi:.3f}] m")
    if args.mc:
        mc = draw_scenarios(group, named[(args.scene or [group.figure_scene])[0]])
        t0 = time.perf_counter()
        m = measure_driving(mc, group, radar, *chain, ego,
                            adc_headroom_db=SimConfig.from_cfg(cfg).adc_headroom_db).points
        out["monte_carlo"] = {"n_scenes": len(mc), "n_points": len(m),
                              "wall_s": time.perf_counter() - t0}
        print(f"Monte-Carlo set: {len(mc)} scenes, {len(m)} points, "
              f"{out['monte_carlo']['wall_s']:.0f} s")
    print(json.dumps(out))


def stage_subset_time(every: int, jobs: int) -> None:
    """Wall and CPU seconds of :func:`measure_driving` on every ``every``-th scene of the
    driving_measure stage (its scene list: the named scenes, then the Monte-Carlo draws)."""
    import os
    import resource

    cfg = compose(config_dir="conf")
    group, named = load_scenarios(cfg.scenario)
    radar = RadarConfig.from_cfg(cfg, "driving_radar")
    scenes = (list(named.values()) + draw_scenarios(group, named[group.figure_scene]))[::every]
    load0 = os.getloadavg()
    t0, c0 = time.perf_counter(), time.process_time()
    k0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    res = measure_driving(scenes, group, radar, CfarConfig.from_cfg(cfg, "driving_cfar"), DoaConfig.from_cfg(cfg), DetectConfig.from_cfg(cfg),
                          EgoMotionConfig.from_cfg(cfg), adc_headroom_db=SimConfig.from_cfg(cfg).adc_headroom_db,
                          jobs=jobs)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    k1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu_workers = (k1.ru_utime - k0.ru_utime) + (k1.ru_stime - k0.ru_stime)
    n_frames = int(res.points.groupby("scene").frame.nunique().sum())
    load1 = os.getloadavg()
    out = {"n_scenes": len(scenes), "n_frames_with_points": n_frames,
           "n_points": len(res.points), "n_measured": len(res.measured), "jobs": jobs,
           "wall_s": wall, "cpu_s": cpu, "cpu_workers_s": cpu_workers,
           "load_average_1min_before_after": [load0[0], load1[0]], "cores": os.cpu_count()}
    print(f"measure_driving on every {every}-th stage scene ({len(scenes)} scenes, "
          f"{n_frames} frames with points, {len(res.points)} points), jobs={jobs}: "
          f"wall {wall:.1f} s, CPU {cpu:.1f} s here + {cpu_workers:.1f} s in workers "
          f"(load {load0[0]:.1f} -> {load1[0]:.1f} on {os.cpu_count()} cores)")
    print(json.dumps(out))


DRIVING_STAGES = ("driving_scenes", "driving_detect", "driving_measure", "fig_driving")


def stage_times(uri: str) -> None:
    """Wall time (s) of the last finished run of each driving stage in the MLflow store."""
    import os

    from mlflow.tracking import MlflowClient

    client = MlflowClient(tracking_uri=uri)
    out = {}
    exps = [e.experiment_id for e in client.search_experiments()]
    for stage in DRIVING_STAGES:
        runs = client.search_runs(exps, filter_string=f"attributes.run_name = '{stage}' and "
                                  "attributes.status = 'FINISHED'",
                                  order_by=["attributes.start_time DESC"], max_results=1)
        if runs:
            r = runs[0].info
            out[stage] = {"wall_s": (r.end_time - r.start_time) / 1000.0,
                          "start": time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime(r.start_time / 1000))}
            print(f"{stage:>16}: {out[stage]['wall_s']:.1f} s (started {out[stage]['start']} UTC)")
        else:
            print(f"{stage:>16}: no finished run in {uri}")
    load = os.getloadavg()
    print(f"load average now (1, 5, 15 min): {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on "
          f"{os.cpu_count()} cores")
    print(json.dumps({"stages": out, "load_average": load}))


if __name__ == "__main__":
    main()
