"""Speed of the FMCW simulator: one MMWCAS frame (64 x 12 x 16 x 256) of a paper scene.

    python benchmarks/bench_simulator.py [--threads 1] [--repeats 30] [--scene approach_car]
                                         [--adc-bits 16] [--json]

Prints the median per step over ``--repeats`` frames (after a warm-up), as wall-clock ms and as
CPU ms of the calling thread (``time.thread_time``). With ``--threads 1`` every library thread
pool is pinned to one thread, so all the work runs on the calling thread and its CPU time is the
one-core cost even on a machine shared with other jobs (wall time then also counts waiting for
the core). With ``--json`` the last stdout line is
``{"ms_per_frame": .., "cpu_ms_per_frame": .., "steps": {name: {"wall_ms": .., "cpu_ms": ..}}}``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path


def _parse(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--threads", type=int, default=1, help="library threads (default 1)")
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--scene", default="approach_car", help="a scene of conf/scene/paper.yaml")
    ap.add_argument("--adc-bits", type=int, default=None, help="quantise to this many bits")
    ap.add_argument("--json", action="store_true")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = _parse(argv)
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = str(args.threads)   # before numpy/scipy load their BLAS

    import numpy as np
    from omegaconf import OmegaConf
    from scipy.linalg import blas
    from threadpoolctl import threadpool_limits

    from blindspot.radar.config import RadarConfig
    from blindspot.radar.scene import load_scenes
    from blindspot.radar.simulator import SimulatedSource, frame_bit_generator, quantise

    root = Path(__file__).resolve().parents[1]
    radar_map = OmegaConf.to_container(OmegaConf.load(root / "conf/radar/mmwcas.yaml"))
    if args.adc_bits is not None:
        radar_map["adc_bits"] = args.adc_bits
    radar = RadarConfig.from_mapping(radar_map)
    scenes = load_scenes(OmegaConf.load(root / "conf/scene/paper.yaml"))
    if args.scene not in scenes:
        print(f"unknown scene {args.scene!r}; choose from {sorted(scenes)}", file=sys.stderr)
        return 2
    src = SimulatedSource(scenes[args.scene], radar)
    sim = src.simulator
    out = np.empty(sim.shape, dtype=np.complex64)
    frames = np.arange(args.repeats) % src.n_frames
    times: dict[str, list[tuple[float, float]]] = {}

    def timed(name, fn):
        w, c = time.perf_counter(), time.thread_time()
        result = fn()
        times.setdefault(name, []).append((time.perf_counter() - w, time.thread_time() - c))
        return result

    with threadpool_limits(limits=args.threads):
        src.frame(0)                                          # warm-up (buffers, BLAS)
        for i in frames:
            t = float(src.times_s[i])
            sc = timed("scene", lambda: src.scene.scatterers_at(t))
            left, right = timed("factors", lambda: sim.signal_factors(*sc))
            timed("noise", lambda: sim.add_noise(out, frame_bit_generator(1, int(i))))
            timed("gemm", lambda: blas.cgemm(1.0, right.T, left.T, beta=1.0,
                                             c=out.reshape(-1, sim.shape[-1]).T, overwrite_c=1))
            if radar.adc_bits is not None:
                timed("quantise", lambda: quantise(out, radar.adc_bits, out=out))
            timed("frame_into_buffer", lambda: src.frame(int(i), out=out))
            timed("frame", lambda: src.frame(int(i)))

    med = {k: (1e3 * float(np.median([w for w, _ in v])), 1e3 * float(np.median([c for _, c in v])))
           for k, v in times.items()}
    print(f"FMCW simulator, scene {args.scene}: {sim.shape} complex64, K = {src.scene.n_scatterers} "
          f"scatterers, threads {args.threads}, median of {args.repeats} frames")
    print(f"{'step':<20}{'wall ms':>10}{'cpu ms':>10}")
    for k, (w, c) in med.items():
        print(f"{k:<20}{w:>10.2f}{c:>10.2f}")
    total_w, total_c = med["frame"]
    print(f"ms/frame (fresh cube): {total_w:.1f} wall, {total_c:.1f} cpu "
          f"-> {1e3 / total_w:.1f} frames/s")
    if args.json:
        print(json.dumps({"ms_per_frame": total_w, "cpu_ms_per_frame": total_c,
                          "steps": {k: {"wall_ms": w, "cpu_ms": c} for k, (w, c) in med.items()}}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
