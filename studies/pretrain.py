"""Does ETH/UCY pre-training help the scene LSTM? (issue 10, section 1, last item). Prints a table.

    .venv/bin/python studies/pretrain.py [--seeds 3] [--pretrain-epochs 3]
        [--fractions 1.0 0.1] [--walks 300] [--windows data/windows] [--json out.json]

For every seed and every fraction of the radar training paths (1.0 = the train stage's set,
0.1 = a tenth of its paths, the regime where pre-training usually matters), three networks of
the scene model's config (``conf/model``, ``conf/train``: 15 epochs of Adam at lr 0.001):

- ``scratch``: trained on the radar windows alone, as the train stage does;
- ``ethucy``: trained on ETH/UCY alone (``--pretrain-epochs`` over every recording resampled to
  the radar's 0.1 s, :mod:`blindspot.traj.pretrain`), never seeing a radar window;
- ``finetuned``: that network, then trained on the radar windows like ``scratch``.

Each variant's seeds form one ensemble (as the train stage's ``train.ensemble``), scored on the
radar data set's validation and test windows (one-step RMSE; ADE/FDE of a 2 s rollout from every
window whose future the split holds, the search objective) and on ``--walks`` randomised occluded
walks of the paper's scene through the reduced radar chain (the benchmark stage's draw, seed and
scoring: ADE/FDE at 1 and 2 s with 95 % bootstrap intervals, and the paired difference
finetuned - scratch). Reads data/windows/{train,val,test}.parquet of the last ``dvc repro``.
Training runs on one torch thread per process, ``--jobs`` processes.

Conclusion: ETH/UCY pre-training does not help the paper's next-point LSTM where it counts; on
the occluded walks the network pre-trained alone is the best (README, 'Does ETH/UCY pre-training
help the scenes').
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
VARIANTS = ("scratch", "ethucy", "finetuned")


def _pretrain(job):
    """One seed's network trained on ETH/UCY alone (module level, so workers can run it)."""
    from blindspot.traj.train import train_lstm

    seed, pretrain, val, model_cfg, train_cfg, pre_epochs = job
    cfg = replace(train_cfg, seed=seed, epochs=pre_epochs)
    return train_lstm(pretrain, val, model_cfg, cfg, progress=False)


def _member(job):
    """One seed's radar networks for one training fraction: from scratch and fine-tuned from that
    seed's pre-trained network."""
    from blindspot.traj.train import train_lstm

    seed, fraction, (train, val), pre, model_cfg, train_cfg = job
    cfg = replace(train_cfg, seed=seed)
    scratch = train_lstm(train, val, model_cfg, cfg, progress=False)
    tuned = train_lstm(train, val, model_cfg, cfg, progress=False, init_from=pre.predictor)
    return seed, fraction, {"scratch": scratch, "ethucy": pre, "finetuned": tuned}


