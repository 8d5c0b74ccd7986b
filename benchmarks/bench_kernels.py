"""Do the CPU kernel selectors change our bytes? Hashes of the radar chain and of LSTM training.

    python benchmarks/bench_kernels.py [--only radar|paths|driving|train]

Runs in fresh interpreters, once with blindspot's pinned kernels (blindspot.kernels.PINS) and
once per selector set to another kernel family this machine can run, and prints a table of
hashes:

* radar: the detect stage's work on the tiny profile (2 scenes x 4 frames: simulated frames and
  detections);
* paths: the paths stage's work on 17 of its walks, two of its 16-walk chunks (the reduced
  chain: synthesised patches, CFAR, MUSIC on each frame's moving detections, the pedestrian's
  point);
* driving: the driving_measure stage's work on eight frames of one named driving scene, two
  batches of four (the synthesised range-Doppler map, CFAR, Doppler unwrapping, MUSIC, the
  static test);
* train: 30 Adam steps of a 64-unit LSTM.

A row that differs from the pinned row shows that the selector reaches those bytes, i.e. that a
CPU choosing another kernel family by itself would compute other bytes; the pins make every AVX2
x86-64 machine choose the same family. The radar chain's stages must not be reached by PyTorch's
selectors (MKL, ATen, oneDNN): MKL's AVX2 branch computes other bytes on AMD than on Intel CPUs,
which no pin fixes, so the radar code does not use torch (an import contract in .importlinter;
the paths and driving scripts also report whether torch was loaded), and the PyTorch-selector
rows of paths and driving must say "yes" (their OPENBLAS_CORETYPE row says "NO": BLAS does
reach those bytes). (About a minute per radar row, 10-15 s per paths or driving row on the
project's 2-core machines.)
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
from blindspot import kernels

RADAR = r"""
import blindspot, hashlib, json, sys
import numpy as np, pandas as pd
from blindspot import config
from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig, EgoMotionConfig
from blindspot.radar.config import RadarConfig, SimConfig
from blindspot.radar.scene import load_scenes
from blindspot.radar.scenario import load_scenarios
from blindspot.traj.config import DatasetConfig
from blindspot.radar.simulator import SimulatedSource
from blindspot.synth.scene_detection import detect_scenes

cfg = config.compose(["profile=tiny", "scene.shared.n_frames=4"], config_dir=sys.argv[1])
scenes = dict(list(load_scenes(cfg.scene).items())[:2])
radar, sim = RadarConfig.from_cfg(cfg), SimConfig.from_cfg(cfg)
res = detect_scenes(scenes, radar, CfarConfig.from_cfg(cfg), DoaConfig.from_cfg(cfg), DetectConfig.from_cfg(cfg),
                    sim, jobs=int(sys.argv[2]))
det = pd.concat([r.detections for r in res], ignore_index=True)
frames = SimulatedSource.from_config(next(iter(scenes.values())), radar, sim)
cube = np.stack([frames.frame(i) for i in range(2)])
print(json.dumps({
    "n_detections": len(det),
    "n_moving": int(det["moving"].sum()),
    "detections": hashlib.sha256(pd.util.hash_pandas_object(det, index=True).to_numpy().tobytes()
                                 + det.to_numpy(dtype=str).tobytes()).hexdigest(),
    "frames": hashlib.sha256(cube.tobytes()).hexdigest(),
}))
"""

PATHS = r"""
import blindspot, hashlib, json, sys
import numpy as np, pandas as pd
from blindspot import config
from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig, EgoMotionConfig
from blindspot.radar.config import RadarConfig, SimConfig
from blindspot.radar.scene import load_scenes
from blindspot.radar.scenario import load_scenarios
from blindspot.traj.config import DatasetConfig
from blindspot.synth.path_dataset import measure_path_set, path_table
from blindspot.synth.path_measurement import PedestrianModel
from blindspot.traj.paths import random_path_set

cfg = config.compose(["profile=tiny", "dataset.n_paths=17"], config_dir=sys.argv[1])
radar, dataset = RadarConfig.from_cfg(cfg), DatasetConfig.from_cfg(cfg)
paths = random_path_set(dataset.n_paths, dataset.path_spec(), seed=dataset.seed)
walker = PedestrianModel.from_scene(next(iter(load_scenes(cfg.scene).values())))
measured = measure_path_set(paths, radar, CfarConfig.from_cfg(cfg), DoaConfig.from_cfg(cfg),
                            DetectConfig.from_cfg(cfg), pedestrian=walker, seed=dataset.seed,
                            jobs=int(sys.argv[2]))
table = path_table(paths, measured, radar.frame_period_s)
print(json.dumps({
    "n_points": int(table.x_m.notna().sum()),
    "torch_loaded": "torch" in sys.modules,
    "paths": hashlib.sha256(pd.util.hash_pandas_object(table, index=True).to_numpy().tobytes()
                            ).hexdigest(),
}))
"""

DRIVING = r"""
import blindspot, hashlib, json, sys
import numpy as np, pandas as pd
from blindspot import config
from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig, EgoMotionConfig
from blindspot.radar.config import RadarConfig, SimConfig
from blindspot.radar.scene import load_scenes
from blindspot.radar.scenario import load_scenarios
from blindspot.traj.config import DatasetConfig
from blindspot.synth.driving_measurement import measure_driving

