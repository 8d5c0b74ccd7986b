"""Settings chosen by a held-out scene: does a validation that sees another scene choose what
ETH/UCY's test prefers?

    BLINDSPOT_SHARED=/work/shared python studies/ethucy_scene_selection.py \
        --variants base,transformer,steps_5_3_5_2 --set cell=lstm --seeds 0,1,2 [--jobs 2] \
        [--json FILE]

The benchmark's val split is a slice of the same four scenes the fold trains on, so it cannot
see what sets the fold's test scene apart (eth's pace, issue 43). Leave-one-domain-out
validation (Gulrajani and Lopez-Paz 2021, "In search of lost domain generalization", DomainBed's
model selection) asks instead how a setting does on a scene it never trained on. For test scene
F and every other scene G, a model trained on F's train split without G's files (its epoch kept
by F's val split without G's files) is scored on G's whole recording (fold G's test files).
F's own recording is never read, so the choice stays blind to F's test. The held-out models of
F and G train on the same files (each fold's train split holds the same per-scene files), so
the ten scene pairs' models serve both folds. Each setting's held-out score for fold F is its
ADE averaged over the four scenes G (equal weight, as the folds are averaged), over the seeds;
the lowest is held-out validation's choice, set beside the standard val's choice and every
variant's test (the fold's own model, as ``studies/ethucy_models.py`` trains it; the seeds'
mean and sd).

Variants are ``studies/ethucy_models.py``'s (one change from the benchmark's seq2seq settings,
``conf/ethucy/standard.yaml``); ``--set`` overrides the base for all of them. ``--print FILE``
prints an earlier run's tables from its ``--json`` file. A multi-modal base (``--set
cell=mlp,modes=20``) adds the tables scored and chosen by best-of-20.

Conclusion (2026-12-07, the LSTM encoder, the transformer encoder and the LSTM with training
windows also at 5/2, seeds 0-2, about 1 h on 2 cores; docs/studies/ethucy.md, tenth pass): the
held-out scenes choose the transformer for hotel, univ, zara1 and zara2, whose held-out scenes
include eth (trained without eth, it scores 0.76-0.84 m there against the LSTM's 0.78-0.90),
and the LSTM for eth, whose test the transformer improves: test 0.4750 / 0.9859 m against the
stage's 0.4733 / 0.9791. What makes eth hard is in eth alone; nothing adopted.
"""

from __future__ import annotations

import argparse
import itertools
import json
import time
from dataclasses import replace
from functools import partial
from pathlib import Path

import numpy as np
from ethucy_models import VARIANTS, base_config   # the script's own folder is on its path

from blindspot.traj.ethucy import FOLDS, Windows, default_data_dir, load_split
from blindspot.traj.ethucy_protocol import BEST_OF
from blindspot.traj.metrics import ade, fde
from blindspot.traj.mixture import best_of
from blindspot.traj.multimodal import MultiModalPredictor
from blindspot.traj.seq2seq import train_ensemble

#: the file-name stems of each test scene's recordings (the Social-GAN split's files;
#: crowds_zara03 and uni_examples are training files of every fold and belong to no test scene)
SCENE_FILES = {"eth": ("biwi_eth",), "hotel": ("biwi_hotel",),
               "univ": ("students001", "students003"), "zara1": ("crowds_zara01",),
               "zara2": ("crowds_zara02",)}


def without_scene(w: Windows, scene: str) -> Windows:
    """The windows of ``w`` whose file is not one of ``scene``'s recordings."""
    keep_file = np.array([not Path(f).stem.startswith(SCENE_FILES[scene]) for f in w.files])
    if keep_file.all():
        raise ValueError(f"without_scene: no file of {scene!r} among {w.files}")
    m = keep_file[w.file_index]
    return replace(w, xy=w.xy[m], track_id=w.track_id[m], start=w.start[m],
                   file_index=w.file_index[m],
                   neighbours=None if w.neighbours is None else w.neighbours[m])


def _scores(model, cfg, w: Windows) -> dict:
    """ADE / FDE of the mean prediction; for a multi-modal model (``modes`` > 1) also of the
    best of its 20 most probable hypotheses (``best_ade`` / ``best_fde``)."""
    obs, fut = w.xy[:, :8], w.xy[:, 8:]
    p = model.predict(obs, 12, neighbours=w.neighbours)
    out = {"ade": ade(p, fut), "fde": fde(p, fut)}
    if cfg.modes > 1:
        mix = MultiModalPredictor(model).predict_mixture(obs, 12, neighbours=w.neighbours)
        b_ade, b_fde = best_of(mix.most_probable(min(BEST_OF, mix.modes)), fut)
        out |= {"best_ade": b_ade, "best_fde": b_fde}
    return out


