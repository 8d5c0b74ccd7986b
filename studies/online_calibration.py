"""Online ellipses on the ETH/UCY folds: coverage per setting, CV and Kalman.

    BLINDSPOT_SHARED=<shared> python studies/online_calibration.py \
        [--split val-scenes|val|test] [--gammas 0.002 0.005 0.01] [--windows 60 100 150] \
        [--rescale 0 3 5 10] [--etas 0.02 0.05] [--kappas 5 10 20] [--reveal step whole]

The ethucy stage chooses the setting itself, per fold and model, among the candidates of
``ethucy.online_*`` (:func:`blindspot.traj.conformal.select_on_held_out_streams`, the rule of
``--split val-scenes`` below, with every model's own val scores). This bench shows what the
candidates give with constant velocity and the Kalman filter:

* ``--split val-scenes`` (the default): each scene file of a fold's val split is a stream of
  its own, its first window filled with the scores of the fold's *other* val scenes: a new
  scene met with a prior from elsewhere, as a test scene is (constant velocity's noise model
  is fitted without the held-out scene too). A fold's val scenes never include its test
  recording, but they do include the tails of the *other* folds' test recordings (the
  ``biwi_eth_val`` of fold hotel is frames 10240-12380 of fold eth's test scene), so a
  setting is ranked per fold on that fold's own val scenes only: pooling the folds would rank
  by windows of the very test scenes it is then scored on. Ranked by the mean distance from
  nominal over the fold's streams and levels, among the settings that never give an
  unbounded ellipse there (an unbounded ellipse says nothing).
* ``--split val``: each fold's whole val split run as its own stream (prior from itself).
* ``--split test``: the test scenes as streams (what the ethucy stage reports, there for every
  model), with the val-calibrated scale mixture's coverage beside: a check, not a choice.

Settings: the sliding window's ``gamma`` (ACI step per prediction time), ``window`` (revealed
scores kept) and ``rescale`` (:class:`~blindspot.traj.conformal.AdaptiveConformal`'s
``rescale_prior_after``; 0 off); the scale tracker's ``eta`` and ``kappa``
(:class:`~blindspot.traj.scale_tracker.ScaleTracker`); and ``reveal`` (``step``: each future
point known at its own frame; ``whole``: the whole future at its last frame). Prints per
setting the worst and mean distance from nominal and the largest share of unbounded ellipses
(with ``--per-stream`` or a single setting, first each stream's 50 / 90 / 95 % coverage).
Constant velocity and the Kalman filter only: they need no training, so the table takes about 1.5 min (the learned models' online coverage is in ``reports/metrics/calibration.json``).

Conclusion: on the val scenes with CV and Kalman (2026-12-06, ``--top 40 --reveal step``), the
best scale tracker is nearer nominal than the best sliding window on every fold: mean distance
1.23 / 1.50 / 1.78 / 1.32 / 1.48 pp (eth / hotel / univ / zara1 / zara2; eta 0.02 or 0.05,
kappa 20) against 1.46 / 2.50 / 2.39 / 2.17 / 2.42 pp, worst stream 5.2-7.7 against 6.6-12.3 pp.
Here constant velocity's noise model is refitted without the held-out scene and 36 window settings
are ranked, so the figures differ a little from the stage's val distances. The ethucy stage
chooses per fold and model among both kinds (conf/ethucy/standard.yaml online_*); a new
scene can differ from validation by a scale of 0.01x-16x, hence the window's
rescale_prior_after (blindspot.traj.conformal) and the tracker (blindspot.traj.scale_tracker).
Extended grid (2026-12-07, ``--kappas 10 20 40 60 100 --reveal step``): kappa 100 ranks first on
eth, hotel, univ and zara1 (mean 0.96 / 0.95 / 1.21 / 0.82 pp) and ties 60 on zara2 (1.17 pp),
so the stage's candidates gained 40 and 100 (docs/studies/ethucy.md, fifth pass).
"""

from __future__ import annotations

import argparse
import itertools
import os
from pathlib import Path

import numpy as np

from blindspot.traj.baselines import ConstantVelocity, KalmanCV
from blindspot.traj.conformal import (AdaptiveConformal, HeldOutStreamScore, rank_held_out,
                                      stream_coverage)
from blindspot.traj.distribution import fit_scale_mixture, mahalanobis_sq
from blindspot.traj.ethucy import FOLDS, OBS_LEN, PRED_LEN, load_split
from blindspot.traj.ethucy_protocol import (CALIBRATION_LEVELS, MIXTURE_COMPONENTS,
                                             reveal_times, val_windows)
