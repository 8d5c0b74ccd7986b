"""CPU time of the parts of the heavy stages that were cut (train, ethucy, driving_track), old
way against new way in one process, with a check that both give the same bits.

    BLINDSPOT_SHARED=/work/shared python -m benchmarks.bench_stage_cpu \
        [train] [ethucy] [seq2seq] [track] [--data DATA] [--repeats N] [--every K]

* ``train``: the train stage's scoring after the training (:func:`blindspot.traj.train.ensemble_scores`: the
  ensemble's and each member's one-step errors, the ensemble's 20-frame rollouts, on the val
  and test windows) with torch's default thread pool (the old way: every core of the machine)
  and at ``train.num_threads`` (1, the new way, :func:`blindspot.traj.train.torch_threads`).
  Reads ``DATA/train/model.pt`` and ``DATA/windows/{val,test}.parquet`` (a finished repro's).
* ``ethucy``: ``fit_conditional_scale_mixture`` (the ``conditional`` calibration of every
  ETH/UCY fold x model item; six EM fits each) on the constant-velocity forecasts of each
  fold's val split, with the plain (B, H, K) EM (the old fit_scale_mixture, kept here) and with
  the (K, B, H) one.
* ``seq2seq``: one ETH/UCY seq2seq training (zara1, 3,000 windows, 3 epochs, mlp and lstm
  cells, the stage's settings otherwise) with the seq2seq module of commit ca8c9a2 (val tracks
  framed and their covariances computed on every epoch's validation) and with this one.
* ``track``: the driving_track stage's tracker (``track_points``, paper-profile config) on
  every ``--every``-th driving scene of ``DATA/driving/{truth,points}.parquet``, with the
  tracker module of commit ca8c9a2 (``git show``: Stone Soup's deleter walking each
  track's states, a detection stack per track, a pandas reindex per frame) and with this one,
  both without the field of view (``tracker.field_of_view_deg``), which the base lacks; the two
  track tables must be equal.

Times are CPU seconds of this process (``time.process_time``: every thread's user + system),
best of ``--repeats``; on a shared machine read them as upper bounds and compare the two
columns, measured side by side.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path
from unittest import mock

import numpy as np
import torch

from blindspot.traj import distribution
from blindspot.traj.baselines import ConstantVelocity
from blindspot.traj.distribution import GaussianForecast, ScaleMixture, observed_speed
from blindspot.traj.ethucy import FOLDS, FRAME_PERIOD_S, default_data_dir, load_split
from blindspot.traj.lstm import LSTMPredictor
from blindspot.traj.train import evaluate, rollout_errors, torch_threads
from blindspot.traj.windows import WindowSet

from tests.traj.test_distribution import _em_reference   # run from the root with -m


def cpu(fn, repeats: int):
    """(best CPU seconds over ``repeats`` calls, the last result)."""
    best, out = np.inf, None
    for _ in range(repeats):
        c0 = time.process_time()
        out = fn()
        best = min(best, time.process_time() - c0)
    return best, out


def train_scores(predictor: LSTMPredictor, split: dict[str, WindowSet], horizon: int) -> dict:
    """The LSTM part of stages/train.py's ``scores`` (the baselines take milliseconds)."""
    return {"ensemble": {s: {**evaluate(predictor, split[s]),
                             **rollout_errors(predictor, split[s], horizon)}
                         for s in ("val", "test")},
            "members": [{s: evaluate(predictor.member(i), split[s]) for s in ("val", "test")}
                        for i in range(predictor.n_members)]}


def bench_train(data: Path, repeats: int) -> None:
    predictor = LSTMPredictor.load(data / "train" / "model.pt")
    split = {s: WindowSet.load(data / "windows" / f"{s}.parquet") for s in ("val", "test")}
    run = lambda: train_scores(predictor, split, 20)  # noqa: E731
    default = torch.get_num_threads()
    old_s, old = cpu(run, repeats)
    with torch_threads(1):
        new_s, new = cpu(run, repeats)
    print(f"train scoring ({predictor.n_members} members, {len(split['val'])} val + "
          f"{len(split['test'])} test windows, 20-frame rollouts): CPU {old_s:.1f} s with torch's "
          f"{default} threads, {new_s:.1f} s with 1 thread ({old_s / new_s:.1f}x); same numbers: "
          f"{old == new}")


def plain_em(forecast: GaussianForecast, truth: np.ndarray, *, n_components: int = 3,
             max_iter: int = 300, tol: float = 1e-8) -> ScaleMixture:
    """The fit_scale_mixture of commit ca8c9a2: the EM on (B, H, K) arrays, as the test suite's
    reference keeps it (tests/traj/test_distribution.py ``_em_reference``)."""
    return ScaleMixture(*_em_reference(forecast, truth, int(n_components), max_iter, tol))


def bench_ethucy(repeats: int) -> None:
    data = default_data_dir()
    edges = (0.2, 0.6, 1.0, 1.4)
    total_old = total_new = 0.0
    same = True
    for fold in FOLDS:
        val = load_split(data, fold, "val")
        fc = ConstantVelocity().fit(val.observed(), val.future()).predict_distribution(
            val.observed(), 12)
        speed = observed_speed(val.observed(), FRAME_PERIOD_S)
        fit = lambda: distribution.fit_conditional_scale_mixture(  # noqa: E731
            fc, val.future(), speed, edges).to_dict()
        with mock.patch.object(distribution, "fit_scale_mixture", plain_em):
            old_s, old = cpu(fit, repeats)
        new_s, new = cpu(fit, repeats)
        same &= old == new
        total_old, total_new = total_old + old_s, total_new + new_s
        print(f"ethucy {fold}: conditional scale mixture on {len(val)} val windows, CPU "
              f"{old_s:.2f} s plain EM, {new_s:.2f} s per-component EM")
    print(f"ethucy, the five folds (one of the fold x model items each): CPU {total_old:.2f} s "
          f"-> {total_new:.2f} s ({total_old / total_new:.1f}x); same mixtures: {same}")


