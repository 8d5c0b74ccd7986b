"""A minimum track age before a track may request AEB, scored on the halves of the Monte-Carlo
scenes from a run's stored risk rows. Prints figures, asserts nothing.

    BLINDSPOT_SHARED=../shared .venv/bin/python \
        studies/track_age.py [--data data] [--ages 0,5,6,7,8] \
        [--predictors constant_velocity,kalman,lstm_direct,none] [--since first_row|moving]

Production AEB systems commonly require an object to have been tracked for a while before
they brake for it ("object maturity"). Most false activations of the default run come from
clutter tracks 3-7 rows old (``moving_diagnosis.py``). For each age A, the tracker
input's risk rows (DATA/safety/risk.parquet) of tracks younger than A rows at the row's frame
(rows since the track's first row in DATA/driving/tracks.parquet, tentative and coasting rows
included, the row itself counted) are dropped. The outcome is then scored behind the configured
AEB gate and thresholds (``aeb_gate``'s machinery), on the tuning half (even replicates)
and the held-out half (odd): avoided collisions / false activations of 54 each. Dropping the
rows also drops their warnings; only the AEB outcome is scored. With ``--since moving`` the age
is counted from the track's first row classed moving instead (the persistence of the moving
class: most of those clutter tracks request AEB in the very frame they are first classed
moving). Time: about 30 s.

Conclusion: a minimum track age before AEB: measured, not adopted; 5 rows removes at most one
false activation held out (CV 20/7 | 14/2 -> 20/6 | 14/2), the first frame of persistence costs
2-5 avoided collisions per half (docs/studies/safety.md, 2026-12-01).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads
import pandas as pd

REPO = Path(__file__).resolve().parents[1]

from aeb_gate import half_counts, half_results, load_inputs, outcome_setup  # noqa: E402


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=REPO / "data")
    ap.add_argument("--ages", default="0,5,6,7,8", help="comma-separated minimum ages, rows")
    ap.add_argument("--predictors", default="constant_velocity,kalman,lstm_direct,none")
    ap.add_argument("--since", choices=("first_row", "moving"), default="first_row",
                    help="count a track's age from its first row or its first moving row")
    args = ap.parse_args(argv)
    try:
        ages = [int(a) for a in args.ages.split(",")]
    except ValueError:
        ap.error(f"--ages: expected comma-separated integers, found {args.ages!r}")
    _, w, _, bodies, shape, truth_all, meta, risk = load_inputs(args.data, "tracker")
    truth = truth_all[truth_all.set == "monte_carlo"]
    setup = outcome_setup(truth, meta, bodies, shape, w)
    tracks = pd.read_parquet(args.data / "driving/tracks.parquet")
    rows = tracks[tracks.moving] if args.since == "moving" else tracks
    born = rows.groupby(["group", "track_id"]).frame.min().rename("born")
    risk = risk.join(born, on=["group", "track_id"])
    age = risk.frame - risk.born + 1
    known = sorted(risk.predictor.unique())
    since = args.since.replace("_", " ")
    print(f"minimum track age before AEB (rows since its {since}): avoided / false activations "
          "of 54, tuning half (even replicates) | held-out half (odd)")
    for pred in args.predictors.split(","):
        if pred not in known:
            ap.error(f"--predictors: {pred!r} has no tracker risk rows; expected some of {known}")
        r = risk[risk.predictor == pred]
        cells = []
        for a in ages:
            res = half_results(r[age.loc[r.index] >= a], setup, w)
            counts = [half_counts(res[h]) for h in ("tune", "held_out")]
            cells.append(f"{a}: " + " | ".join(f"{c['n_avoided']}/{c['n_false']}"
                                                for c in counts))
        print(f"  {pred:18s} " + ";  ".join(cells))


if __name__ == "__main__":
    main(sys.argv[1:])