def _path_subset(ws, fraction: float, seed: int):
    if fraction >= 1.0:
        return ws
    paths = np.unique(ws.path_id)
    keep = np.random.default_rng(seed).choice(paths, max(1, round(fraction * paths.size)),
                                              replace=False)
    return ws.subset(np.isin(ws.path_id, keep))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3, help="networks per ensemble (default 3)")
    ap.add_argument("--pretrain-epochs", type=int, default=3,
                    help="epochs over the ETH/UCY windows (default 3)")
    ap.add_argument("--fractions", type=float, nargs="+", default=[1.0, 0.1],
                    help="fractions of the radar training paths (default 1.0 0.1)")
    ap.add_argument("--walks", type=int, default=300, help="benchmark walks (0 = skip)")
    ap.add_argument("--jobs", type=int, default=2, help="training processes (default 2)")
    ap.add_argument("--windows", default=str(REPO / "data" / "windows"),
                    help="folder of the windows stage's train/val/test.parquet")
    ap.add_argument("--json", help="also write the figures here")
    args = ap.parse_args()

    from blindspot import config
    from blindspot.parallel import parallel_map
    from blindspot.traj.ethucy import default_data_dir
    from blindspot.traj.lstm import LSTMPredictor
    from blindspot.traj.pretrain import ethucy_next_point_windows
    from blindspot.traj.train import evaluate, rollout_errors
    from blindspot.traj.windows import WindowSet

    cfg = config.compose([], config_dir=REPO / "conf")
    model_cfg, train_cfg = LSTMConfig.from_cfg(cfg), TrainConfig.from_cfg(cfg)
    dt = RadarConfig.from_cfg(cfg).frame_period_s
    horizon = train_cfg.val_horizon_frames
    split = {s: WindowSet.load(Path(args.windows) / f"{s}.parquet")
             for s in ("train", "val", "test")}
    t0 = time.perf_counter()
    pretrain = ethucy_next_point_windows(default_data_dir(), model_cfg.window, dt,
                                         seed=int(cfg.seed))
    print(f"ETH/UCY at {dt} s: {len(pretrain)} windows of {model_cfg.window} points "
          f"({time.perf_counter() - t0:.1f} s); radar train {len(split['train'])}, "
          f"val {len(split['val'])}, test {len(split['test'])}")

    seeds = [int(train_cfg.seed) + i for i in range(args.seeds)]
    t0 = time.perf_counter()
    # pre-training does not depend on the radar fraction: once per seed, shared by the fractions
    pre = dict(zip(seeds, parallel_map(_pretrain, [(s, pretrain, split["val"], model_cfg, train_cfg,
                                                    args.pretrain_epochs) for s in seeds],
                                       args.jobs, progress="pre-train")))
    jobs = [(s, f, (_path_subset(split["train"], f, int(cfg.seed)), split["val"]), pre[s],
             model_cfg, train_cfg) for f in args.fractions for s in seeds]
    done = parallel_map(_member, jobs, args.jobs, progress="train")
    print(f"trained {len(seeds) + 2 * len(jobs)} networks in {time.perf_counter() - t0:.0f} s")

    results: dict = {}
    ensembles: dict = {}
    for fraction in args.fractions:
        n_train = len(_path_subset(split["train"], fraction, int(cfg.seed)))
        for variant in VARIANTS:
            nets = [r[variant].predictor for s, f, r in done if f == fraction]
            lstm = LSTMPredictor.ensemble(nets)
            name = f"{variant}@{fraction:g}"
            ensembles[name] = lstm
            results[name] = {"n_train_windows": n_train, **{
                s: {**evaluate(lstm, split[s]), **rollout_errors(lstm, split[s], horizon)}
                for s in ("val", "test")}}

    if args.walks:
        results["walks"] = _walk_benchmark(cfg, ensembles, args.walks)

    print(f"\n{'model':18s} {'train win':>9s} {'val RMSE':>9s} {'val ADE':>8s} {'val FDE':>8s} "
          f"{'test ADE':>8s} {'test FDE':>8s}   (m; ADE/FDE of a {horizon}-frame rollout)")
    for name, r in results.items():
        if name == "walks":
            continue
        print(f"{name:18s} {r['n_train_windows']:9d} {r['val']['rmse_m']:9.4f} "
              f"{r['val']['ade_m']:8.3f} {r['val']['fde_m']:8.3f} {r['test']['ade_m']:8.3f} "
              f"{r['test']['fde_m']:8.3f}")
    if args.walks:
        w = results["walks"]
        print(f"\n{w['n_walks']} occluded walks, mean and 95 % bootstrap interval (m):")
        for name in ensembles:
            row = w[name]
            print(f"{name:18s} " + "  ".join(
                f"{k} {row[k]['mean']:.3f} [{row[k]['ci95'][0]:.3f}, {row[k]['ci95'][1]:.3f}]"
                for k in ("ade_1s", "ade_2s", "fde_2s")))
        for pair, diff in w["paired"].items():
            print(f"{pair:40s} " + "  ".join(
                f"{k} {d['mean']:+.3f} [{d['ci95'][0]:+.3f}, {d['ci95'][1]:+.3f}]"
                for k, d in diff.items() if k in ("ade_1s", "ade_2s", "fde_2s")))
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))


def _walk_benchmark(cfg, ensembles: dict, n_walks: int) -> dict:
    """The benchmark stage's walks and scoring with these ensembles as the predictors."""
    from blindspot.radar.config import RadarConfig
    from blindspot.traj.baselines import kalman_baseline
    from blindspot.traj.config import EvalConfig, LSTMConfig, TrainConfig
    from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig
    from blindspot.radar.scene import load_scenes
    from blindspot.synth.scene_walks import car_scene_walks   # the walks stage's walks
    from blindspot.traj.config import WalksConfig
    from blindspot.synth.walk_scores import score_scene_walks
    from blindspot.traj.bootstrap import bootstrap_means, paired_differences

    bench = replace(WalksConfig.from_cfg(cfg), n_walks=n_walks)
    ev = EvalConfig.from_cfg(cfg)
    radar = RadarConfig.from_cfg(cfg)
    car = next(s for s in load_scenes(cfg.scene).values() if s.with_car)
    walks, measured = car_scene_walks(bench, radar, car, CfarConfig.from_cfg(cfg),
                                      DoaConfig.from_cfg(cfg), DetectConfig.from_cfg(cfg),
                                      seed=int(cfg.seed), jobs=int(cfg.jobs))
    gap = ensembles.get("scratch@1", next(iter(ensembles.values())))   # the train stage's kind
    scores, _ = score_scene_walks(
        walks, measured, predictors=ensembles, interpolation_methods=ev.interpolation_methods,
        prediction_input=ev.prediction_input, gap_predictor=gap,
        smoother=kalman_baseline(ev, radar.frame_period_s).smooth_batch, horizon=bench.horizon_frames,
        dt_s=radar.frame_period_s, horizons_s=ev.horizons_s, threads=bench.threads)
    boot = dict(n_boot=bench.n_bootstrap, level=bench.ci_level, seed=int(cfg.seed))
    fractions = sorted({n.split("@")[1] for n in ensembles})
    pairs = [(f"finetuned@{f}", f"scratch@{f}") for f in fractions]
    means = bootstrap_means({k: v for k, v in scores.items() if k in ensembles}, **boot)
    return {"n_walks": len(walks), **means,
            "paired": paired_differences(scores, pairs, **boot)}


if __name__ == "__main__":
    main()
