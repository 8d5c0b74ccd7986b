"""Fast driving measurement against the full FMCW chain (issue 11): the same frames of the
figure scene (CPNCO, child crossing from behind the parked cars) at several ego speeds through
both, and the point-error statistics of each; then the time of the fast measurement on the
whole Monte-Carlo set.

    PYTHONPATH=src python benchmarks/bench_driving.py [--speeds 20 40 60] [--scene along_kerb] [--mc]

Prints one line per statistic (full, fast, relative difference) and, with --mc, the wall time
of the fast measurement of every Monte-Carlo scene.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace

import numpy as np
import pandas as pd

from blindspot import experiment as ex
from blindspot.config import compose
from blindspot.radar.driving import draw_scenarios, scene_truth
from blindspot.synth.driving_detection import (
    detect_driving_scene, point_error_statistics, points_from_detections,
)
from blindspot.synth.driving_measurement import measure_driving


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--speeds", type=float, nargs="+", default=[20.0, 40.0, 60.0])
    ap.add_argument("--scene", default=None,
                    help="a scene of conf/scenario (default: the figure scene, CPNCO)")
    ap.add_argument("--mc", action="store_true", help="also time the whole Monte-Carlo set")
    args = ap.parse_args()
    cfg = compose(config_dir="conf")
    group, named = ex.scenarios(cfg)
    radar, ego = ex.driving_radar(cfg), ex.ego_motion(cfg)
    chain = (ex.cfar(cfg), ex.doa(cfg), ex.detect(cfg))
    base = named[args.scene or group.figure_scene]
    full_pts, fast_pts, truths, counts = [], [], [], []
    for kmh in args.speeds:
        sc = replace(base, speed_kmh=kmh, name=f"{base.name}_{kmh:g}")
        tr = scene_truth(sc, group, radar.frame_period_s)
        tr = tr[(tr.pedestrian == sc.pedestrians[0].name) & (tr.range_m < ego.max_range_m - 2)
                & (tr.y_vehicle_m > 0.2) & (tr.angle_deg.abs() < 75) & ~tr.occluded]
        frames = tr.frame.to_numpy()
        t0 = time.perf_counter()
        res = detect_driving_scene(sc, group, radar, *chain, ego, ex.sim(cfg), frames=frames)
        t_full = time.perf_counter() - t0
        full_pts.append(points_from_detections(res.detections, res.ego, scene=sc.name,
                                               cluster_gap_m=ex.detect(cfg).cluster_gap_m,
                                               static_tolerance_mps=ego.static_tolerance_mps))
        t0 = time.perf_counter()
        res_fast = measure_driving([sc], group, radar, *chain, ego,
                                   adc_headroom_db=ex.sim(cfg).adc_headroom_db,
                                   frames={sc.name: frames})
        t_fast = time.perf_counter() - t0
        fast = res_fast.measured
        fast_pts.append(fast)
        # every point per frame (static world and pedestrian), both chains
        det = res.detections[res.detections.angle_deg.notna()]
        counts.append({"full_points": len(det) / len(frames),
                       "full_static": det.static.sum() / len(frames),
                       "fast_points": len(res_fast.points) / len(frames),
                       "fast_static": res_fast.points.static.sum() / len(frames),
                       "n_frames": len(frames)})
        truths.append(tr)
        print(f"{kmh:g} km/h: {len(frames)} frames; full chain {t_full:.1f} s, fast {t_fast:.1f} s")
    truth = pd.concat(truths)
    full = point_error_statistics(pd.concat(full_pts), truth)
    fast = point_error_statistics(pd.concat(fast_pts).drop(columns=["pedestrian", "x_m", "y_m"]), truth)
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
    if args.mc:
        mc = draw_scenarios(group, base)
        t0 = time.perf_counter()
        m = measure_driving(mc, group, radar, *chain, ego,
                            adc_headroom_db=ex.sim(cfg).adc_headroom_db).points
        out["monte_carlo"] = {"n_scenes": len(mc), "n_points": len(m),
                              "wall_s": time.perf_counter() - t0}
        print(f"Monte-Carlo set: {len(mc)} scenes, {len(m)} points, "
              f"{out['monte_carlo']['wall_s']:.0f} s")
    print(json.dumps(out))


if __name__ == "__main__":
    main()
