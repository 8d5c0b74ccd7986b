"""Two predictors of one safety run, or one predictor of two runs, compared on the same scenes:
paired differences of the avoided rate (intruding scenes) and of the false-activation rate
(non-intruding scenes), with the discordant scene counts and a paired bootstrap interval. Prints
figures, asserts nothing (docs/studies/safety.md, the LSTM and fresh-draw bullets).

    python studies/paired.py [--outcomes data/safety/scene_outcomes.parquet ...]
        [--pairs lstm_direct:constant_velocity,lstm_direct:kalman,lstm:constant_velocity]
        [--inputs tracker,oracle,noisy_position] [--n-bootstrap 10000] [--against B.parquet ...]

With ``--against``, A is read from ``--outcomes`` and B from that second run of the same scenes
(e.g. a setting against the default, both ``dvc repro safety`` on one draw), and a pair may name
one predictor (``constant_velocity`` = ``constant_velocity:constant_velocity``). The two runs
must come from one draw (``scenario.monte_carlo.seed``): scene names do not carry the seed, so
only the names are checked to match, and a run of another draw with the same design passes that
check unnoticed. Several ``--outcomes`` files are several draws pooled (e.g. seeds 0 and 1):
scene k of file i is its own scene, and ``--against`` then names one file per draw, in the same
order. Files with identical contents are refused as two draws.

Both predictors of a pair see the same tracks and the same scenes, so a paired comparison is the
fair one: the unpaired intervals of README's table overlap even where one predictor is better on
nearly every scene where they differ. The interval resamples scenes (with replacement, seed 0);
"A only / B only" count the scenes where just one of the two avoided the collision (or activated
falsely): the exact two-sided McNemar test on those is printed as p. One generator serves all
pairs in order, so an interval depends on the pairs printed before it (the figures of README and
docs/studies/safety.md are for the commands they quote).

Conclusion: neither LSTM earns its place on the tracker's input: the paper's next-point LSTM is
within the interval of constant velocity (avoided +0.037 [-0.009, +0.083], false activations
+0.028 [-0.019, +0.074], McNemar p 0.29 / 0.45) (docs/studies/safety.md).
"""

from __future__ import annotations

import argparse
import hashlib
import io
from pathlib import Path

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads
import numpy as np
import pandas as pd
from scipy.stats import binomtest

REPO = Path(__file__).resolve().parents[1]
#: the columns of data/safety/scene_outcomes.parquet this benchmark reads
OUTCOME_COLUMNS = {"scene", "input", "predictor", "evaluated", "intruding", "avoided",
                   "aeb_frame"}


def paired(a: np.ndarray, b: np.ndarray, n_boot: int, rng: np.random.Generator) -> str:
    """'diff [lo, hi]; A only x, B only y, McNemar p' for two boolean outcomes on the same
    scenes (mean of a minus mean of b)."""
    d = a.astype(float) - b.astype(float)
    idx = rng.integers(0, len(d), (n_boot, len(d)))
    lo, hi = np.quantile(d[idx].mean(axis=1), [0.025, 0.975])
    x, y = int((a & ~b).sum()), int((~a & b).sum())
    p = binomtest(x, x + y, 0.5).pvalue if x + y else 1.0
    return f"{d.mean():+.3f} [{lo:+.3f}, {hi:+.3f}]; A only {x}, B only {y}, McNemar p {p:.2f}"