def run(job: tuple, data_dir) -> dict:
    """One training: ``("fold", F, cfg)`` scored on F's val and test, or ``("pair", (F, G),
    cfg)`` trained without F and G, scored on each one's whole recording."""
    kind, key, cfg = job
    t0 = time.perf_counter()
    k = cfg.neighbours
    fold = key if kind == "fold" else key[0]
    train = load_split(data_dir, fold, "train", min_peds=1, neighbours=k,
                       time_steps=cfg.time_steps)
    val = load_split(data_dir, fold, "val", neighbours=k)
    if kind == "pair":
        train, val = without_scene(train, key[1]), without_scene(val, key[1])
    model, _ = train_ensemble(train.xy, val.xy, cfg, train_nb=train.neighbours,
                              val_nb=val.neighbours)
    if kind == "fold":
        out = {"val": _scores(model, cfg, val),
               "test": _scores(model, cfg, load_split(data_dir, fold, "test", neighbours=k))}
    else:
        out = {s: _scores(model, cfg, load_split(data_dir, s, "test", neighbours=k))
               for s in key}
    return out | {"seconds": time.perf_counter() - t0}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", default="base,transformer,steps_5_3_5_2")
    ap.add_argument("--set", default="cell=lstm", help="base overrides, e.g. cell=lstm")
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--json", default=None, help="write every score to this file")
    ap.add_argument("--print", default=None, metavar="JSON",
                    help="print the tables of an earlier run's --json file (no training)")
    args = ap.parse_args()
    if args.print:
        saved = json.loads(Path(args.print).read_text())
        res = {v: {int(s): r for s, r in by.items()} for v, by in saved["results"].items()}
        _print(res)
        if saved["base"]["modes"] > 1:
            _print(res, "best_")
        return
    from blindspot.parallel import parallel_map

    base = base_config()
    for item in filter(None, args.set.split(",")):
        k, v = item.split("=")
        typ = type(getattr(base, k))
        base = replace(base, **{k: (v == "True") if typ is bool else typ(v)})
    variants = args.variants.split(",")
    unknown = [v for v in variants if v not in VARIANTS]
    if unknown:
        ap.error(f"--variants: unknown {unknown}; expected among {sorted(VARIANTS)}")
    seeds = [int(s) for s in args.seeds.split(",")]
    pairs = list(itertools.combinations(FOLDS, 2))
    res: dict = {}
    for v in variants:
        for s in seeds:
            cfg = replace(base, **({"ensemble": 1, "seed": s} | VARIANTS[v]))
            jobs = [("fold", f, cfg) for f in FOLDS] + [("pair", p, cfg) for p in pairs]
            out = parallel_map(partial(run, data_dir=default_data_dir()), jobs, args.jobs)
            res.setdefault(v, {})[s] = {"fold": dict(zip(FOLDS, out[:len(FOLDS)])),
                                        "pair": {"+".join(p): o for p, o in
                                                 zip(pairs, out[len(FOLDS):])}}
            print(f"# {v} seed {s}: {sum(o['seconds'] for o in out):.0f} s of training",
                  flush=True)
            if args.json:
                Path(args.json).write_text(json.dumps({"base": base.__dict__, "results": res},
                                                      indent=1, default=str))
    _print(res)
    if base.modes > 1:
        _print(res, "best_")


def held_out(res: dict, v: str, fold: str, metric: str = "ade") -> float:
    """Variant ``v``'s score for ``fold``: its ``metric`` on each other scene, trained without
    it and ``fold``, averaged over those scenes and the seeds."""
    vals = [r["pair"]["+".join(sorted((fold, g), key=FOLDS.index))][g][metric]
            for r in res[v].values() for g in FOLDS if g != fold]
    return float(np.mean(vals))


def _print(res: dict, prefix: str = "") -> None:
    """The tables of ``res`` scored by the mean prediction (``prefix`` "") or the best of 20
    hypotheses ("best_"): every variant's scores per fold, then each rule's choices and their
    test over the five folds (the seeds' mean +- sd)."""
    variants, a, f_ = list(res), prefix + "ade", prefix + "fde"
    seeds = list(res[variants[0]])

    def fold_mean(v, f, split, metric):
        return float(np.mean([r["fold"][f][split][metric] for r in res[v].values()]))

    what = "best of 20" if prefix else "mean prediction"
    print(f"\n{what}, each variant per fold (seeds averaged):\n\n"
          "| variant | fold | held-out scenes ADE / FDE | val ADE | test ADE / FDE |")
    print("|---|---|---|---|---|")
    for v in variants:
        for f in FOLDS:
            print(f"| {v} | {f} | {held_out(res, v, f, a):.4f} / {held_out(res, v, f, f_):.4f} "
                  f"| {fold_mean(v, f, 'val', a):.4f} | {fold_mean(v, f, 'test', a):.3f} / "
                  f"{fold_mean(v, f, 'test', f_):.3f} |")
    print(f"\n{what}, each rule's choice per fold:\n\n| chosen by | " + " | ".join(FOLDS)
          + " | test ADE / FDE, five folds, mean +- sd over seeds |")
    print("|---" * (len(FOLDS) + 2) + "|")
    rules = {"held-out scenes": lambda f: min(variants, key=lambda v: held_out(res, v, f, a)),
             "val split": lambda f: min(variants, key=lambda v: fold_mean(v, f, "val", a))}
    rules |= {f"always {v}": (lambda f, v=v: v) for v in variants}
    for name, rule in rules.items():
        pick = {f: rule(f) for f in FOLDS}
        per_seed = [[np.mean([res[pick[f]][s]["fold"][f]["test"][m] for f in FOLDS])
                     for s in seeds] for m in (a, f_)]
        sd = [np.std(x, ddof=1) if len(x) > 1 else 0.0 for x in per_seed]
        print(f"| {name} | " + " | ".join(pick[f] for f in FOLDS)
              + f" | {np.mean(per_seed[0]):.4f} +- {sd[0]:.4f} / "
              f"{np.mean(per_seed[1]):.4f} +- {sd[1]:.4f} |")


if __name__ == "__main__":
    main()