from blindspot.traj.scale_tracker import ScaleTracker


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--split", choices=("val-scenes", "val", "test"), default="val-scenes")
    ap.add_argument("--gammas", type=float, nargs="+", default=[0.002, 0.005, 0.01])
    ap.add_argument("--windows", type=int, nargs="+", default=[60, 100, 150])
    ap.add_argument("--rescale", type=int, nargs="+", default=[0, 3, 5, 10])
    ap.add_argument("--etas", type=float, nargs="*", default=[0.02, 0.05],
                    help="scale tracker steps (none: the sliding window alone)")
    ap.add_argument("--kappas", type=float, nargs="+", default=[5.0, 10.0, 20.0])
    ap.add_argument("--reveal", choices=("step", "whole"), nargs="+", default=["step", "whole"])
    ap.add_argument("--top", type=int, default=0,
                    help="print only the best N settings of each fold (0: all)")
    ap.add_argument("--per-stream", action="store_true",
                    help="print each stream's coverage under every setting (a wide table)")
    ap.add_argument("--data", type=Path, default=None,
                    help="ETH/UCY folder (default: $BLINDSPOT_SHARED/data/ethucy)")
    args = ap.parse_args()
    data = args.data or Path(os.environ.get("BLINDSPOT_SHARED", "../shared")) / "data/ethucy"
    levels = np.asarray(CALIBRATION_LEVELS)
    lv = tuple(levels)
    settings = [(reveal, c) for reveal in args.reveal for c in (
        *(AdaptiveConformal(lv, g, w, k) for g, w, k in itertools.product(
            args.gammas, args.windows, args.rescale)),
        *(ScaleTracker(lv, e, k) for e, k in itertools.product(args.etas, args.kappas)))]
    print(f"split {args.split}; coverage of the "
          f"{' / '.join(f'{round(100 * x)}' for x in levels)} % ellipses")
    for fold in FOLDS:
        dist: dict[tuple, list[np.ndarray]] = {k: [] for k in settings}  # |coverage - nominal|
        unbounded: dict[tuple, list[float]] = {k: [] for k in settings}
        for name, d2, start, prior, scene, note in _streams(data, fold, args.split, levels):
            row = [f"{fold:6s} {name:6s} {scene[:16]:16s} n={len(d2):6d}{note}"]
            for key in settings:
                reveal, candidate = key
                hits, unb = stream_coverage(candidate, d2,
                                            *reveal_times(start, reveal == "step"), prior)
                dist[key].append(np.abs(hits - levels))
                unbounded[key].append(unb)
                row.append(f"{_name(key)} {_fmt(hits)}" + (f" u {unb:.3f}" if unb else ""))
            if args.per_stream or len(settings) == 1:
                print("  ".join(row))
        table = [HeldOutStreamScore.of(dist[k], unbounded[k]) for k in settings]
        ranked = rank_held_out(table)
        print(f"{fold}: {len(dist[settings[0]])} streams; per setting the worst / mean level off "
              f"nominal (pp) and the largest unbounded share, best first:")
        for i in ranked[:args.top] if args.top else ranked:
            t = table[i]
            print(f"  {_name(settings[i]):28s} {100 * t.distance_worst:5.1f} / "
                  f"{100 * t.distance_mean:5.2f} pp, {100 * t.unbounded:.1f} % unbounded")

def _streams(data: Path, fold: str, split: str, levels: np.ndarray):
    """(model, d2 (N, H), start (N,), prior (M, H), scene, note) of each stream of a fold."""
    val = val_windows(data, fold, 0)
    test = load_split(data, fold, "test") if split == "test" else None
    scene = np.asarray(val.file_index)
    for name in ("cvm", "kalman"):
        kalman = None if name == "cvm" else KalmanCV().fit(
            load_split(data, fold, "train").xy, objective="forecast", obs_len=OBS_LEN)

        def fitted(rows):   # constant velocity's noise model: fitted on these val windows
            return kalman or ConstantVelocity().fit(val.observed()[rows], val.future()[rows])

        everything = np.ones(len(val), bool)
        d2_val = mahalanobis_sq(fitted(everything).predict_distribution(val.observed(), PRED_LEN),
                                val.future())
        start_val = np.asarray(val.start, np.int64)
        if split == "val":
            yield name, d2_val, start_val, d2_val, "val (whole)", ""
        elif split == "val-scenes":
            for k in np.unique(scene):
                own = scene == k
                pr = fitted(~own)
                d2 = mahalanobis_sq(pr.predict_distribution(val.observed(), PRED_LEN),
                                    val.future())
                yield name, d2[own], start_val[own], d2[~own], Path(val.files[k]).stem, ""
        else:
            pr = fitted(everything)
            f_val = pr.predict_distribution(val.observed(), PRED_LEN)
            f_test = pr.predict_distribution(test.observed(), PRED_LEN)
            mix = fit_scale_mixture(f_val, val.future(), n_components=MIXTURE_COMPONENTS)
            note = " val-calibrated " + _fmt(mix.coverage(f_test, test.future(), tuple(levels)))
            d2, test_scene = mahalanobis_sq(f_test, test.future()), np.asarray(test.file_index)
            for k in np.unique(test_scene):   # each test scene file a stream, as the stage does
                own = test_scene == k
                yield (name, d2[own], np.asarray(test.start, np.int64)[own], d2_val,
                       Path(test.files[k]).stem, note)


def _name(key: tuple) -> str:
    reveal, candidate = key
    if isinstance(candidate, ScaleTracker):
        return f"{reveal} scale eta={candidate.eta} kappa={candidate.kappa}"
    return (f"{reveal} g={candidate.gamma} W={candidate.window} "
            f"k={candidate.rescale_prior_after}")


def _fmt(x: np.ndarray) -> str:
    return "/".join(f"{v:.3f}" for v in x)


if __name__ == "__main__":
    main()
