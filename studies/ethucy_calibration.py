"""ETH/UCY calibration of CVM and Kalman per fold: one scale mixture vs one per speed class.

    BLINDSPOT_SHARED=/work/shared python studies/ethucy_calibration.py \
        [--edges 0.2,0.6,1.0,1.4] [--components 3]

Fitted on each fold's val split, scored on its test scene (never fitted there): coverage of the
50/90/95 % ellipses and NLL (nats per point) under ``fit_scale_mixture`` (one mixture per step,
the ``mixture`` calibration) and ``fit_conditional_scale_mixture`` (one per class of observed
speed, the ``conditional`` calibration). The learned models' numbers are the ethucy stage's
(reports/ethucy.md).

Conclusion: one scale mixture per class of observed speed (conditional) against one mixture per
fold, for CV and Kalman on every fold: the ethucy stage calibrates with conditional, speed edges
0.2 / 0.6 / 1.0 / 1.4 m/s (conf/ethucy/standard.yaml calibration, calibration_speed_edges).
"""

from __future__ import annotations

import argparse

import numpy as np

from blindspot.traj.baselines import ConstantVelocity, KalmanCV
from blindspot.traj.distribution import (fit_conditional_scale_mixture, fit_scale_mixture,
                                         observed_speed)
from blindspot.traj.ethucy import FOLDS, FRAME_PERIOD_S, OBS_LEN, PRED_LEN, default_data_dir, \
    load_split


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--edges", default="0.2,0.6,1.0,1.4", help="speed class edges, m/s")
    ap.add_argument("--components", type=int, default=3)
    args = ap.parse_args()
    edges = [float(e) for e in args.edges.split(",")]
    data = default_data_dir()
    print("| fold | model | mixture 50/90/95, NLL | conditional 50/90/95, NLL |")
    print("|---|---|---|---|")
    for fold in FOLDS:
        val, test = load_split(data, fold, "val"), load_split(data, fold, "test")
        train = load_split(data, fold, "train")
        models = {"cvm": ConstantVelocity().fit(val.observed(), val.future()),
                  "kalman": KalmanCV().fit(train.xy, objective="forecast", obs_len=OBS_LEN)}
        sv = observed_speed(val.observed(), FRAME_PERIOD_S)
        st = observed_speed(test.observed(), FRAME_PERIOD_S)
        for name, p in models.items():
            fv = p.predict_distribution(val.observed(), PRED_LEN)
            ft = p.predict_distribution(test.observed(), PRED_LEN)
            mix = fit_scale_mixture(fv, val.future(), n_components=args.components)
            cond = fit_conditional_scale_mixture(fv, val.future(), sv, edges,
                                                 n_components=args.components)
            a, b = mix.coverage(ft, test.future()), cond.coverage(ft, test.future(), st)
            print(f"| {fold} | {name} | {' / '.join(f'{x:.3f}' for x in a)}, "
                  f"{mix.nll(ft, test.future()):.2f} | {' / '.join(f'{x:.3f}' for x in b)}, "
                  f"{cond.nll(ft, test.future(), st):.2f} |", flush=True)


if __name__ == "__main__":
    main()
