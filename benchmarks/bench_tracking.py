"""Speed of the multi-target tracker (issue 12 budget: tracking + prediction + risk <= 10 ms per
frame with three pedestrians on one core): prints figures, asserts nothing.

    .venv/bin/python benchmarks/bench_tracking.py [--frames N] [--clutter C] [--points P]
        [--tracker gnn_cv|jpda_cv] [--repeat R] [--profile]
    .venv/bin/python benchmarks/bench_tracking.py --driving [DATA] [--scenes N] [--tracker ...]

Three pedestrians crossing in front of the radar at 10 frames/s (the driving profile's frame
rate), each giving P points per frame around their position (an extended target), plus C
uniform clutter points per frame over 30 m x 30 m; tracked with conf/tracker/<tracker>.yaml in
this process with every thread pool pinned to one thread. Prints the CPU time per frame
(process time, so other jobs on a shared machine inflate it little) and the wall time, the
median of R runs, and the mean number of live tracks per frame. ``--profile`` prints the 20
costliest functions (cProfile) of one run (with ``--driving``: of the slowest scene, by own
time).

``--driving [DATA]`` (default the repository's ``data``) times the tracker on the driving scenes'
own point clouds instead: ``DATA/driving/points.parquet`` (every radar point of every frame, parked
cars and kerb clutter included) and ``DATA/driving/truth.parquet`` of a ``dvc repro
driving_measure``, put together exactly as the driving_track stage does
(``driving_track.tracker_input``: every frame stepped, the ego's position as the Doppler's line of
sight and its yaw as the field of view's boresight), the configured tracker group of ``params.yaml`` (its ``tracker`` key; ``--tracker`` loads
``conf/tracker/<name>.yaml`` instead), one scene after another in this process on one thread.
``--scenes N`` times N scenes spread evenly over the sorted scene names (default all of them: 226
scenes, about 2 minutes). Prints the tracker's name, points and live tracks per frame (mean and
95th percentile) and the CPU time per frame over all frames and per scene (median and the slowest
scene): what the issue's 10 ms budget has to hold on a realistic cloud, where the synthetic scene
above has 3 clutter points a frame.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import sys
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


def driving_clouds(data: Path, n_scenes: int | None) -> pd.DataFrame:
    """The driving_track stage's tracker input (``group`` = scene) from DATA/driving/."""
    from blindspot.synth.driving_tracks import tracker_input

    paths = {n: data / "driving" / f"{n}.parquet" for n in ("truth", "points")}
    for name, path in paths.items():
        if not path.is_file():
            raise SystemExit(f"bench_tracking --driving: {path} not found (the {name} of "
                             "`dvc repro driving_measure`, or `dvc checkout`)")
    truth = pd.read_parquet(paths["truth"], columns=["scene", "frame", "time_s", "ego_x_m",
                                                     "ego_y_m", "ego_yaw_deg"])
    points = pd.read_parquet(paths["points"], columns=["scene", "frame", "x_m", "y_m",
                                                       "velocity_over_ground_mps"])
    scenes = np.array(sorted(truth.scene.unique()))
    if not len(scenes):
        raise SystemExit(f"bench_tracking --driving: {paths['truth']} holds no scene")
    if n_scenes is not None:
        if n_scenes < 1:
            raise SystemExit(f"bench_tracking --scenes: expected at least 1, got {n_scenes}")
        scenes = scenes[np.linspace(0, len(scenes) - 1, min(n_scenes, len(scenes))).astype(int)]
        truth, points = truth[truth.scene.isin(scenes)], points[points.scene.isin(scenes)]
    pts, _ = tracker_input(truth, points)
    return pts


def bench_driving(args, cfg: TrackerConfig, name: str) -> None:
    """Time ``cfg`` scene by scene on the driving clouds of ``args.driving``; print the
    figures (module docstring)."""
    pts = driving_clouds(Path(args.driving), args.scenes)
    groups = [g for _, g in pts.groupby("group", sort=True)]
    with threadpool_limits(1):
        track_points(groups[0], cfg)  # warm-up: imports, caches
        cpu, frames, live = [], [], []
        for g in groups:
            c0 = time.process_time()
            tracks = track_points(g, cfg)
            cpu.append(time.process_time() - c0)
            frames.append(g.frame.nunique())
            live.append(tracks.groupby("frame").size().reindex(g.frame.unique(), fill_value=0))
        if args.profile:
            prof = cProfile.Profile()
            prof.runcall(track_points, groups[int(np.argmax(cpu))], cfg)
            pstats.Stats(prof).sort_stats("tottime").print_stats(20)
    cpu, frames = np.array(cpu), np.array(frames)
    per_frame_pts = pts.groupby(["group", "frame"]).x_m.count()
    live = pd.concat(live)
    per_scene = 1e3 * cpu / frames
    print(f"tracker {name} on the driving clouds ({args.driving}/driving/points.parquet): "
          f"{len(groups)} scenes, {frames.sum()} frames")
    print(f"  points per frame  mean {per_frame_pts.mean():.1f}, p95 "
          f"{np.percentile(per_frame_pts, 95):.0f}, max {per_frame_pts.max()}")
    print(f"  live tracks per frame (tentative included)  mean {live.mean():.1f}, p95 "
          f"{np.percentile(live, 95):.0f}")
    print(f"  CPU  {1e3 * cpu.sum() / frames.sum():.2f} ms per frame over all frames; per scene "
          f"median {np.median(per_scene):.2f}, slowest {per_scene.max():.2f} ms per frame")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--clutter", type=int, default=3)
    ap.add_argument("--points", type=int, default=3)
    ap.add_argument("--tracker", default=None)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--profile", action="store_true")
    ap.add_argument("--driving", nargs="?", const=str(REPO / "data"), default=None,
                    metavar="DATA")
    ap.add_argument("--scenes", type=int, default=None)
    args = ap.parse_args()
    synthetic = [f"--{k}" for k in ("frames", "clutter", "points", "repeat")
                 if getattr(args, k) != ap.get_default(k)]
    if args.driving is None and args.scenes is not None:
        ap.error("--scenes needs --driving")
    if args.driving is not None and synthetic:
        ap.error(f"{', '.join(synthetic)}: the synthetic scene's options, not used with "
                 "--driving")
    if args.driving is not None:
        tracker = (OmegaConf.load(REPO / "params.yaml").tracker if args.tracker is None
                   else OmegaConf.load(REPO / "conf" / "tracker" / f"{args.tracker}.yaml"))
        return bench_driving(args, TrackerConfig.from_mapping(tracker), str(tracker.name))
    cfg = TrackerConfig.from_mapping(OmegaConf.load(
        REPO / "conf" / "tracker" / f"{args.tracker or 'gnn_cv'}.yaml"))
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
    print(f"tracker {args.tracker or 'gnn_cv'}: {n} frames, 3 pedestrians x {args.points} "
          f"points + {args.clutter} clutter points per frame; {live:.1f} live tracks per frame "
          f"(confirmed ids: {confirmed})")
    print(f"  CPU  {1e3 * np.median(cpu) / n:.2f} ms per frame (median of {args.repeat})")
    print(f"  wall {1e3 * np.median(wall) / n:.2f} ms per frame")


if __name__ == "__main__":
    main()
