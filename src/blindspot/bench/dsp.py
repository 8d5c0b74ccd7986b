"""Speed of the detection chain on one frame.

    python -m blindspot.bench.dsp [--frame FILE.npz] [--threads N] [--json] [--batch N]
                                  [--repeats 50] [--set detect.max_range_m=null ...]

Runs the whole chain (range and Doppler FFTs, channel-summed map, CFAR, MUSIC for up to
``detect.max_detections`` detections, points) with the MMWCAS profile and the paper's config
groups (conf/cfar/paper.yaml, conf/doa/music.yaml, conf/detect/paper.yaml) on one frame,
``--warmup`` times unmeasured, then ``--repeats`` times, and prints the median of every step and
of the whole call. With ``--json`` the last stdout line is
``{"fps": .., "ms_per_frame": .., "steps": {..}, "n_detections": .., ...}``.

The frame: ``FILE.npz`` holding ``cube`` complex64 (chirps, tx, rx, samples), or by default a
simulated frame of the paper's scene (``blindspot.radar.simulator``, scene ``straight_car`` of
conf/scene/paper.yaml, frame 3: car and pedestrian both in view) in 16-bit ADC codes (as captures
are; the paper CFAR's dB-domain scale needs those units).

``--threads N`` pins every thread pool to N threads: the OpenMP/BLAS environment variables are set
before numpy is first imported, threadpoolctl limits the already-loaded BLAS/OpenMP libraries,
the FFTs (FFTW, scipy.fft) get ``workers=N`` and torch ``set_num_threads(N)``. ``--batch N`` also times
``DetectionChain.process_batch`` on N copies of the frame (frames/s of a batch).

The configuration is composed from conf/ through Hydra exactly as the stages compose it
(:func:`blindspot.config.compose`), with the radar in 16-bit ADC codes; ``--set`` takes any
Hydra override.
"""

from __future__ import annotations

import os
import sys

_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")


def _early_threads(argv: list[str]) -> int | None:
    """Read --threads before numpy is imported and export the pool-size variables."""
    for i, a in enumerate(argv):
        value = None
        if a == "--threads" and i + 1 < len(argv):
            value = argv[i + 1]
        elif a.startswith("--threads="):
            value = a.split("=", 1)[1]
        if value is not None and value.isdigit() and int(value) >= 1:
            for var in _THREAD_VARS:
                os.environ[var] = value
            return int(value)
    return None


if __name__ == "__main__":  # only when run as a program, never on import
    _early_threads(sys.argv[1:])

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402


