"""Settings chosen by a held-out scene: does a validation that sees another scene choose what
ETH/UCY's test prefers?

    BLINDSPOT_SHARED=/work/shared python studies/ethucy_scene_selection.py \
        --variants base,transformer,steps_5_3_5_2 --set cell=lstm --seeds 0,1,2 [--jobs 2] \
        [--json FILE]

The benchmark's val split is a slice of the same four scenes the fold trains on, so it cannot
see what sets the fold's test scene apart (eth's pace, issue 43). Leave-one-domain-out
validation (Gulrajani and Lopez-Paz 2021, "In search of lost domain generalization", DomainBed's
model selection) asks instead how a setting does on a recording it never trained on. For test
scene F and every other scene G, a model trained on F's train split without G's recordings'
files (its epoch kept by F's val split without them) is scored on G's whole recording (fold G's
test files). F's own recording never enters F's choice, which stays blind to F's test. (Only eth
and hotel are places no other file shows: uni_examples, of univ's campus, and crowds_zara03
train in every fold.) The pair models of F and G train on the same files (each fold's splits
hold the same per-scene files, checked byte for byte before training), so the ten scene pairs'
models serve both folds. Each setting's held-out score for fold F is its ADE averaged over the
four scenes G (equal weight, as the folds are averaged) and over the seeds; the lowest is
held-out validation's choice, set beside each fold's own val split's choice and every variant's
test (the fold's own model, ``ethucy_models.run_variant``; the seeds' mean and sd).

Variants are ``studies/ethucy_models.py``'s (one change from the benchmark's seq2seq settings,
``conf/ethucy/standard.yaml``); ``--set`` overrides the base for all of them (not ``seed`` or
``ensemble``: one member per seed of ``--seeds``). ``--print FILE`` prints an earlier run's
tables from its ``--json`` file. A multi-modal base (``--set cell=mlp,modes=20``) adds the
tables scored and chosen by best-of-20.

Conclusion (2026-12-07, the LSTM encoder, the transformer encoder and the LSTM with training
windows also at 5/2, seeds 0-2, 52 min on 2 cores; docs/studies/ethucy.md, tenth pass): by
held-out ADE the transformer is chosen for hotel, univ, zara1 and zara2, whose held-out scenes
include eth (trained without eth it scores 0.796 m there against the LSTM's 0.856), and for eth
itself, whose test the transformer improves, the LSTM, tied with 5/2 (0.37418 against 0.37424
m): test 0.4750 / 0.9859 m against 0.4733 / 0.9791 for the stage's settings retrained. By
held-out FDE, as by each fold's val, eth takes 5/2: 0.4687 / 0.9637 m, on margins inside the
seeds' spread. No rule chooses the transformer for eth; what makes eth hard is in eth alone.
For mix (best-of-20, with
and without 5/2; 38 min) each fold's val keeps the stage's settings, and the held-out scenes'
choice loses 0.001 / 0.002 m on test. Nothing adopted.
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
from ethucy_models import VARIANTS, apply_set, base_config, run_variant, scores  # own folder

from blindspot.traj.ethucy import FOLDS, Windows, default_data_dir, load_split, split_files
from blindspot.traj.seq2seq import train_ensemble

SPLIT_SUFFIXES = ("_train", "_val")   # a train / val file is a test recording's stem + suffix


def scene_stems(data_dir, scene: str) -> set[str]:
    """The stems of ``scene``'s recordings: its fold's test files (univ: students001 and
    students003; uni_examples and crowds_zara03 are training files of every fold, of no
    test scene)."""
    return {f.stem for f in split_files(data_dir, scene, "test")}


def _recording(path: str) -> str:
    stem = Path(path).stem
    for suffix in SPLIT_SUFFIXES:
        stem = stem.removesuffix(suffix)
    return stem


def without_scene(w: Windows, stems: set[str], scene: str) -> Windows:
    """The windows of ``w`` whose file is not a part of one of ``scene``'s recordings
    (``stems``, :func:`scene_stems`); ``files``, ``skipped`` and ``file_index`` follow.
    Raises ValueError when a recording has no file in ``w``."""
    rec = [_recording(f) for f in w.files]
    missing = sorted(stems - set(rec))
    if missing:
        raise ValueError(f"without_scene: {scene}: no file of {missing} among {w.files}")
    keep = np.array([r not in stems for r in rec])
    new_index = np.cumsum(keep) - 1
    m = keep[w.file_index]
    return replace(w, xy=w.xy[m], track_id=w.track_id[m], start=w.start[m],
                   file_index=new_index[w.file_index[m]],
                   files=tuple(f for f, k in zip(w.files, keep) if k),
                   skipped=tuple(r for r, k in zip(w.skipped, keep) if k),
                   neighbours=None if w.neighbours is None else w.neighbours[m])


def check_shared_pairs(data_dir) -> None:
    """The pair models' premise: for scenes F and G, fold F's train and val files less G's are
    fold G's less F's, byte for byte (so one model serves both folds). Raises ValueError."""
    stems = {scene: scene_stems(data_dir, scene) for scene in FOLDS}
    for f, g in itertools.combinations(FOLDS, 2):
        for split in ("train", "val"):
            a, b = ({p.name: p.read_bytes() for p in split_files(data_dir, fold, split)
                     if _recording(p.name) not in stems[other]}
                    for fold, other in ((f, g), (g, f)))
            if a != b:
                raise ValueError(f"{data_dir}: {f}/{split} without {g} differs from {g}/{split} "
                                 f"without {f}: {sorted(a)} against {sorted(b)}")


def run(job: tuple, data_dir) -> dict:
    """One training: ``("fold", F, cfg)`` scored on F's val and test splits
    (:func:`ethucy_models.run_variant`), or ``("pair", (F, G), cfg)`` trained without F and G,
    scored on each one's whole recording."""
    kind, key, cfg = job
    t0 = time.perf_counter()
    if kind == "fold":
        r = run_variant(key, "v", cfg, data_dir)["v"]
        out = {split: {m.removeprefix(split + "_"): x for m, x in r.items()
                       if m.startswith(split + "_")} for split in ("val", "test")}
        return out | {"seconds": time.perf_counter() - t0}
    k, (fold, other) = cfg.neighbours, key
    stems = scene_stems(data_dir, other)
    train, val = (without_scene(load_split(data_dir, fold, split, min_peds=1 if split == "train"
                                           else 2, neighbours=k, time_steps=steps), stems, other)
                  for split, steps in (("train", cfg.time_steps), ("val", (1.0,))))
    model, _ = train_ensemble(train.xy, val.xy, cfg, train_nb=train.neighbours,
                              val_nb=val.neighbours)
    out = {}
    for scene in key:
        test = load_split(data_dir, scene, "test", neighbours=k)
        out[scene] = scores(model, test.xy, test.neighbours)
    return out | {"seconds": time.perf_counter() - t0}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", default="base,transformer,steps_5_3_5_2")
    ap.add_argument("--set", default="cell=lstm", help="base overrides, e.g. cell=lstm")
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--json", default=None, help="write every score to this file")
    ap.add_argument("--print", default=None, metavar="JSON",
                    help="print the tables of an earlier run's --json file (no training; "
                    "the other options are not read)")
    args = ap.parse_args()
    if args.print:
        try:
            saved = json.loads(Path(args.print).read_text())
            res = {v: {int(s): r for s, r in by.items()} for v, by in saved["results"].items()}
            modes = saved["base"]["modes"]
            if not res or not all(res.values()):
                raise ValueError("no variant with a finished seed")
            tables = [_tables(res)] + ([_tables(res, "best_")] if modes > 1 else [])
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as err:
            ap.error(f"--print: expected a --json file of this script, found {args.print!r} "
                     f"({type(err).__name__}: {err})")
        print(*tables, sep="\n")
        return
    variants = args.variants.split(",")
    unknown = sorted({v for v in variants if v not in VARIANTS})
    repeated = sorted({v for v in variants if variants.count(v) > 1})
    if unknown or repeated:
        ap.error(f"--variants: unknown {unknown}, repeated {repeated}; expected distinct names "
                 f"among {sorted(VARIANTS)}")
    try:
        seeds = [int(s) for s in args.seeds.split(",")]
    except ValueError:
        ap.error(f"--seeds: expected integers such as 0,1,2, found {args.seeds!r}")
    if len(set(seeds)) != len(seeds):
        ap.error(f"--seeds: expected distinct seeds, found {args.seeds!r}")
    fixed = {item.partition("=")[0] for item in args.set.split(",")} & {"seed", "ensemble"}
    if fixed:
        ap.error(f"--set: {sorted(fixed)} are set by this script (one member, --seeds)")
    try:
        base = apply_set(base_config(), args.set)
    except ValueError as err:
        ap.error(str(err))
    configs = {}
    for v, s in itertools.product(variants, seeds):   # every config checked before training
        try:
            configs[v, s] = replace(base, **({"ensemble": 1, "seed": s} | VARIANTS[v]))
        except ValueError as err:
            ap.error(f"--variants {v} with --seeds {s} and --set {args.set!r}: {err}")
    if args.json:
        try:
            Path(args.json).write_text("{}")
        except OSError as err:
            ap.error(f"--json: cannot write {args.json!r} ({err})")
    try:
        check_shared_pairs(default_data_dir())
    except ValueError as err:
        ap.error(f"the ETH/UCY data: {err}")
    from blindspot.parallel import parallel_map

    t0 = time.perf_counter()
    pairs = list(itertools.combinations(FOLDS, 2))
    res: dict = {}
    for (v, s), cfg in configs.items():
        jobs = [("fold", f, cfg) for f in FOLDS] + [("pair", p, cfg) for p in pairs]
        out = parallel_map(partial(run, data_dir=default_data_dir()), jobs, args.jobs)
        res.setdefault(v, {})[s] = {"fold": dict(zip(FOLDS, out[:len(FOLDS)])),
                                    "pair": {"+".join(p): o for p, o in
                                             zip(pairs, out[len(FOLDS):])}}
        print(f"# {v} seed {s}: {sum(o['seconds'] for o in out):.0f} s of fold time", flush=True)
        if args.json:
            Path(args.json).write_text(json.dumps({"base": base.__dict__, "results": res},
                                                  indent=1, default=str))
    print(f"# wall time {time.perf_counter() - t0:.0f} s")
    print(_tables(res))
    if base.modes > 1:
        print(_tables(res, "best_"))


