"""Two predictors of one safety run compared on the same scenes: paired differences of the avoided
rate (intruding scenes) and of the false-activation rate (non-intruding scenes), with the
discordant scene counts and a paired bootstrap interval. Prints figures, asserts nothing
(README, "Does it protect a child", the LSTM bullet).

    python benchmarks/bench_paired.py [--outcomes data/safety/scene_outcomes.parquet]
        [--pairs lstm_direct:constant_velocity,lstm_direct:kalman,lstm:constant_velocity]
        [--inputs tracker,oracle,visible_truth] [--n-bootstrap 10000]

Both predictors of a pair see the same tracks and the same scenes, so a paired comparison is the
fair one: the unpaired intervals of README's table overlap even where one predictor is better on
nearly every scene where they differ. The interval resamples scenes (with replacement, seed 0);
"A only / B only" count the scenes where just one of the two avoided the collision (or activated
falsely): the exact two-sided McNemar test on those is printed as p.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads
import numpy as np
import pandas as pd
from scipy.stats import binomtest

REPO = Path(__file__).resolve().parents[1]


def paired(a: np.ndarray, b: np.ndarray, n_boot: int, rng: np.random.Generator) -> str:
    """'diff [lo, hi]; A only x, B only y, McNemar p' for two boolean outcomes on the same
    scenes (mean of a minus mean of b)."""
    d = a.astype(float) - b.astype(float)
    idx = rng.integers(0, len(d), (n_boot, len(d)))
    lo, hi = np.quantile(d[idx].mean(axis=1), [0.025, 0.975])
    x, y = int((a & ~b).sum()), int((~a & b).sum())
    p = binomtest(x, x + y, 0.5).pvalue if x + y else 1.0
    return f"{d.mean():+.3f} [{lo:+.3f}, {hi:+.3f}]; A only {x}, B only {y}, McNemar p {p:.2f}"


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--outcomes", type=Path, default=REPO / "data/safety/scene_outcomes.parquet")
    ap.add_argument("--pairs", default="lstm_direct:constant_velocity,lstm_direct:kalman,"
                                       "lstm:constant_velocity")
    ap.add_argument("--inputs", default="tracker,oracle,visible_truth")
    ap.add_argument("--n-bootstrap", type=int, default=10_000)
    args = ap.parse_args(argv)
    s = pd.read_parquet(args.outcomes)
    s = s[s.evaluated]
    rng = np.random.default_rng(0)
    for inp in args.inputs.split(","):
        q = s[s.input == inp]
        for pair in args.pairs.split(","):
            a_name, b_name = pair.split(":")
            a = q[q.predictor == a_name].set_index("scene")
            b = q[q.predictor == b_name].set_index("scene")
            if a.empty or b.empty:
                print(f"{inp}: {pair}: not both in {args.outcomes} for this input")
                continue
            b = b.loc[a.index]
            it = a.intruding.to_numpy()
            fa_a, fa_b = (a.aeb_frame >= 0).to_numpy(), (b.aeb_frame >= 0).to_numpy()
            print(f"{inp}: A = {a_name}, B = {b_name} ({it.sum()} intruding, {(~it).sum()} "
                  f"non-intruding scenes)")
            av_a, av_b = a.avoided.to_numpy()[it], b.avoided.to_numpy()[it]
            print(f"  avoided, A - B:           {paired(av_a, av_b, args.n_bootstrap, rng)}")
            print(f"  false activations, A - B: "
                  f"{paired(fa_a[~it], fa_b[~it], args.n_bootstrap, rng)}")


if __name__ == "__main__":
    main()
