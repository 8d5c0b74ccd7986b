"""Speed of passing synthetic paths through the radar chain: prints figures, asserts nothing.

    .venv/bin/python benchmarks/bench_paths.py [--paths N] [--full-frames F] [--threads T]

Draws N paths of the data set's length (``conf/dataset/paper.yaml``), measures them through the
reduced chain (analytic range-Doppler patches + the chain's CFAR, MUSIC and grouping) and prints
frames/s and the projected time for the default data set (``n_paths x points_per_path`` frames
of ``conf/dataset/paper.yaml``). With ``--full-frames F`` it also runs the first F frames
through the full chain (simulated 64 x 12 x 16 x 256 cube + DetectionChain.process) for
comparison. The radar is ``conf/radar/mmwcas.yaml`` with ``adc_bits: 16`` (the paper's dB-domain
CFAR needs the map in ADC-code units), the chain ``conf/cfar/paper.yaml``,
``conf/doa/music.yaml`` and ``conf/detect/paper.yaml``, the walker the paper scene's body.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--paths", type=int, default=16, help="paths to time (default 16)")
    ap.add_argument("--full-frames", type=int, default=0,
                    help="also time this many frames through the full chain")
    ap.add_argument("--threads", type=int, default=None,
                    help="pin BLAS/torch thread pools to this many threads")
    ap.add_argument("--cfar", default="paper", help="conf/cfar/<name>.yaml (default paper)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    if args.threads:
        for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
            os.environ[var] = str(args.threads)

    from omegaconf import OmegaConf

    from blindspot.synth.path_measurement import PedestrianModel, error_statistics, measure_paths
    from blindspot.radar.config import RadarConfig
    from blindspot.radar.scene import load_scenes
    from blindspot.config import compose
    from blindspot.traj.config import DatasetConfig
    from blindspot.traj.paths import random_paths

    if args.threads:
        import torch

        torch.set_num_threads(args.threads)
    conf = REPO / "conf"
    radar_cfg = OmegaConf.to_container(OmegaConf.load(conf / "radar" / "mmwcas.yaml"))
    radar_cfg["adc_bits"] = 16
    radar = RadarConfig.from_mapping(radar_cfg)
    cfar = OmegaConf.load(conf / "cfar" / f"{args.cfar}.yaml")
    doa = OmegaConf.load(conf / "doa" / "music.yaml")
    detect = OmegaConf.load(conf / "detect" / "paper.yaml")
    spec = DatasetConfig.from_mapping(compose(config_dir=conf).dataset).path_spec()
    scene = next(iter(load_scenes(OmegaConf.load(conf / "scene" / "paper.yaml")).values()))
    walker = PedestrianModel.from_scene(scene)
    paths = random_paths(args.paths, spec, seed=args.seed)
    n_frames = paths.shape[0] * paths.shape[1]

    measure_paths(paths[:1, :20], radar, None, cfar, doa, detect, pedestrian=walker,
                  seed=args.seed, progress=False)  # warm-up: imports, caches
    t0 = time.perf_counter()
    m = measure_paths(paths, radar, None, cfar, doa, detect, pedestrian=walker, seed=args.seed,
                      progress=False)
    dt = time.perf_counter() - t0
    fps = n_frames / dt
    total = int(dataset["n_paths"]) * int(dataset["points_per_path"])
    print(f"reduced chain: {n_frames} frames in {dt:.1f} s = {fps:.0f} frames/s")
    print(f"default data set ({dataset['n_paths']} paths x {dataset['points_per_path']} points "
          f"= {total} frames): projected {total / fps:.0f} s (budget 180 s on 2 cores)")
    stats = error_statistics(m, paths)
    print("point errors:", ", ".join(f"{k} {v:.3g}" for k, v in stats.items()))
    rng_m = (paths[..., 0] ** 2 + paths[..., 1] ** 2) ** 0.5
    bands = [(0, 10), (10, 20), (20, 25), (25, 30), (30, 40), (40, 60)]
    print("detection rate by truth range:", ", ".join(
        f"{lo}-{hi} m {m.detected[(rng_m >= lo) & (rng_m < hi)].mean():.2f} "
        f"(n={int(((rng_m >= lo) & (rng_m < hi)).sum())})"
        for lo, hi in bands if ((rng_m >= lo) & (rng_m < hi)).any()))
    if args.full_frames:
        t_pts = paths.shape[1]
        n_p = max(1, -(-args.full_frames // t_pts))
        sub = paths[:n_p, :min(t_pts, args.full_frames)]
        t0 = time.perf_counter()
        measure_paths(sub, radar, None, cfar, doa, detect, pedestrian=walker, seed=args.seed,
                      progress=False, full_chain=True)
        dt = time.perf_counter() - t0
        print(f"full chain: {sub.shape[0] * sub.shape[1]} frames in {dt:.1f} s = "
              f"{sub.shape[0] * sub.shape[1] / dt:.1f} frames/s "
              f"(reduced is {fps / (sub.shape[0] * sub.shape[1] / dt):.0f}x faster)")


if __name__ == "__main__":
    main()
