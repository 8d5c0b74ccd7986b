"""What helps a path predictor beat constant velocity on ETH/UCY: an ablation table.

    BLINDSPOT_SHARED=/work/shared python studies/ethucy_models.py \
        [--variants base,no_residual,...] [--folds eth,hotel,...] [--jobs 2] [--epochs N] \
        [--set cell=mlp,modes=20] [--val-steps 1,5/3] [--save DIR]

Every variant is the direct multi-step predictor (:mod:`blindspot.traj.seq2seq`) with the
benchmark's settings (conf/ethucy/standard.yaml, ``seq2seq``) and one change, trained per fold on
the fold's train split with the epoch kept by the fold's val ADE, ONE member (seed 0) unless the
variant says otherwise; ``next_point`` is the project's next-point LSTM rolled out 12 steps
(:func:`blindspot.traj.ethucy_protocol.train_fold_lstm`, one member). The table gives the
average over the folds of val ADE/FDE (what settings are chosen on) and test ADE/FDE (reported,
never chosen on), CVM beside them. ``ensemble_k`` rows are prefixes of one ensemble
(``--variants ensemble --set ensemble=K``: seeds 0 to k - 1 averaged).
Prints the table (Markdown) and, with ``--json``, the per-fold numbers. A multi-modal base
(``--set modes=20``: the stage's ``mix`` with ``cell=mlp``) adds a table of best-of-20 (each
model's 20 most probable hypotheses; an ensemble's pooled ones also merged into 20,
``_reduced``: :meth:`blindspot.traj.mixture.MixtureForecast.reduced`). ``--save DIR`` writes
each trained model to ``DIR/<variant>_<fold>.pt`` (``studies/ethucy_best_of.py`` reads them).
``--val-steps 1,5/3`` pools the val split's windows at those annotation steps (as
``time_steps`` does the train split's): what keeps each epoch and what the val columns average.

Conclusion: the direct multi-step predictor's choices, one change at a time against the base
(heading frame, residual on constant velocity, mirroring, displacement inputs, the loss, the
neighbours); the table and the configured seq2seq settings are in conf/ethucy/standard.yaml, the
encoders over three seeds in README (0.47-0.48 / 1.02-1.05 m; every seed past 0.50 / 1.10).
A frame scaled by the walker's step (studies/patches/speed_scaled_frame.diff: the mean observed
step, a loss in metres) makes eth worse at seed 0 (0.85 / 1.87 -> 0.88-0.92 / 1.95-2.03 m) while
val prefers the mean-step scale (0.4028 -> 0.3988 m): not adopted (docs/studies/ethucy.md,
third pass). For mix (``--set cell=mlp,modes=20``) the epoch kept by val best-of-20 is val's
choice (``keep_by: best_of``: val 0.1692 / 0.3016 -> 0.1679 / 0.2995 m at seed 0); the winner
by ADE + FDE, no residual and three seeds pooled and merged are not; 32 epochs gains 0.0005 /
0.004 m on val at twice the training, not taken (fourth pass). Training windows also resampled
every 5/3 annotated steps (``steps_5_3``: the eth file's labelled 0.4 s spans 0.67 s) are
adopted on that documented step, and val does not object: it slightly prefers them for the LSTM
encoder over seeds 0-2 (val ADE 0.4029 -> 0.4017 m) and for mix's best-of-20 at seed 0 (0.1679 /
0.2995 -> 0.1666 / 0.2931 m), and is indifferent for the MLP encoder (0.4020 -> 0.4027 m);
adding 5/2, or 4/3 and 2, is not val's choice (docs/studies/ethucy.md, sixth pass). Val
windows also at 5/3 (``--val-steps 1,5/3``, seed 0) still rank 32 epochs and [1, 5/3] first
(by 0.0008 / 0.0013 m) where test ranks them last (eighth pass).
mix with 40 hypotheses (``--set cell=mlp,modes=40``) loses on val best-of-20 whether its 20
most probable or its 40 merged into 20 are scored. Three seeds' LSTM encoders averaged
(``--variants ensemble --set cell=lstm,ensemble=3,seed=S``, S = 0, 3, 6) are preferred by val,
but the three averages score 0.4724 +- 0.0065 / 0.9762 +- 0.0111 m on test against the stage's
three-seed mean 0.4730 / 0.9785: not adopted (eighth pass).
A transformer encoder (``transformer``, three seeds) ties the LSTM on val (0.4020 against 0.4018
m) and beats the stage's LSTM on test (0.456 / 0.961 against 0.473 / 0.978 m), all of it on eth
(0.77 / 1.57 against 0.87 / 1.70): not val's choice, so a model key run on request, as the GRU
is. The low-rank motion basis (``basis_4`` to ``basis_8``) moves the LSTM's val by at most
0.0009 m with no trend in the rank (test too: 0.467-0.472 m), and loses for the MLP encoder
and mix at seed 0; one ``basis_rank`` serves every encoder, so it stays 0 (ninth pass).
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import fields, replace
from fractions import Fraction
from functools import partial
from pathlib import Path

import numpy as np

from blindspot.traj.baselines import ConstantVelocity
from blindspot.traj.ethucy import FOLDS, default_data_dir, load_split
from blindspot.traj.ethucy_protocol import BEST_OF
from blindspot.traj.metrics import ade, fde
from blindspot.traj.mixture import best_of
from blindspot.traj.multimodal import MultiModalPredictor
from blindspot.traj.seq2seq import Seq2SeqConfig, Seq2SeqEnsemble, train_ensemble

#: one change each from the base config
VARIANTS: dict[str, dict] = {
    "base": {},
    "cell_gru": {"cell": "gru"},
    "cell_lstm": {"cell": "lstm"},
    "cell_mlp": {"cell": "mlp"},
    "no_residual": {"residual": False},
    "position_inputs": {"inputs": "position"},
    "displacement_outputs": {"outputs": "displacement"},
    "no_mirror": {"mirror": False},
    "world_frame_rot180": {"frame": "world", "rotation_deg": 180.0},
    "world_frame_no_aug": {"frame": "world", "rotation_deg": 0.0},
    "heading_rot10": {"rotation_deg": 10.0},
    "mse_loss": {"loss": "mse"},
    "speed_norm": {"speed_floor": 0.05},
    "no_nll_head": {"nll_weight": 0.0},
    "social_k4": {"neighbours": 4},
    "social_k8": {"neighbours": 8},
    "lstm_social_k8": {"cell": "lstm", "neighbours": 8},
    "wide": {"hidden_size": 128, "head_hidden": 256},
    "epochs32": {"epochs": 32},
    "scale_aug15": {"scale_aug": 0.15},
    "scale_aug30": {"scale_aug": 0.3},
    # the multi-modal head's training (run with --set cell=mlp,modes=20: the stage's mix)
    "wta_ade_fde": {"wta_score": "ade_fde"},
    "keep_best_of": {"keep_by": "best_of"},
    "wta_keep": {"wta_score": "ade_fde", "keep_by": "best_of"},
    # three seeds pooled (60 hypotheses): the 20 most probable, and the 20 merged (_reduced)
    "ensemble3": {"ensemble": 3},
    # training windows also at longer annotation steps (the eth file's 10 / 6 = 5/3, issue 43;
    # the base takes the configured steps, [1, 5/3] since the sixth pass)
    "steps_1": {"time_steps": (1.0,)},
    "steps_5_3": {"time_steps": (1.0, 5 / 3)},
    "steps_5_3_5_2": {"time_steps": (1.0, 5 / 3, 5 / 2)},
    "steps_4_3_to_2": {"time_steps": (1.0, 4 / 3, 5 / 3, 2.0)},
    "steps_2": {"time_steps": (1.0, 2.0)},
    "steps_5_3_epochs32": {"time_steps": (1.0, 5 / 3), "epochs": 32},
    "transformer": {"cell": "transformer"},
    "transformer_2l": {"cell": "transformer", "num_layers": 2},
    "basis_4": {"basis_rank": 4},
    "basis_6": {"basis_rank": 6},
    "basis_8": {"basis_rank": 8},
    "transformer_basis_4": {"cell": "transformer", "basis_rank": 4},
}


def base_config() -> Seq2SeqConfig:
    from omegaconf import OmegaConf

    conf = OmegaConf.load(Path(__file__).resolve().parents[1] / "conf/ethucy/standard.yaml")
    return Seq2SeqConfig.from_mapping(OmegaConf.to_container(conf.seq2seq))


def apply_set(base: Seq2SeqConfig, spec: str) -> Seq2SeqConfig:
    """``base`` with the overrides of ``spec`` (``key=value,key=value``; ``--set``), each value
    read as its key's type. Raises ValueError naming a malformed item, an unknown key, a value
    of the wrong type, or a key no single value can set (a tuple: use a variant)."""
    names = sorted(f.name for f in fields(base))
    for item in filter(None, spec.split(",")):
        key, eq, value = item.partition("=")
        if not eq or not key:
            raise ValueError(f"--set: expected key=value items, found {item!r}")
        if key not in names:
            raise ValueError(f"--set: unknown setting {key!r}; expected one of {names}")
        typ = type(getattr(base, key))
        if typ is tuple:
            raise ValueError(f"--set: {key} takes a list, which --set cannot give; use a variant")
        if typ is bool and value not in ("True", "False"):
            raise ValueError(f"--set: {key}: expected True or False, found {value!r}")
        try:
            parsed = value == "True" if typ is bool else typ(value)
        except ValueError:
            raise ValueError(f"--set: {key}: expected a value of type {typ.__name__}, found "
                             f"{value!r}") from None
        try:
            base = replace(base, **{key: parsed})
        except ValueError as err:             # the config's own check (ConfigError)
            raise ValueError(f"--set: {key}={value}: {err}") from None
    return base


def scores(p, xy: np.ndarray, nb: np.ndarray | None) -> dict:
    """ADE / FDE of predictor ``p``'s prediction of windows ``xy`` (N, 20, 2) with neighbours
    ``nb`` (passed when ``p`` reads them); a multi-modal model (``cfg.modes`` > 1) adds
    ``best_ade`` / ``best_fde``, the best of its 20 most probable hypotheses, and when it has more
    than 20 (an ensemble's pooled ones) ``reduced_ade`` / ``reduced_fde``, the best of them merged
    into 20 (:meth:`blindspot.traj.mixture.MixtureForecast.reduced`)."""
    kw = {"neighbours": nb} if getattr(p, "uses_neighbours", False) else {}
    pred = p.predict(xy[:, :8], 12, **kw)
    out = {"ade": ade(pred, xy[:, 8:]), "fde": fde(pred, xy[:, 8:])}
    if getattr(getattr(p, "cfg", None), "modes", 1) > 1:
        mix = MultiModalPredictor(p).predict_mixture(xy[:, :8], 12, neighbours=nb)
        b_ade, b_fde = best_of(mix.most_probable(min(BEST_OF, mix.modes)), xy[:, 8:])
        out |= {"best_ade": b_ade, "best_fde": b_fde}
        if mix.modes > BEST_OF:
            r_ade, r_fde = best_of(mix.reduced(BEST_OF).means, xy[:, 8:])
            out |= {"reduced_ade": r_ade, "reduced_fde": r_fde}
    return out


def run_variant(fold: str, name: str, cfg: Seq2SeqConfig, data_dir, save_dir=None,
                val_steps: tuple[float, ...] = (1.0,)) -> dict:
    t0 = time.perf_counter()
    k = cfg.neighbours
    val_w = load_split(data_dir, fold, "val", neighbours=k, time_steps=val_steps)
    test_w = load_split(data_dir, fold, "test", neighbours=k)
    val, test = val_w.xy, test_w.xy
    nb = {"val": val_w.neighbours, "test": test_w.neighbours}
    out = {}
    if name == "next_point":
        from blindspot.traj.config import RolloutLSTMConfig
        from blindspot.traj.ethucy_protocol import train_fold_lstm
        pred, *_ = train_fold_lstm(data_dir, fold, RolloutLSTMConfig(ensemble=1, num_threads=1),
                                   progress=False)
        preds = {name: pred}
    else:
        train_w = load_split(data_dir, fold, "train", min_peds=1, neighbours=k,
                             time_steps=cfg.time_steps)
        ens, _ = train_ensemble(train_w.xy, val, cfg, train_nb=train_w.neighbours,
                                val_nb=nb["val"])
        if save_dir:
            ens.save(Path(save_dir) / f"{name}_{fold}.pt")
        preds = {name: ens}
        if cfg.ensemble > 1:
            for k in range(1, cfg.ensemble + 1):
                preds[f"ensemble_{k}"] = Seq2SeqEnsemble(ens.members[:k])
    preds["cvm"] = ConstantVelocity()
    for key, p in preds.items():
        sc = {"val": scores(p, val, nb["val"]), "test": scores(p, test, nb["test"])}
        out[key] = {f"{split}_{m}": sc[split][m] for split in sc for m in ("ade", "fde")}
        out[key] |= {f"{split}_{m}": sc[split][m] for split in sc for m in ("best_ade", "best_fde")
                     if m in sc[split]}
        if "reduced_ade" in sc["val"]:     # the pooled hypotheses merged into 20
            out[f"{key}_reduced"] = out[key] | {f"{split}_best_{m}": sc[split][f"reduced_{m}"]
                                                for split in sc for m in ("ade", "fde")}
    out["_seconds"] = time.perf_counter() - t0
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", default=",".join(VARIANTS) + ",next_point,ensemble")
    ap.add_argument("--folds", default=",".join(FOLDS))
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--epochs", type=int, default=None, help="override the base epochs")
    ap.add_argument("--set", default="", help="base overrides, e.g. cell=gru,epochs=8")
    ap.add_argument("--json", default=None, help="write per-fold numbers to this file")
    ap.add_argument("--val-steps", default="1", help="the val split's windows at these "
                    "annotation steps, pooled (e.g. 1,5/3): what keeps the direct predictor's "
                    "epoch and what the val columns average")
    ap.add_argument("--save", default=None, help="write each trained model to DIR/<variant>_"
                    "<fold>.pt (Seq2SeqEnsemble.save)")
    args = ap.parse_args()
    from blindspot.parallel import parallel_map

    try:
        base = apply_set(base_config(), args.set)
    except ValueError as err:
        ap.error(str(err))
    if args.epochs:
        base = replace(base, epochs=args.epochs)
    folds = args.folds.split(",")
    try:
        val_steps = tuple(float(Fraction(v)) for v in args.val_steps.split(","))
    except (ValueError, ZeroDivisionError):
        ap.error(f"--val-steps: expected annotation steps such as 1,5/3, found {args.val_steps!r}")
    if 1.0 not in val_steps or len(set(val_steps)) != len(val_steps) or min(val_steps) < 1:
        ap.error(f"--val-steps: expected distinct steps >= 1 holding 1 (the annotated grid), "
                 f"found {args.val_steps!r}")
    unknown = [v for v in args.variants.split(",")
               if v not in VARIANTS and v not in ("ensemble", "next_point")]
    if unknown:
        ap.error(f"--variants: unknown {unknown}; expected among {sorted(VARIANTS)}, ensemble, "
                 "next_point")
    configs = {}
    for v in args.variants.split(","):     # every config checked before any training
        try:
            configs[v] = (base if v in ("ensemble", "next_point")
                          else replace(base, **({"ensemble": 1} | VARIANTS[v])))
        except ValueError as err:
            ap.error(f"--variants {v} with --set {args.set!r}: {err}")
    rows: dict[str, dict[str, dict]] = {}
    for v, cfg in configs.items():
        work = partial(run_variant, name=v, cfg=cfg, data_dir=default_data_dir(),
                       save_dir=args.save, val_steps=val_steps)
        res = dict(zip(folds, parallel_map(work, folds, args.jobs)))
        for key in res[folds[0]]:
            if key.startswith("_"):
                continue
            rows[key if key not in ("cvm",) or "cvm" not in rows else "cvm"] = {
                f: res[f][key] for f in folds}
        print(f"# {v}: {sum(r['_seconds'] for r in res.values()):.0f} s of fold time",
              flush=True)
        _print(rows, folds)
        if args.json:
            with open(args.json, "w") as fh:
                json.dump({"base": base.__dict__, "val_steps": val_steps, "rows": rows}, fh, indent=1, default=str)


def _print(rows, folds) -> None:
    print("| variant | val ADE | val FDE | test ADE | test FDE | test per fold (ADE/FDE) |")
    print("|---|---|---|---|---|---|")
    for k, r in rows.items():
        if k.endswith("_reduced"):            # its single prediction is its parent's
            continue
        m = {s: np.mean([r[f][s] for f in folds]) for s in ("val_ade", "val_fde", "test_ade",
                                                            "test_fde")}
        per = ", ".join(f"{f} {r[f]['test_ade']:.2f}/{r[f]['test_fde']:.2f}" for f in folds)
        print(f"| {k} | {m['val_ade']:.4f} | {m['val_fde']:.4f} | {m['test_ade']:.4f} | "
              f"{m['test_fde']:.4f} | {per} |", flush=True)
    multi = [k for k, r in rows.items() if "val_best_ade" in r[folds[0]]]
    if not multi:
        return
    print("\n| variant, best of the hypotheses | val ADE | val FDE | test ADE | test FDE | "
          "test per fold (ADE/FDE) |")
    print("|---|---|---|---|---|---|")
    for k in multi:
        r = rows[k]
        m = {s: np.mean([r[f][s] for f in folds]) for s in ("val_best_ade", "val_best_fde",
                                                            "test_best_ade", "test_best_fde")}
        per = ", ".join(f"{f} {r[f]['test_best_ade']:.2f}/{r[f]['test_best_fde']:.2f}"
                        for f in folds)
        print(f"| {k} | {m['val_best_ade']:.4f} | {m['val_best_fde']:.4f} | "
              f"{m['test_best_ade']:.4f} | {m['test_best_fde']:.4f} | {per} |", flush=True)


if __name__ == "__main__":
    main()