cfg = config.compose([], config_dir=sys.argv[1])
group, named = load_scenarios(cfg.scenario)
scene = named["cpnco"]
frames = np.arange(16, 24)
res = measure_driving([scene], group, RadarConfig.from_cfg(cfg, "driving_radar"), CfarConfig.from_cfg(cfg, "driving_cfar"), DoaConfig.from_cfg(cfg),
                      DetectConfig.from_cfg(cfg), EgoMotionConfig.from_cfg(cfg),
                      adc_headroom_db=SimConfig.from_cfg(cfg).adc_headroom_db, frames={scene.name: frames},
                      frames_per_batch=4, jobs=int(sys.argv[2]))
h = lambda df: hashlib.sha256(pd.util.hash_pandas_object(df, index=True).to_numpy().tobytes()
                              ).hexdigest()
print(json.dumps({"n_points": len(res.points), "torch_loaded": "torch" in sys.modules,
                  "points": h(res.points), "measured": h(res.measured)}))
"""

TRAIN = r"""
import blindspot, hashlib, json, torch
torch.manual_seed(0); torch.set_num_threads(1)
lstm = torch.nn.LSTM(2, 64, batch_first=True); head = torch.nn.Linear(64, 2)
opt = torch.optim.Adam([*lstm.parameters(), *head.parameters()], 1e-3)
x, y = torch.randn(256, 8, 2), torch.randn(256, 2)
for _ in range(30):
    opt.zero_grad()
    out, _ = lstm(x)
    ((head(out[:, -1]) - y) ** 2).mean().backward()
    opt.step()
print(json.dumps({"weights": hashlib.sha256(b"".join(p.detach().numpy().tobytes()
                                                     for p in lstm.parameters())).hexdigest()}))
"""

# another kernel family per selector, each runnable on any x86-64 CPU with AVX2
TORCH_SELECTORS = {"ATEN_CPU_CAPABILITY": "default", "MKL_CBWR": "COMPATIBLE",
                   "ONEDNN_MAX_CPU_ISA": "SSE41"}
VARIANTS = {
    "radar": {"OPENBLAS_CORETYPE": "Sandybridge", "NPY_DISABLE_CPU_FEATURES": "X86_V3",
              **TORCH_SELECTORS},
    "paths": {"OPENBLAS_CORETYPE": "Sandybridge", **TORCH_SELECTORS},
    "driving": {"OPENBLAS_CORETYPE": "Sandybridge", **TORCH_SELECTORS},
    "train": TORCH_SELECTORS,
}
THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def run(code: str, args: list[str], override: dict[str, str], threads: int = 1) -> dict:
    """Run ``code`` in a fresh interpreter with the pins plus ``override``; its JSON line."""
    env = {k: v for k, v in os.environ.items() if k not in kernels.PINS}
    env.update(kernels.PINS, **override)
    env.update({k: str(threads) for k in THREAD_VARS})
    env["PYTHONPATH"] = os.pathsep.join([str(REPO / "src"), str(REPO)])
    out = subprocess.run([sys.executable, "-c", code, *args], env=env, capture_output=True,
                         text=True, timeout=900)
    if out.returncode:
        raise RuntimeError(out.stderr[-3000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


WORK = {"radar": RADAR, "paths": PATHS, "driving": DRIVING}   # the radar chain's workloads


def chain_hashes(work: str, override: dict[str, str], threads: int = 1, jobs: int = 1) -> dict:
    """Hashes of one radar-chain workload of :data:`WORK` (see module docstring) in a fresh
    interpreter with the pins plus ``override``, ``threads`` BLAS/OpenMP threads and ``jobs``
    worker processes."""
    return run(WORK[work], [str(REPO / "conf"), str(jobs)], override, threads)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", choices=sorted(VARIANTS))
    a = ap.parse_args(argv)
    print(f"{'work':6} {'selector':40} hashes (first 12 hex)   same as pinned")
    for work in [a.only] if a.only else sorted(VARIANTS):
        hashes = (lambda o, w=work: chain_hashes(w, o)) if work in WORK else \
            (lambda o: run(TRAIN, [], o))
        pinned = hashes({})
        print(f"{work:6} {'pinned (blindspot.kernels.PINS)':40} "
              + " ".join(str(v)[:12] for v in pinned.values()), flush=True)
        for name, value in VARIANTS[work].items():
            got = hashes({name: value})
            print(f"{work:6} {name + '=' + value:40} "
                  + " ".join(str(v)[:12] for v in got.values())
                  + f"   {'yes' if got == pinned else 'NO'}", flush=True)


if __name__ == "__main__":
    main()
