"""Speed of the many-walk benchmark stage: prints figures, asserts nothing.

    .venv/bin/python benchmarks/bench_walk_scores.py [--walks N] [--jobs J] [--model FILE]

Draws N walks of ``conf/walks/scene_walks.yaml``, measures them through the reduced radar
chain in J processes (the stage's ``jobs``), then fills and predicts them with the stage's
methods (the LSTM of ``data/train/model.pt``, constant velocity, Kalman) on the stage's torch
threads, and prints the seconds of each part, walks/s and the time projected for the stage's
``n_walks`` (the bootstrap and the figure add about a second). Also prints the load average,
since the machine is shared.
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import replace
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--walks", type=int, default=48, help="walks to time (default 48)")
    ap.add_argument("--jobs", type=int, default=2, help="radar worker processes (default 2)")
    ap.add_argument("--model", default=str(REPO / "data/train/model.pt"),
                    help="LSTM checkpoint (default data/train/model.pt)")
    args = ap.parse_args()

    from blindspot import config
    from blindspot.radar.config import RadarConfig
    from blindspot.traj.baselines import kalman_baseline, prediction_methods
    from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig
    from blindspot.radar.scene import load_scenes
    from blindspot.synth.scene_walks import car_scene_walks   # the walks stage's walks
    from blindspot.traj.config import EvalConfig, WalksConfig
    from blindspot.synth.walk_scores import score_scene_walks
    from blindspot.traj.lstm import LSTMPredictor

    cfg = config.compose([], config_dir=REPO / "conf")
    full = WalksConfig.from_cfg(cfg)
    bench = replace(full, n_walks=args.walks)
    ev = EvalConfig.from_cfg(cfg)
    radar = RadarConfig.from_cfg(cfg)
    t0 = time.perf_counter()
    car = next(s for s in load_scenes(cfg.scene).values() if s.with_car)
    walks, measured = car_scene_walks(bench, radar, car, CfarConfig.from_cfg(cfg),
                                      DoaConfig.from_cfg(cfg), DetectConfig.from_cfg(cfg),
                                      seed=0, jobs=args.jobs)
    t1 = time.perf_counter()
    lstm = LSTMPredictor.load(args.model)
    score_scene_walks(walks, measured, predictors=prediction_methods(ev, radar.frame_period_s, lstm),
                      interpolation_methods=ev.interpolation_methods,
                      prediction_input=ev.prediction_input, gap_predictor=lstm,
                      smoother=kalman_baseline(ev, radar.frame_period_s).smooth_batch,
                      horizon=bench.horizon_frames, dt_s=radar.frame_period_s,
                      horizons_s=ev.horizons_s, threads=bench.threads)
    t2 = time.perf_counter()
    frames = int((walks.start).sum())
    radar_s, score_s = t1 - t0, t2 - t1
    per_walk = (radar_s + score_s) / args.walks
    print(f"walks {args.walks}: radar {radar_s:.1f} s ({frames / radar_s:.0f} frames/s, "
          f"{frames} frames, jobs {args.jobs}), interpolation + prediction {score_s:.1f} s")
    print(f"{args.walks / (radar_s + score_s):.2f} walks/s; projected for n_walks = "
          f"{full.n_walks}: {per_walk * full.n_walks:.0f} s (scoring grows less than linearly: "
          f"one batched LSTM call per step)")
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
