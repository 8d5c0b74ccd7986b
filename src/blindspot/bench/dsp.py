"""Speed of the detection chain on one frame.

    python -m blindspot.bench.dsp [--frame FILE.npz] [--threads N] [--json]
                                  [--repeats 50] [--set detect.max_range_m=30 ...]

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
scipy.fft gets ``workers=N`` and torch (if loaded) ``set_num_threads(N)``.
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

REPO_ROOT = Path(__file__).resolve().parents[3]
CONF = REPO_ROOT / "conf"


def _load_yaml(path: Path) -> dict:
    from omegaconf import OmegaConf

    if not path.is_file():
        raise FileNotFoundError(f"config file {path} not found (run from a blindspot checkout)")
    return OmegaConf.to_container(OmegaConf.load(path), resolve=True)  # type: ignore[return-value]


def load_configs(overrides: list[str]) -> dict[str, dict]:
    """radar / cfar / doa / detect mappings: the paper profiles plus ``group.key=value``
    overrides (values parsed as YAML)."""
    import yaml

    cfg = {
        "radar": _load_yaml(CONF / "radar" / "mmwcas.yaml"),
        "cfar": _load_yaml(CONF / "cfar" / "paper.yaml"),
        "doa": _load_yaml(CONF / "doa" / "music.yaml"),
        "detect": _load_yaml(CONF / "detect" / "paper.yaml"),
    }
    for item in overrides:
        key, sep, value = item.partition("=")
        group, _, name = key.partition(".")
        if not sep or group not in cfg or not name:
            raise SystemExit(f"--set expects group.key=value with group in {sorted(cfg)}, got {item!r}")
        cfg[group][name] = yaml.safe_load(value)
    return cfg


def simulated_frame(radar, scene_name: str = "straight_car", index: int = 3):
    """One frame of a paper scene from the simulator (returns cube, label)."""
    from blindspot.radar.scene import load_scenes
    from blindspot.radar.simulator import SimulatedSource

    scenes = load_scenes(_load_yaml(CONF / "scene" / "paper.yaml"))
    src = SimulatedSource(scenes[scene_name], radar)
    return src.frame(index), f"simulated paper scene '{scene_name}' frame {index}"


def synthetic_frame(radar, array, seed: int = 0):
    """Fallback when no simulator is available: ideal point targets (two static car points at 5 m
    and 8.5 m, a pedestrian at 12 m moving at -0.7 m/s) plus white noise. Clearly not physics."""
    from blindspot.radar.config import SPEED_OF_LIGHT

    c = np.arange(radar.n_chirps)[:, None, None, None]
    t = np.arange(radar.n_tx)[None, :, None, None]
    s = np.arange(radar.n_samples)[None, None, None, :]
    p = (array.virtual_pos[..., 0] * array.spacing_wl)[None, :, :, None]
    rng = np.random.default_rng(seed)
    shape = (radar.n_chirps, radar.n_tx, radar.n_rx, radar.n_samples)
    cube = 30 * (rng.standard_normal(shape) + 1j * rng.standard_normal(shape))
    for r_m, v, ang, amp in ((5.0, 0.0, 17.0, 3e4), (8.5, 0.0, 10.0, 1e4), (12.5, -0.7, 36.0, 500)):
        fb = 2 * radar.slope_hz_per_s * r_m / SPEED_OF_LIGHT
        fd = 2 * v / radar.wavelength_m
        ph = (fb * s / radar.adc_rate_hz + fd * (c * radar.loop_period_s + t * radar.chirp_period_s)
              + p * np.sin(np.radians(ang)))
        cube = cube + amp * np.exp(2j * np.pi * ph)
    return cube.astype(np.complex64), "SYNTHETIC point targets (no simulator available)"


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(prog="python -m blindspot.bench.dsp", description=__doc__.split("\n")[0])
    ap.add_argument("--frame", type=Path, help="npz file with 'cube' complex64 (chirps, tx, rx, samples)")
    ap.add_argument("--threads", type=int, default=None, help="pin all thread pools to N threads")
    ap.add_argument("--json", action="store_true", help="last stdout line is a JSON summary")
    ap.add_argument("--repeats", type=int, default=50)
    ap.add_argument("--warmup", type=int, default=5)
    ap.add_argument("--scene", default="straight_car")
    ap.add_argument("--frame-index", type=int, default=3)
    ap.add_argument("--set", dest="overrides", action="append", default=[],
                    metavar="GROUP.KEY=VALUE", help="override a config key (radar/cfar/doa/detect)")
    args = ap.parse_args(argv)
    if args.threads is not None and args.threads < 1:
        ap.error("--threads must be >= 1")

    from contextlib import nullcontext

    limiter = nullcontext()
    pinned = "not pinned"
    if args.threads is not None:
        for var in _THREAD_VARS:
            os.environ.setdefault(var, str(args.threads))
        from threadpoolctl import threadpool_limits

        limiter = threadpool_limits(limits=args.threads)
        if "torch" in sys.modules:
            sys.modules["torch"].set_num_threads(args.threads)
        pinned = f"{args.threads} thread(s): env vars + threadpoolctl + scipy.fft workers"

    from blindspot.dsp.chain import DetectionChain
    from blindspot.radar.array import array_for
    from blindspot.radar.config import RadarConfig

    cfg = load_configs(args.overrides)
    if args.threads is not None:
        cfg["detect"]["workers"] = args.threads
    if args.frame is None and cfg["radar"].get("adc_bits") is None:
        cfg["radar"]["adc_bits"] = 16  # simulated frames in ADC codes, like captures
    radar = RadarConfig.from_mapping(cfg["radar"])
    array = array_for(radar)
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
        try:
            cube, label = simulated_frame(radar, args.scene, args.frame_index)
        except ImportError:
            cube, label = synthetic_frame(radar, array)

    chain = DetectionChain.from_config(radar, array, cfg["cfar"], cfg["doa"], cfg["detect"])
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
    if args.json:
        print(json.dumps({"fps": 1e3 / total, "ms_per_frame": total, "steps": med,
                          "n_detections": n_det, "n_music": n_doa, "cpu_ms_per_frame": cpu, "frame": label,
                          "threads": args.threads, "n_range_bins": int(chain.range_axis_m.size)}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