def pooled(ap: argparse.ArgumentParser, option: str, paths: list[Path]) -> pd.DataFrame:
    """The evaluated rows of the scene_outcomes files of one or more draws; with several, each
    scene name is prefixed by its draw's position (``d0/``, ``d1/``, ...) so draws do not pair.
    Two files of the same contents are refused (one draw counted twice would narrow every
    interval)."""
    parts, seen = [], {}
    for i, path in enumerate(paths):
        if not path.is_file():
            ap.error(f"{option}: {path}: no such file (expected a run's "
                     "data/safety/scene_outcomes.parquet)")
        raw = path.read_bytes()
        digest = hashlib.sha256(raw).hexdigest()
        if digest in seen:
            ap.error(f"{option}: {path} has the same contents as {seen[digest]}; each file must "
                     "be another draw of scenes")
        seen[digest] = path
        try:
            t = pd.read_parquet(io.BytesIO(raw))
        except (OSError, ValueError) as err:   # pyarrow's ArrowInvalid is a ValueError
            ap.error(f"{option}: {path} is not a Parquet table ({err})")
        missing = sorted(OUTCOME_COLUMNS - set(t.columns))
        if missing:
            ap.error(f"{option}: {path} is not a scene_outcomes table: it lacks {missing}")
        t = t[t.evaluated]
        if len(paths) > 1:
            t = t.assign(scene=f"d{i}/" + t.scene.astype(str))
        parts.append(t)
    return pd.concat(parts, ignore_index=True)


def _names(paths: list[Path]) -> str:
    return " + ".join(str(x) for x in paths)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--outcomes", type=Path, nargs="+",
                    default=[REPO / "data/safety/scene_outcomes.parquet"],
                    help="scene_outcomes.parquet of one or more draws (pooled)")
    ap.add_argument("--pairs", default="lstm_direct:constant_velocity,lstm_direct:kalman,"
                                       "lstm:constant_velocity")
    ap.add_argument("--inputs", default="tracker,oracle,noisy_position")
    ap.add_argument("--n-bootstrap", type=int, default=10_000)
    ap.add_argument("--against", type=Path, nargs="+", default=None,
                    help="a second run's scene_outcomes.parquet per draw: B is read from them")
    args = ap.parse_args(argv)
    if args.against is not None and len(args.against) != len(args.outcomes):
        ap.error(f"--against: expected one file per --outcomes draw ({len(args.outcomes)}), "
                 f"found {len(args.against)}")
    same = [q for q in args.pairs.split(",") if len(set(q.split(":"))) == 1]
    if args.against is None and same:
        ap.error(f"--pairs: {same} compare a predictor with itself; name two predictors (A:B), "
                 "or give --against to compare one predictor across two runs")
    s = pooled(ap, "--outcomes", args.outcomes)
    other = s if args.against is None else pooled(ap, "--against", args.against)
    rng = np.random.default_rng(0)
    for inp in args.inputs.split(","):
        q, r = s[s.input == inp], other[other.input == inp]
        for pair in args.pairs.split(","):
            a_name, _, b_name = pair.partition(":")
            b_name = b_name or a_name
            a = q[q.predictor == a_name].set_index("scene")
            b = r[r.predictor == b_name].set_index("scene")
            if a.empty or b.empty:
                print(f"{inp}: {pair}: not both in {_names(args.outcomes)}"
                      + ("" if args.against is None else f" / {_names(args.against)}")
                      + " for this input")
                continue
            if set(a.index) != set(b.index):
                print(f"{inp}: {pair}: {b_name} of {_names(args.against or args.outcomes)} has "
                      f"other scene names than {a_name} of {_names(args.outcomes)} "
                      f"({len(set(a.index) ^ set(b.index))} differ); a paired comparison needs "
                      "the same scenes")
                continue
            b = b.loc[a.index]
            it = a.intruding.to_numpy()
            fa_a, fa_b = (a.aeb_frame >= 0).to_numpy(), (b.aeb_frame >= 0).to_numpy()
            runs = "" if args.against is None else \
                f" (A of {_names(args.outcomes)}, B of {_names(args.against)})"
            print(f"{inp}: A = {a_name}, B = {b_name}{runs} ({it.sum()} intruding, "
                  f"{(~it).sum()} non-intruding scenes)")
            av_a, av_b = a.avoided.to_numpy()[it], b.avoided.to_numpy()[it]
            print(f"  avoided, A - B:           {paired(av_a, av_b, args.n_bootstrap, rng)}")
            print(f"  false activations, A - B: "
                  f"{paired(fa_a[~it], fa_b[~it], args.n_bootstrap, rng)}")


if __name__ == "__main__":
    main()