ROOT = Path(__file__).resolve().parents[1]
BASE = "ca8c9a2"     # the commit before these changes


def module_at_base(path: str, name: str):
    """The module ``path`` (repo-relative) as it was at :data:`BASE` (``git show``)."""
    import importlib.util
    import subprocess
    import sys
    import tempfile

    src = subprocess.run(["git", "show", f"{BASE}:{path}"], cwd=ROOT, check=True,
                         capture_output=True, text=True).stdout
    with tempfile.NamedTemporaryFile("w", suffix=".py", delete=False) as f:
        f.write(src)
    try:
        spec = importlib.util.spec_from_file_location(name, f.name)
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod               # dataclasses look their module up there
        spec.loader.exec_module(mod)
    finally:
        Path(f.name).unlink()
    return mod


def bench_seq2seq(repeats: int, n_train: int = 3000, epochs: int = 3) -> None:
    from dataclasses import replace

    from omegaconf import OmegaConf

    from blindspot.traj import seq2seq
    from blindspot.traj.config import EthUcyConfig
    from blindspot.traj.ethucy_protocol import EthUcySettings

    old = module_at_base("src/blindspot/traj/seq2seq.py", "seq2seq_base")
    settings = EthUcySettings.from_config(EthUcyConfig.from_cfg(OmegaConf.load(ROOT / "params.yaml")),
                                          shared_dir=default_data_dir().parents[1], seed=0)
    data = default_data_dir()
    for cell in ("mlp", "lstm"):
        cfg = replace(settings.seq2seq, cell=cell, epochs=epochs)
        tr = load_split(data, "zara1", "train", min_peds=1, neighbours=cfg.neighbours)
        va = load_split(data, "zara1", "val", neighbours=cfg.neighbours)
        seq2seq.train_seq2seq(tr.xy[:200], va.xy[:200], replace(cfg, epochs=1),  # warm-up
                              train_nb=tr.neighbours[:200], val_nb=va.neighbours[:200])
        out = {}
        for label, mod in (("old", old), ("new", seq2seq)):
            out[label] = cpu(lambda: mod.train_seq2seq(  # noqa: B023
                tr.xy[:n_train], va.xy, cfg, train_nb=tr.neighbours[:n_train],
                val_nb=va.neighbours), repeats)
        (a_s, (a, ra)), (b_s, (b, rb)) = out["old"], out["new"]
        same = (ra.val_ade == rb.val_ade and ra.best_epoch == rb.best_epoch
                and all(torch.equal(v, b.net.state_dict()[k])
                        for k, v in a.net.state_dict().items()))
        print(f"seq2seq {cell} on zara1 ({n_train} train windows x2 mirrored, {len(va)} val, "
              f"{epochs} epochs): CPU {a_s:.2f} s ({BASE}) -> {b_s:.2f} s; same val ADE per "
              f"epoch, kept epoch and weights: {same}")


def bench_track(data: Path, every: int, repeats: int) -> None:
    import pandas as pd
    from omegaconf import OmegaConf

    from blindspot.track import tracker
    from blindspot.track.config import TrackerConfig

    old = module_at_base("src/blindspot/track/tracker.py", "tracker_base")
    cfg = TrackerConfig.from_cfg(OmegaConf.load(ROOT / "params.yaml"))
    truth = pd.read_parquet(data / "driving" / "truth.parquet")
    points = pd.read_parquet(data / "driving" / "points.parquet")
    scenes = sorted(truth.scene.unique())[::every]
    truth, points = truth[truth.scene.isin(scenes)], points[points.scene.isin(scenes)]
    from blindspot.synth.driving_tracks import tracker_input        # the stage's own input, sensor columns too

    pts, _ = tracker_input(truth, points)
    # the same work on both sides: the base has no field of view (its tracks coast until
    # max_misses), so the new one is timed without it too
    cfg = dataclasses.replace(cfg, field_of_view_deg=None)
    old_s, a = cpu(lambda: old.track_points(pts, cfg, jobs=1), repeats)
    new_s, b = cpu(lambda: tracker.track_points(pts, cfg, jobs=1), repeats)
    # the base's columns: the tracker has gained output columns since (Doppler, spread)
    print(f"track: {len(scenes)} scenes, {len(pts)} points, {len(b)} track rows: CPU "
          f"{old_s:.1f} s (ca8c9a2) -> {new_s:.1f} s ({old_s / new_s:.2f}x); same tracks "
          f"(the {a.shape[1]} columns of ca8c9a2): {a.equals(b[list(a.columns)])}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("parts", nargs="*", choices=["train", "ethucy", "seq2seq", "track", []], default=[],
                    help="what to time (default: all)")
    ap.add_argument("--data", type=Path, default=Path("data"),
                    help="a finished repro's data folder (default: ./data)")
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--every", type=int, default=10, help="track: every k-th scene (default 10)")
    args = ap.parse_args()
    args.parts = args.parts or ["train", "ethucy", "seq2seq", "track"]
    if "train" in args.parts:
        bench_train(args.data, args.repeats)
    if "ethucy" in args.parts:
        bench_ethucy(args.repeats)
    if "seq2seq" in args.parts:
        bench_seq2seq(args.repeats)
    if "track" in args.parts:
        bench_track(args.data, args.every, args.repeats)


if __name__ == "__main__":
    main()
