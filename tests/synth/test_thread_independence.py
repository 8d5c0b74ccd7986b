"""The radar stages compute the same bytes whatever the thread settings (issue 10.0).

The detect stage's work (simulate every frame, run the detection chain, MUSIC) is run in fresh
interpreters under two thread settings: BLAS/OpenMP/MKL pools of 1 thread in one process, and
pools of 2 threads with two worker processes. The simulated frames and the detections must be
identical to the last bit, so the committed dvc.lock holds whatever OMP_NUM_THREADS a user has.
(Kernels of other CPUs, e.g. AVX-512 BLAS, are outside what one machine can test.)
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from tests.conftest import REPO_ROOT

SCRIPT = r"""
import hashlib, json, sys
import numpy as np, pandas as pd
from blindspot import config, experiment
from blindspot.radar.simulator import SimulatedSource
from blindspot.synth.scene_detection import detect_scenes

cfg = config.compose(["profile=tiny", "scene.shared.n_frames=4"], config_dir=sys.argv[1])
scenes = dict(list(experiment.scenes(cfg).items())[:2])  # two scenes: one per worker process
radar, sim = experiment.radar(cfg), experiment.sim(cfg)
res = detect_scenes(scenes, radar, experiment.cfar(cfg), experiment.doa(cfg), experiment.detect(cfg),
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

THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def run_detect(threads: int, jobs: int) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARS}
    env.update({k: str(threads) for k in THREAD_VARS})
    env["PYTHONPATH"] = os.pathsep.join([str(REPO_ROOT / "src"), str(REPO_ROOT)])
    out = subprocess.run([sys.executable, "-c", SCRIPT, str(REPO_ROOT / "conf"), str(jobs)],
                         env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.slow  # two fresh interpreters simulating and detecting: about 1 min
@pytest.mark.timeout(900)
def test_detections_and_frames_do_not_depend_on_thread_settings():
    one = run_detect(threads=1, jobs=1)
    two = run_detect(threads=2, jobs=2)
    assert one["n_moving"] > 0, one  # the pedestrian is seen in these frames
    assert one == two
