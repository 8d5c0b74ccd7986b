"""Does ETH/UCY pre-training help the scenes' direct multi-step LSTM (``lstm_direct``)? Issue 10,
section 1, last item, for the model the scenes use since the direct model came in (the paper's
next-point LSTM has its own answer: ``pretrain.py``). Prints a table.

    .venv/bin/python studies/pretrain_direct.py [--pretrain-epochs 5]
        [--fractions 1.0 0.1] [--walks 300] [--walk-seed S] [--json out.json]

Reads the last ``dvc repro``'s radar path data set (``data/paths/paths.parquet``) and the
windows stage's splits (``data/windows/{train,val}.parquet``: which paths train and validate;
every other path is held out, :func:`blindspot.traj.direct.path_splits`), and the ETH/UCY
recordings (``BLINDSPOT_SHARED``). The model, its training and its pairs are the train_direct
stage's (``conf/direct``: obs_len 20, horizon 40 at 0.1 s, ``direct.model.ensemble`` members,
one pair every ``direct.stride`` points, each member's epoch chosen on the validation paths).
For every fraction of the training paths (1.0 = the stage's set; 0.1 = a tenth, where
pre-training usually matters):

- ``scratch``: trained on the radar pairs alone (the stage with ``direct.pretrain_epochs: 0``);
  at a fraction below 1 for
  ``direct.model.epochs / fraction`` epochs, so it takes as many optimiser steps as on all the
  paths (fewer pairs must not also mean less training);
- ``ethucy``: trained on ETH/UCY alone, never on a radar pair: every pedestrian's walk of
  obs_len + horizon points resampled to the radar's 0.1 s, one starting at every annotated
  frame, each turned by a random angle, each history point moved by a measured-minus-true error
  vector drawn at random from the training paths' radar points (heavy tails and all,
  independently per point), the future left as annotated like the radar pairs' true futures
  (:func:`blindspot.traj.direct.pretraining_walks`, what the stage pre-trains on),
  ``--pretrain-epochs`` epochs, each member's epoch chosen on the radar validation pairs;
- ``finetuned``: that ensemble, member by member, trained on the radar pairs like ``scratch``
  (same epochs, learning rate and schedule; :func:`blindspot.traj.seq2seq.train_ensemble`
  ``init``; the pre-trained weights are kept where no epoch beats them on val): what the
  train_direct stage does with ``direct.pretrain_epochs`` > 0 at fraction 1.

Scored on the held-out paths' pairs, one every ``calibration.stride`` points, each history the
model's own ``obs_len`` points and each future 3 s (so more pairs than the train_direct stage
scores, whose histories are 50 points long for the next-point LSTM): ADE / FDE over 1, 2 and
3 s (printed: 1 and 3 s; ``--json``: all), each held-out path's mean a sample, 95 % bootstrap
intervals over the held-out paths, and the paired differences of ``finetuned`` and of
``ethucy`` against ``scratch`` at the same fraction
(:func:`blindspot.traj.bootstrap.bootstrap_means`, ``paired_differences``). The intervals
cover the sampling of held-out paths only: one draw of the training subset, fixed seeds.
Constant velocity on the same pairs for reference.

The scenes themselves (``--walks``, default ``benchmark.n_walks``; 0 skips): every model is also
scored on the benchmark stage's randomised occluded walks of the paper's scene (the same draws,
the same radar chain, :mod:`blindspot.synth.scene_walks`), each predicting 2.5 s from the track
filled up to the prediction time, once with the configured fill (``eval.prediction_input``, the
benchmark stage's input; its next-point LSTM is ``data/train/model.pt``) and once with the
Kalman smoother's fill; the paper's metric and ADE / FDE at 0.5, 1 and 2 s per walk, intervals
and paired differences over walks (:func:`blindspot.synth.walk_scores.score_scene_walks`;
a forecast asked past the 40 steps, from a walk last seen long before, continues at its last
step's velocity: :class:`blindspot.traj.predictor.ConstantVelocityTail`, as in the stage).
``--walk-seed`` draws other walks than the stage's (default: the config's ``seed``, the stage's
own): walks from another seed are a validation set of the scene, disjoint from the benchmark's.

Training runs ``direct.jobs`` processes of one torch thread; about 7 minutes on the 2-core
machine.

Conclusion: for the direct multi-step LSTM it helps on radar paths: 3 s ADE / FDE 0.135 / 0.302
m against 0.150 / 0.334 m from scratch (paired -0.015 [-0.020, -0.010] m); on 300 validation
walks (--walk-seed 1) the ETH/UCY-only network wins (0.184 against 0.284 m); direct.finetune
stays true because the radar paths are the kind the calibration and warning were tuned with
(conf/direct/scene.yaml).
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
STEPS_S = (1.0, 2.0, 3.0)


def _path_subset(ids: np.ndarray, fraction: float, seed: int) -> np.ndarray:
    if fraction >= 1.0:
        return ids
    n = max(1, round(fraction * ids.size))
    return np.sort(np.random.default_rng(seed).choice(ids, n, replace=False))


def per_path_scores(model, hist: np.ndarray, fut: np.ndarray, path: np.ndarray,
                    steps: dict[str, int]) -> dict[str, np.ndarray]:
    """{"ade_1s": (P,), "fde_1s": (P,), ...}: each held-out path's mean over its pairs."""
    err = np.linalg.norm(np.asarray(model.predict(hist, max(steps.values()))) - fut, axis=-1)
    _, row = np.unique(path, return_inverse=True)
    count = np.bincount(row)
    out = {}
    for label, k in steps.items():
        out[f"ade_{label}"] = np.bincount(row, err[:, :k].mean(axis=1)) / count
        out[f"fde_{label}"] = np.bincount(row, err[:, k - 1]) / count
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pretrain-epochs", type=int, default=5,
                    help="epochs over the ETH/UCY walks (default 5)")
    ap.add_argument("--fractions", type=float, nargs="+", default=[1.0, 0.1],
                    help="fractions of the radar training paths (default 1.0 0.1)")
    ap.add_argument("--walks", type=int, default=None,
                    help="occluded walks of the paper's scene to score on too (default "
                         "benchmark.n_walks; 0 = none)")
    ap.add_argument("--walk-seed", type=int, default=None,
                    help="seed of the walks (default: the config's seed, the benchmark stage's "
                         "walks); another seed gives walks disjoint from the benchmark's")
    ap.add_argument("--data", default=str(REPO / "data"), help="the repro's data folder")
    ap.add_argument("--json", help="also write the figures here")
    args = ap.parse_args()
    if args.walks is not None and (args.walks == 1 or args.walks < 0):
        ap.error(f"--walks: expected 0 (none) or at least 2 walks (the bootstrap needs two), "
                 f"found {args.walks}")

    import pandas as pd

    from blindspot import config
    from blindspot.traj.baselines import ConstantVelocity
    from blindspot.traj.bootstrap import bootstrap_means, paired_differences
    from blindspot.traj.calibration import path_pairs
    from blindspot.traj.direct import NAME, direct_pairs, path_splits, pretraining_walks
    from blindspot.traj.ethucy import default_data_dir
    from blindspot.traj.paths import table_to_arrays
    from blindspot.traj.pretrain import radar_point_errors
    from blindspot.traj.seq2seq import train_ensemble
    from blindspot.traj.train import torch_threads
    from blindspot.traj.windows import WindowSet

    cfg = config.compose([], config_dir=REPO / "conf")
    d = DirectConfig.from_cfg(cfg)
    m = d.model
    dt = DatasetConfig.from_cfg(cfg).frame_period_s
    seed = int(cfg.seed)
    data = Path(args.data)
    truth, measured, _ = table_to_arrays(pd.read_parquet(data / "paths" / "paths.parquet"))
    ids = path_splits(len(truth), *(WindowSet.load(data / "windows" / f"{s}.parquet")
                                    for s in ("train", "val")))
    val_xy = direct_pairs(measured[ids["val"]], truth[ids["val"]], m.obs_len, m.horizon, d.stride)

    walks = pretraining_walks(default_data_dir(), measured[ids["train"]], truth[ids["train"]],
                              replace(d, pretrain_walks=0), dt)
    res = radar_point_errors(measured[ids["train"]], truth[ids["train"]])
    noise = (f"the training paths' {len(res)} point errors resampled (median "
             f"{np.median(np.hypot(*res.T)):.3f} m, rms per axis {np.sqrt(np.mean(res ** 2)):.3f} m)")
    print(f"ETH/UCY: {len(walks)} walks of {m.obs_len} + {m.horizon} points at {dt} s, history "
          f"noise: {noise}; radar: {ids['train'].size} train / {ids['val'].size} val / "
          f"{ids['test'].size} held-out paths, {len(val_xy)} val pairs")

    t0 = time.perf_counter()
    pre, pre_rep = train_ensemble(walks, val_xy, replace(m, epochs=args.pretrain_epochs),
                                  name=NAME, jobs=d.jobs)
    print(f"pre-trained {len(pre.members)} members in {time.perf_counter() - t0:.0f} s, best "
          f"epochs {[r.best_epoch for r in pre_rep]}")

    models: dict = {"constant_velocity": ConstantVelocity(
        k=EvalConfig.from_cfg(cfg).cv_fit_points, name="constant_velocity"), "ethucy": pre}
    n_pairs = {}
    for fraction in args.fractions:
        train_ids = _path_subset(ids["train"], fraction, seed)
        train_xy = direct_pairs(measured[train_ids], truth[train_ids], m.obs_len, m.horizon,
                                d.stride)
        n_pairs[f"{fraction:g}"] = {"paths": int(train_ids.size), "pairs": int(len(train_xy))}
        # as many optimiser steps as on all the paths
        fm = replace(m, epochs=max(1, round(m.epochs / min(fraction, 1.0))))
        t0 = time.perf_counter()
        models[f"scratch@{fraction:g}"], rs = train_ensemble(train_xy, val_xy, fm, name=NAME,
                                                             jobs=d.jobs)
        models[f"finetuned@{fraction:g}"], rf = train_ensemble(train_xy, val_xy, fm, name=NAME,
                                                               jobs=d.jobs, init=pre)
        n_pairs[f"{fraction:g}"].update(epochs=fm.epochs,
                                        best_epochs_scratch=[r.best_epoch for r in rs],
                                        best_epochs_finetuned=[r.best_epoch for r in rf])
        print(f"fraction {fraction:g}: {train_ids.size} paths, {len(train_xy)} pairs, "
              f"{fm.epochs} epochs; best epochs scratch {[r.best_epoch for r in rs]}, "
              f"fine-tuned {[r.best_epoch for r in rf]}; {time.perf_counter() - t0:.0f} s")

    steps = {f"{s:g}s": min(int(round(s / dt)), m.horizon) for s in STEPS_S}
    hist, fut, path, _ = path_pairs(measured[ids["test"]], truth[ids["test"]], m.obs_len,
                                    max(steps.values()), CalibrationConfig.from_cfg(cfg).stride,
                                    with_index=True)
    with torch_threads(1):
        scores = {name: per_path_scores(model, hist, fut, path, steps)
                  for name, model in models.items()}
    boot = dict(n_boot=2000, seed=seed)
    means = bootstrap_means(scores, **boot)
    pairs = ([(f"finetuned@{f:g}", f"scratch@{f:g}") for f in args.fractions]
             + [("ethucy", f"scratch@{f:g}") for f in args.fractions])
    paired = paired_differences(scores, pairs, **boot)

    n_paths = np.unique(path).size
    print(f"\nheld-out radar paths: {n_paths} paths, {len(hist)} pairs; each path's mean a sample,"
          " mean [95 % bootstrap interval], m")
    keys = [f"{k}_{s}" for s in ("1s", "3s") for k in ("ade", "fde")]
    print(f"{'model':22s} " + "  ".join(f"{k:>22s}" for k in keys))
    for name in models:
        print(f"{name:22s} " + "  ".join(
            f"{means[name][k]['mean']:6.3f} [{means[name][k]['ci95'][0]:.3f}, "
            f"{means[name][k]['ci95'][1]:.3f}]" for k in keys))
    print("\npaired differences (a - b; negative: a closer to the truth):")
    for pair, diff in paired.items():
        print(f"{pair:30s} " + "  ".join(
            f"{k} {diff[k]['mean']:+.3f} [{diff[k]['ci95'][0]:+.3f}, {diff[k]['ci95'][1]:+.3f}]"
            for k in ("ade_1s", "ade_3s", "fde_3s")))
    scenes = scene_walk_scores(cfg, models, data, args.walks, pairs, boot,
                               walk_seed=args.walk_seed)
    if args.json:
        Path(args.json).write_text(json.dumps(
            {"history_noise": noise, "n_ethucy_walks": int(len(walks)),
             "pretrain_epochs": args.pretrain_epochs, "pretrain_best_epochs":
             [r.best_epoch for r in pre_rep], "train": n_pairs, "n_test_paths": int(n_paths),
             "n_test_pairs": int(len(hist)), "means": means, "paired": paired,
             "scene_walks": scenes}, indent=1))


