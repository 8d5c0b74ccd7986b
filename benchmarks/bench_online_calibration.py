"""Adaptive conformal ellipses on the ETH/UCY folds: coverage per window size, CV and Kalman.

    PYTHONPATH=src BLINDSPOT_SHARED=<shared> python benchmarks/bench_online_calibration.py \
        [--split val|test] [--windows 100 300 1000] [--gammas 0.005 0.02 0.05]

``--split val`` (how ``ethucy.online_window`` was chosen): each fold's val split run as the
stream, the val scores also filling the first window; ``--split test``: the test scenes as
streams (what the ethucy stage reports, there for every model). Prints per fold and model the
coverage of the 50 / 90 / 95 % ellipses and the share of unbounded 95 % ellipses (``u``), the
val-calibrated (scale mixture) coverage beside it on the test split, and per (gamma, window) the
worst level's distance from nominal over all folds and the largest unbounded share (a setting
that covers by unbounded ellipses is not a choice).
Constant velocity and the Kalman filter only: they need no training, so the whole table takes
seconds (the learned models' online coverage is in ``reports/metrics/calibration.json``).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np

from blindspot.traj.baselines import ConstantVelocity, KalmanCV
from blindspot.traj.conformal import AdaptiveConformal
from blindspot.traj.distribution import fit_scale_mixture, mahalanobis_sq
from blindspot.traj.ethucy import FOLDS, OBS_LEN, PRED_LEN, load_split
from blindspot.traj.ethucy_benchmark import CALIBRATION_LEVELS, MIXTURE_COMPONENTS, val_windows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--split", choices=("val", "test"), default="val")
    ap.add_argument("--windows", type=int, nargs="+", default=[100, 300, 1000])
    ap.add_argument("--gammas", type=float, nargs="+", default=[0.005, 0.02, 0.05])
    ap.add_argument("--data", type=Path, default=None,
                    help="ETH/UCY folder (default: $BLINDSPOT_SHARED/data/ethucy)")
    args = ap.parse_args()
    data = args.data or Path(os.environ.get("BLINDSPOT_SHARED", "../shared")) / "data/ethucy"
    levels = np.asarray(CALIBRATION_LEVELS)
    settings = [(g, w) for g in args.gammas for w in args.windows]
    worst = {k: 0.0 for k in settings}
    unbounded = {k: 0.0 for k in settings}
    print(f"split {args.split}; coverage of the "
          f"{' / '.join(f'{round(100 * x)}' for x in levels)} % ellipses")
    for fold in FOLDS:
        val = val_windows(data, fold, 0)
        stream = load_split(data, fold, "test") if args.split == "test" else val
        for name in ("cvm", "kalman"):
            if name == "cvm":
                pr = ConstantVelocity().fit(val.observed(), val.future())
            else:
                pr = KalmanCV().fit(load_split(data, fold, "train").xy, objective="forecast",
                                    obs_len=OBS_LEN)
            f_val = pr.predict_distribution(val.observed(), PRED_LEN)
            f_str = pr.predict_distribution(stream.observed(), PRED_LEN)
            d2_val = mahalanobis_sq(f_val, val.future())
            d2 = mahalanobis_sq(f_str, stream.future())
            row = [f"{fold:6s} {name:6s} n={len(stream):6d}"]
            if args.split == "test":
                mix = fit_scale_mixture(f_val, val.future(), n_components=MIXTURE_COMPONENTS)
                row.append("val-calibrated " + _fmt(mix.coverage(f_str, stream.future(),
                                                                 tuple(levels))))
            start = np.asarray(stream.start, np.int64)
            for g, w in settings:
                rep = AdaptiveConformal(tuple(levels), g, w).coverage(
                    d2, start + OBS_LEN - 1, start + OBS_LEN + PRED_LEN - 1,
                    stream.file_index, d2_val)
                hits = np.array([rep[f"online_coverage_{round(100 * x)}"] for x in levels])
                unb = max(rep[f"online_unbounded_{round(100 * x)}"] for x in levels)
                worst[g, w] = max(worst[g, w], float(np.max(np.abs(hits - levels))))
                unbounded[g, w] = max(unbounded[g, w], unb)
                row.append(f"g={g} W={w} {_fmt(hits)} u {unb:.3f}")
            print("  ".join(row))
    print("over folds and models, worst level off nominal / largest unbounded share:")
    for k in settings:
        print(f"  gamma {k[0]}, window {k[1]}: {100 * worst[k]:.1f} pp / "
              f"{100 * unbounded[k]:.1f} %")


def _fmt(x: np.ndarray) -> str:
    return "/".join(f"{v:.3f}" for v in x)


if __name__ == "__main__":
    main()