def simulated_frame(cfg, radar, scene_name: str = "straight_car", index: int = 3):
    """One frame of a paper scene from the simulator (returns cube, label)."""
    from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig
    from blindspot.radar.array import array_for
    from blindspot.radar.config import RadarConfig
    from blindspot.radar.scene import load_scenes
    from blindspot.radar.simulator import SimulatedSource

    scenes = load_scenes(cfg.scene)
    if scene_name not in scenes:
        raise SystemExit(f"--scene {scene_name!r}: expected one of {list(scenes)}")
    src = SimulatedSource(scenes[scene_name], radar)
    return src.frame(index), f"simulated paper scene '{scene_name}' frame {index}"


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(prog="python -m blindspot.bench.dsp", description=__doc__.split("\n")[0])
    ap.add_argument("--frame", type=Path, help="npz file with 'cube' complex64 (chirps, tx, rx, samples)")
    ap.add_argument("--threads", type=int, default=None, help="pin all thread pools to N threads")
    ap.add_argument("--json", action="store_true", help="last stdout line is a JSON summary")
    ap.add_argument("--repeats", type=int, default=50)
    ap.add_argument("--warmup", type=int, default=5)
    ap.add_argument("--batch", type=int, default=0, metavar="N",
                    help="also time process_batch on N copies of the frame (frames/s of a batch)")
    ap.add_argument("--scene", default="straight_car")
    ap.add_argument("--frame-index", type=int, default=3)
    ap.add_argument("--set", dest="overrides", action="append", default=[],
                    metavar="KEY=VALUE", help="a Hydra override of conf/ (e.g. "
                    "detect.max_range_m=null for the full 256-bin range, cfar=ca_pfa)")
    args = ap.parse_args(argv)
    if args.threads is not None and args.threads < 1:
        ap.error("--threads must be >= 1")
    if args.batch < 0 or args.repeats < 1 or args.warmup < 0:
        ap.error("--batch and --warmup must be >= 0, --repeats >= 1")

    from contextlib import nullcontext

    limiter = nullcontext()
    pinned = "not pinned"
    if args.threads is not None:
        for var in _THREAD_VARS:
            os.environ.setdefault(var, str(args.threads))
        from threadpoolctl import threadpool_limits

        limiter = threadpool_limits(limits=args.threads)
        import torch

        torch.set_num_threads(args.threads)
        pinned = (f"{args.threads} thread(s): env vars + threadpoolctl + FFT workers (FFTW, "
                  "scipy) + torch")

    from hydra.errors import HydraException

    from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig
    from blindspot.radar.array import array_for
    from blindspot.radar.config import RadarConfig
    from blindspot.radar.scene import load_scenes
    from blindspot.config import compose
    from blindspot.dsp.chain import DetectionChain

    overrides = list(args.overrides)
    if args.frame is None:  # simulated frames in 16-bit ADC codes, as captures are
        overrides.insert(0, "radar.adc_bits=16")
    if args.threads is not None:
        overrides.append(f"detect.workers={args.threads}")
    try:
        cfg = compose(overrides)
    except HydraException as exc:
        raise SystemExit(f"--set: {exc}") from None
    radar = RadarConfig.from_cfg(cfg)
    array = array_for(RadarConfig.from_cfg(cfg))
    if args.frame is not None:
        with np.load(args.frame) as z:
            if "cube" not in z:
                raise SystemExit(f"{args.frame}: no array 'cube' in the file (found {list(z)})")
            cube = z["cube"]
        expected = (radar.n_chirps, radar.n_tx, radar.n_rx, radar.n_samples)
        if cube.shape != expected:
            raise SystemExit(f"{args.frame}: cube shape {cube.shape} does not match the MMWCAS "
                             f"profile (chirps, tx, rx, samples) = {expected}")
        cube = cube.astype(np.complex64, copy=False)
        label = str(args.frame)
    else:
        cube, label = simulated_frame(cfg, radar, args.scene, args.frame_index)

    chain = DetectionChain(radar, array, CfarConfig.from_cfg(cfg), DoaConfig.from_cfg(cfg),
                           DetectConfig.from_cfg(cfg))
    with limiter:
        for _ in range(args.warmup):
            res = chain.process(cube)
        walls, cpus, steps = [], [], []
        for _ in range(args.repeats):
            c0, t0 = time.thread_time(), time.perf_counter()
            res = chain.process(cube)
            walls.append((time.perf_counter() - t0) * 1e3)
            cpus.append((time.thread_time() - c0) * 1e3)
            steps.append(res.timings_ms)
        batch_fps = None
        if args.batch:
            cubes = np.broadcast_to(cube, (args.batch,) + cube.shape).copy()
            chain.process_batch(cubes)
            batch_walls = []
            for _ in range(max(1, min(args.repeats, 5))):
                t0 = time.perf_counter()
                chain.process_batch(cubes)
                batch_walls.append(time.perf_counter() - t0)
            batch_fps = args.batch / float(np.median(batch_walls))
    med = {k: float(np.median([s[k] for s in steps])) for k in steps[0]}
    total = float(np.median(walls))
    cpu = float(np.median(cpus))
    n_det = int(len(res.detections))
    n_doa = int(np.isfinite(res.detections["angle_deg"]).sum())
    print(f"frame: {label}")
    print(f"threads: {pinned}; repeats {args.repeats} after {args.warmup} warm-up runs; "
          f"load average {os.getloadavg()[0]:.2f}")
    print(f"range bins processed: {chain.range_axis_m.size} of {radar.n_samples}; "
          f"detections {n_det}, MUSIC on {n_doa}")
    for k, v in med.items():
        print(f"  {k:<14s} {v:8.3f} ms  ({1e3 / v if v > 0 else float('inf'):9.1f} /s)")
    print(f"  {'total':<14s} {total:8.3f} ms  ({1e3 / total:9.1f} frames/s)")
    print(f"  {'total CPU':<14s} {cpu:8.3f} ms  ({1e3 / cpu:9.1f} frames/s of this thread's CPU "
          "time; less sensitive to other load on the machine)")
    if batch_fps is not None:
        print(f"  batch of {args.batch:<5d} {1e3 / batch_fps:8.3f} ms per frame "
              f"({batch_fps:9.1f} frames/s)")
    if args.json:
        print(json.dumps({"fps": 1e3 / total, "ms_per_frame": total, "steps": med,
                          "n_detections": n_det, "n_music": n_doa, "cpu_ms_per_frame": cpu,
                          "frame": label, "threads": args.threads,
                          "n_range_bins": int(chain.range_axis_m.size),
                          "batch": args.batch or None, "batch_fps": batch_fps}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
