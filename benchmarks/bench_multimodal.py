"""Speed of the multi-modal predictor in the warning step: one call of prediction + collision
risk for three pedestrian tracks, on one core, against the single-Gaussian direct predictor of
the same size. Prints figures, asserts nothing.

    PYTHONPATH=src .venv/bin/python benchmarks/bench_multimodal.py [--repeat R] [--modes M] \
        [--horizon H] [--tracks B]

The networks have the ETH/UCY benchmark's shape (conf/ethucy/standard.yaml: MLP encoder, 64
units, head 128, 8 observed points; ``--modes`` hypotheses, default 20) with untrained weights:
the time does not depend on their values. ``--horizon`` future steps (default 30: the safety
chain's 3 s at 0.1 s). Times are CPU time of this process (time.process_time); issue 12's budget
is 10 ms per frame for tracking + prediction + risk with three pedestrians.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_v] = "1"                      # one core, before numpy loads

import argparse  # noqa: E402
import time  # noqa: E402

import blindspot  # noqa: E402,F401
import numpy as np  # noqa: E402
import torch  # noqa: E402

from blindspot.safety.risk import EgoShape, collision_risk, mixture_collision_risk  # noqa: E402
from blindspot.traj.config import Seq2SeqConfig  # noqa: E402
from blindspot.traj.multimodal import MultiModalPredictor  # noqa: E402
from blindspot.traj.seq2seq import Seq2SeqEnsemble, Seq2SeqModel, Seq2SeqNet  # noqa: E402


def _ms(fn, repeat: int) -> tuple[float, float]:
    fn()                                                            # warm-up
    times = []
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        times.append(1e3 * (time.process_time() - t0))
    return float(np.median(times)), float(np.percentile(times, 99))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=300)
    ap.add_argument("--modes", type=int, default=20)
    ap.add_argument("--horizon", type=int, default=30)
    ap.add_argument("--tracks", type=int, default=3)
    a = ap.parse_args()
    torch.set_num_threads(1)
    cfg = Seq2SeqConfig(cell="mlp", horizon=a.horizon, ensemble=1, neighbours=0, threads=1)
    single = Seq2SeqEnsemble([Seq2SeqModel(Seq2SeqNet(cfg), cfg)])
    mcfg = Seq2SeqConfig(cell="mlp", horizon=a.horizon, ensemble=1, neighbours=0, threads=1,
                         modes=a.modes)
    multi = MultiModalPredictor(Seq2SeqEnsemble([Seq2SeqModel(Seq2SeqNet(mcfg), mcfg)]))
    rng = np.random.default_rng(0)
    hist = np.cumsum(rng.normal([0.0, 0.14], 0.02, (a.tracks, 50, 2)), axis=1)
    ego = (np.zeros((a.tracks, 2)), np.zeros(a.tracks), np.full(a.tracks, 13.9), 0.1,
           EgoShape(1.815, 4.358))
    rows = {
        "direct (one Gaussian): predict_distribution": lambda: single.predict_distribution(
            hist, a.horizon),
        "direct (one Gaussian): + collision_risk": lambda: collision_risk(
            single.predict_distribution(hist, a.horizon), *ego, margin_m=0.3),
        f"mix ({a.modes} hypotheses): predict_mixture": lambda: multi.predict_mixture(
            hist, a.horizon),
        f"mix ({a.modes} hypotheses): + mixture_collision_risk": lambda: mixture_collision_risk(
            multi.predict_mixture(hist, a.horizon), *ego, margin_m=0.3),
    }
    print(f"{a.tracks} tracks, horizon {a.horizon}, {a.repeat} calls, CPU ms per call:")
    for name, fn in rows.items():
        med, p99 = _ms(fn, a.repeat)
        print(f"  {name}: median {med:.2f}, p99 {p99:.2f}")


if __name__ == "__main__":
    main()
