"""Two safety runs side by side on the halves of the Monte-Carlo replicates
(:func:`blindspot.safety.evaluation.replicate_half`: even replicates tune, odd ones are held out):
per predictor of the tracker input, avoided rate (all speeds and <= 40 km/h), false-activation
rate (count / non-intruding scenes) and avoided minus false activations. Prints figures, asserts
nothing (docs/studies/safety.md, the smallest-of CFAR bullet).

    python studies/halves.py BEFORE.parquet AFTER.parquet [--input tracker]

Each file is a ``data/safety/scene_outcomes.parquet`` (``dvc repro safety``; for an experiment,
``dvc exp run -S 'cfar@driving_cfar=so'`` then copy its scene_outcomes.parquet aside).

Conclusion: the two safety runs' halves of the Monte-Carlo replicates (even tune, odd held out)
side by side; used to judge the peak search x tracker Doppler gate combinations
(docs/studies/safety.md, 2026-12-01): the settings that moved were adopted only where the held-out
half agreed.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads
import numpy as np
import pandas as pd

from blindspot.safety.evaluation import replicate_half


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", type=Path, nargs="+", help="scene_outcomes.parquet files")
    ap.add_argument("--input", default="tracker", help="the safety input to score")
    args = ap.parse_args(argv)
    for path in args.runs:
        s = pd.read_parquet(path)
        s = s[s.evaluated & (s.input == args.input)]
        even = replicate_half(s.scene.to_numpy())
        for half, m in (("tuning (even)", even), ("held-out (odd)", ~even),
                        ("all", np.ones(len(s), bool))):
            rows = []
            for p, q in s[m].groupby("predictor"):       # the four predictors
                it, non = q[q.intruding], q[~q.intruding]
                fa = (non.aeb_frame >= 0).to_numpy()
                rows.append(f"{p}: avoided {it.avoided.mean():.2f} (<=40 km/h "
                            f"{it[it.speed_kmh <= 40].avoided.mean():.2f}), false activations "
                            f"{fa.mean():.3f} [{fa.sum()}/{len(fa)}], avoided - FA "
                            f"{it.avoided.mean() - fa.mean():+.2f}")
            print(f"{path} {half} | " + "; ".join(rows))


if __name__ == "__main__":
    main()
