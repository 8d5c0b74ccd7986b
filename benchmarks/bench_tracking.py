"""Speed of the multi-target tracker (issue 12 budget: tracking + prediction + risk <= 10 ms per
frame with three pedestrians on one core): prints figures, asserts nothing.

    .venv/bin/python benchmarks/bench_tracking.py [--frames N] [--clutter C] [--points P]
        [--tracker gnn_cv|jpda_cv] [--repeat R] [--profile]

Three pedestrians crossing in front of the radar at 10 frames/s (the driving profile's frame
rate), each giving P points per frame around their position (an extended target), plus C
uniform clutter points per frame over 30 m x 30 m; tracked with conf/tracker/<tracker>.yaml in
this process with every thread pool pinned to one thread. Prints the CPU time per frame
(process time, so other jobs on a shared machine inflate it little) and the wall time, the
median of R runs, and the mean number of live tracks per frame. ``--profile`` prints the 20
costliest functions (cProfile) of one run.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import time
from pathlib import Path

import numpy as np
import pandas as pd
from omegaconf import OmegaConf
from threadpoolctl import threadpool_limits

from blindspot.track import TrackerConfig, track_points

REPO = Path(__file__).resolve().parents[1]
DT = 0.1


def scene(n_frames: int, n_clutter: int, n_points: int, seed: int = 0) -> pd.DataFrame:
    """Points of three walkers (1.4, 1.0, 1.2 m/s; P points each, 0.12 m spread) and clutter."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_frames) * DT
    walkers = [np.column_stack([-6 + 1.4 * t, 8 + 0.0 * t]),
               np.column_stack([5 - 1.0 * t, 12 + 0.2 * t]),
               np.column_stack([-2 + 0.3 * t, 20 - 1.2 * t])]
    frames = [np.repeat(np.arange(n_frames), n_points)] * 3 + [np.repeat(np.arange(n_frames),
                                                                         n_clutter)]
    xy = [np.repeat(w, n_points, axis=0) + rng.normal(0, 0.12, (n_frames * n_points, 2))
          for w in walkers]
    xy.append(rng.uniform(-15, 15, (n_frames * n_clutter, 2)) + [0, 15])
    f = np.concatenate(frames)
    df = pd.DataFrame({"frame": f, "time_s": f * DT, "x_m": np.concatenate(xy)[:, 0],
                       "y_m": np.concatenate(xy)[:, 1]})
    return df.sort_values("frame", kind="stable").reset_index(drop=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--clutter", type=int, default=3)
    ap.add_argument("--points", type=int, default=3)
    ap.add_argument("--tracker", default="gnn_cv")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--profile", action="store_true")
    args = ap.parse_args()
    cfg = TrackerConfig.from_mapping(OmegaConf.load(REPO / "conf" / "tracker" / f"{args.tracker}.yaml"))
    pts = scene(args.frames, args.clutter, args.points)
    with threadpool_limits(1):
        tracks = track_points(pts, cfg)  # warm-up: imports, caches
        cpu, wall = [], []
        for _ in range(args.repeat):
            c0, w0 = time.process_time(), time.perf_counter()
            tracks = track_points(pts, cfg)
            cpu.append(time.process_time() - c0)
            wall.append(time.perf_counter() - w0)
        if args.profile:
            prof = cProfile.Profile()
            prof.runcall(track_points, pts, cfg)
            pstats.Stats(prof).sort_stats("cumulative").print_stats(20)
    n = args.frames
    live = len(tracks) / n
    confirmed = tracks[tracks.confirmed].track_id.nunique()
    print(f"tracker {args.tracker}: {n} frames, 3 pedestrians x {args.points} points + "
          f"{args.clutter} clutter points per frame; {live:.1f} live tracks per frame "
          f"(confirmed ids: {confirmed})")
    print(f"  CPU  {1e3 * np.median(cpu) / n:.2f} ms per frame (median of {args.repeat})")
    print(f"  wall {1e3 * np.median(wall) / n:.2f} ms per frame")


if __name__ == "__main__":
    main()