def held_out(res: dict, v: str, fold: str, metric: str = "ade", seed: int | None = None
             ) -> float:
    """Variant ``v``'s score for ``fold``: its ``metric`` on each other scene, trained without
    it and ``fold``, averaged over those scenes and the seeds (or at one ``seed``)."""
    runs = res[v].values() if seed is None else [res[v][seed]]
    return float(np.mean([r["pair"][_pair(fold, g)][g][metric] for r in runs
                          for g in FOLDS if g != fold]))


def _pair(f: str, g: str) -> str:
    return "+".join(sorted((f, g), key=FOLDS.index))


def _tables(res: dict, prefix: str = "") -> str:
    """The tables of ``res`` scored by the mean prediction (``prefix`` "") or the best of 20
    hypotheses ("best_"): every variant's scores per fold; each held-out scene's score by the
    pair models; each rule's choices and their test over the five folds (the seeds' mean +- sd);
    the held-out rule's margin per fold."""
    variants, a, f_ = list(res), prefix + "ade", prefix + "fde"
    seeds = sorted(set.intersection(*(set(by) for by in res.values())))
    lines = []
    if any(set(by) != set(seeds) for by in res.values()):
        lines.append(f"(an unfinished run: the seeds every variant has, {seeds})")
        res = {v: {s: by[s] for s in seeds} for v, by in res.items()}

    def fold_mean(v, f, split, metric):
        return float(np.mean([r["fold"][f][split][metric] for r in res[v].values()]))

    def sd(x):
        return f"{np.std(x, ddof=1):.4f}" if len(x) > 1 else "n/a"

    what = "best of 20" if prefix else "mean prediction"
    lines += [f"\n{what}, each variant per fold (seeds averaged; the held-out score's range over "
              "the seeds):\n", "| variant | fold | held-out scenes ADE [seeds] / FDE | val ADE "
              "/ FDE | test ADE / FDE |", "|---|---|---|---|---|"]
    for v in variants:
        for f in FOLDS:
            per = [held_out(res, v, f, a, s) for s in seeds]
            lines.append(f"| {v} | {f} | {held_out(res, v, f, a):.5f} [{min(per):.4f}-"
                         f"{max(per):.4f}] / {held_out(res, v, f, f_):.4f} | "
                         f"{fold_mean(v, f, 'val', a):.4f} / {fold_mean(v, f, 'val', f_):.4f} | "
                         f"{fold_mean(v, f, 'test', a):.3f} / {fold_mean(v, f, 'test', f_):.3f} |")
    lines += [f"\n{what}, each scene held out: ADE of the four models trained without it (and one "
              "other), seeds averaged, their mean [range]:\n",
              "| variant | " + " | ".join(FOLDS) + " |", "|---" * (len(FOLDS) + 1) + "|"]
    for v in variants:
        cells = []
        for g in FOLDS:
            x = [np.mean([r["pair"][_pair(f, g)][g][a] for r in res[v].values()])
                 for f in FOLDS if f != g]
            cells.append(f"{np.mean(x):.3f} [{min(x):.2f}-{max(x):.2f}]")
        lines.append(f"| {v} | " + " | ".join(cells) + " |")
    lines += [f"\n{what}, each rule's choice per fold:\n", "| chosen by | " + " | ".join(FOLDS)
              + " | test ADE / FDE, five folds, mean +- sd over seeds |",
              "|---" * (len(FOLDS) + 2) + "|"]
    rules = {"held-out scenes, by ADE": lambda f: min(variants,
                                                      key=lambda v: held_out(res, v, f, a)),
             "held-out scenes, by FDE": lambda f: min(variants,
                                                      key=lambda v: held_out(res, v, f, f_)),
             "val split, by ADE": lambda f: min(variants,
                                                key=lambda v: fold_mean(v, f, "val", a))}
    rules |= {f"always {v}": (lambda f, v=v: v) for v in variants}
    for name, rule in rules.items():
        pick = {f: rule(f) for f in FOLDS}
        per_seed = [[np.mean([res[pick[f]][s]["fold"][f]["test"][m] for f in FOLDS])
                     for s in seeds] for m in (a, f_)]
        lines.append(f"| {name} | " + " | ".join(pick[f] for f in FOLDS)
                     + f" | {np.mean(per_seed[0]):.4f} +- {sd(per_seed[0])} / "
                     f"{np.mean(per_seed[1]):.4f} +- {sd(per_seed[1])} |")
    if len(variants) > 1:
        margin = {f: np.diff(sorted(held_out(res, v, f, a) for v in variants)[:2])[0]
                  for f in FOLDS}
        lines.append("\nheld-out scenes' ADE margin between its first two choices (m): "
                     + ", ".join(f"{f} {m:.5f}" for f, m in margin.items()))
    return "\n".join(lines)


if __name__ == "__main__":
    main()