def scene_walk_scores(cfg, models: dict, data: Path, n_walks: int | None,
                      pairs: list[tuple[str, str]], boot: dict, walk_seed: int | None = None
                      ) -> dict:
    """Score ``models`` and the Kalman filter (``eval.kalman``) on occluded walks of the paper's
    scene, from each of two fills (module docstring), and print the table.

    Args:
        cfg: the composed config. models: {name: PathPredictor}; a Seq2SeqEnsemble is carried
            past its horizon by :class:`~blindspot.traj.predictor.ConstantVelocityTail`.
        data: the repro's data folder (``train/model.pt``: the next-point LSTM the two-sided
            fill rolls out).
        n_walks: walks to draw (None: ``benchmark.n_walks``; 0: none, return {}; else >= 2).
        pairs: (a, b) model names whose per-walk differences a - b are bootstrapped, besides
            each model against constant velocity and Kalman.
        boot: ``bootstrap_means`` / ``paired_differences`` options (n_boot, seed).
        walk_seed: seed of the walks (None: ``cfg.seed``, the benchmark stage's walks).

    Returns {fill: {"means": {model: {metric: {"mean", "ci95"}}}, "paired": {"a - b": ..}}}.
    Raises ConfigError (``n_walks`` 1 or negative), FileNotFoundError (no ``train/model.pt``).
    """
    from dataclasses import replace

    from blindspot.radar.config import RadarConfig
    from blindspot.traj.baselines import kalman_baseline
    from blindspot.traj.config import CalibrationConfig, DatasetConfig, DirectConfig, EvalConfig
    from blindspot.typed_config import jobs
    from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig
    from blindspot.radar.scene import load_scenes
    from blindspot.synth.scene_walks import car_scene_walks   # the walks stage's walks
    from blindspot.traj.config import WalksConfig
    from blindspot.synth.walk_scores import score_scene_walks
    from blindspot.traj.bootstrap import bootstrap_means, paired_differences
    from blindspot.traj.lstm import LSTMPredictor
    from blindspot.traj.predictor import ConstantVelocityTail
    from blindspot.traj.seq2seq import Seq2SeqEnsemble

    if n_walks == 0:
        return {}
    bench = WalksConfig.from_cfg(cfg)
    if n_walks is not None:
        bench = replace(bench, n_walks=int(n_walks))
    ev = EvalConfig.from_cfg(cfg)
    radar = RadarConfig.from_cfg(cfg)
    seed = int(cfg.seed) if walk_seed is None else int(walk_seed)
    car = next(s for s in load_scenes(cfg.scene).values() if s.with_car)
    walks, measured = car_scene_walks(bench, radar, car, CfarConfig.from_cfg(cfg),
                                      DoaConfig.from_cfg(cfg), DetectConfig.from_cfg(cfg),
                                      seed=seed, jobs=jobs(cfg))
    lstm = LSTMPredictor.load(data / "train" / "model.pt")
    tailed = {n: (ConstantVelocityTail(m, m.cfg.horizon) if isinstance(m, Seq2SeqEnsemble)
                  else m) for n, m in models.items()}
    tailed["kalman"] = kalman_baseline(ev, radar.frame_period_s)
    pairs = list(dict.fromkeys([*pairs, *((n, b) for n in models if n != "constant_velocity"
                                          for b in ("constant_velocity", "kalman"))]))
    out = {}
    for fill in dict.fromkeys((ev.prediction_input, "kalman")):
        scores, _ = score_scene_walks(
            walks, measured, predictors=tailed, interpolation_methods=(), prediction_input=fill,
            gap_predictor=lstm, smoother=kalman_baseline(EvalConfig.from_cfg(cfg), RadarConfig.from_cfg(cfg).frame_period_s).smooth_batch,
            horizon=bench.horizon_frames, dt_s=radar.frame_period_s, horizons_s=ev.horizons_s,
            threads=1)
        means = bootstrap_means(scores, **boot)
        paired = paired_differences(scores, pairs, **boot)
        out[fill] = {"means": means, "paired": paired}
        keys = ("path_error_mean_m", "ade_1s", "ade_2s", "fde_2s")
        print(f"\n{len(walks)} occluded walks of the paper's scene (walk seed {seed}), predicted "
              f"from the {fill} fill, mean [95 % bootstrap interval over walks], m")
        print(f"{'model':22s} " + "  ".join(f"{k:>22s}" for k in keys))
        for name in tailed:
            print(f"{name:22s} " + "  ".join(
                f"{means[name][k]['mean']:6.3f} [{means[name][k]['ci95'][0]:.3f}, "
                f"{means[name][k]['ci95'][1]:.3f}]" for k in keys))
        for pair, diff in paired.items():
            print(f"{pair:30s} " + "  ".join(
                f"{k} {diff[k]['mean']:+.3f} [{diff[k]['ci95'][0]:+.3f}, "
                f"{diff[k]['ci95'][1]:+.3f}]" for k in keys))
    return out


if __name__ == "__main__":
    main()
