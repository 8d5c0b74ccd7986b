"""The scenes' direct multi-step predictor, ``lstm_direct``: the model of
:mod:`blindspot.traj.seq2seq` trained on the radar path data set.

The paper's LSTM (:mod:`blindspot.traj.lstm`) predicts the next point of a 50-point window and is
rolled out one network call per future step, each call re-running its 50-step recurrence: 30
calls of each of its five networks for a 3 s forecast. This model reads the last ``obs_len``
radar points of a track once and emits every future point together, with a Gaussian per step,
trained on the mean Euclidean error over the whole horizon (the score itself) against the
*true* future positions of the simulated paths, so it learns to look through the radar points'
noise as well as to extrapolate (the next-point LSTM is trained on the noisy next point).

Pairs (:func:`direct_pairs`): from each measured path, the last ``obs_len`` measured points
(interior misses linearly interpolated; windows that still hold a miss, or end in one,
dropped) and the next ``horizon`` true positions, a pair every ``stride`` points
(:func:`blindspot.traj.calibration.path_pairs`). Paths are split as the windows stage split
them: training paths train, validation paths choose each member's epoch, every other path is
held out (:func:`path_splits`).

Pre-training (``direct.pretrain_epochs`` > 0, :func:`pretraining_walks`): the members first learn
from real pedestrians, every ETH/UCY walk resampled to the radar's frame period with radar-like
errors on its history, then are fine-tuned on the radar pairs (issue 10: it helps this model by
10 % at 3 s on held-out radar paths, where it did not help the next-point LSTM).

Shapes: measured and true paths (P, T, 2) metres (measured NaN where the radar saw nothing);
pairs (N, obs_len + horizon, 2) metres.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from blindspot.traj.calibration import path_pairs
from blindspot.traj.config import DirectConfig
from blindspot.traj.pretrain import ethucy_sequences, radar_point_errors, with_point_errors
from blindspot.traj.seq2seq import FitReport, Seq2SeqEnsemble, train_ensemble
from blindspot.traj.windows import WindowSet
from blindspot.typed_config import ConfigError

__all__ = ["NAME", "path_splits", "check_fits", "direct_pairs", "pretraining_walks", "train_direct",
           "direct_scores"]

#: the predictor's name in the calibration records, the warning's predictor list and reports
NAME = "lstm_direct"


def path_splits(n_paths: int, train: WindowSet, val: WindowSet) -> dict[str, np.ndarray]:
    """Path ids (rows of the path arrays) of each split: ``train`` and ``val`` those the windows
    stage's splits were cut from, ``test`` every other path (the test windows' paths and the
    spare paths the split did not need), never trained or validated on.

    Raises ValueError when a window's path id is outside ``0..n_paths - 1``."""
    ids = {"train": np.unique(train.path_id), "val": np.unique(val.path_id)}
    for split, a in ids.items():
        if a.size and (a[0] < 0 or a[-1] >= n_paths):
            raise ValueError(f"path_splits: the {split} windows name paths {a[0]}..{a[-1]}, "
                             f"outside the {n_paths} paths of the path table")
    ids["test"] = np.setdiff1d(np.arange(n_paths), np.concatenate([ids["train"], ids["val"]]))
    return ids


def check_fits(cfg: DirectConfig, window: int, horizon_frames: int) -> None:
    """ConfigError unless the model can serve the calibration pairs (histories of ``window``
    points, futures of ``horizon_frames``): ``direct.model.obs_len`` at most ``window``
    (``dataset.window``) and ``direct.model.horizon`` at least ``horizon_frames``
    (``calibration.horizon_frames``). The train_direct stage checks it before training, so a
    clash does not surface in the calibration stage after the training's minutes."""
    if cfg.model.obs_len > window:
        raise ConfigError("direct.model.obs_len", cfg.model.obs_len,
                          f"at most dataset.window = {window} (the calibration pairs' histories)")
    if cfg.model.horizon < horizon_frames:
        raise ConfigError("direct.model.horizon", cfg.model.horizon,
                          f"at least calibration.horizon_frames = {horizon_frames} (the "
                          "calibration pairs' futures)")


def direct_pairs(measured: np.ndarray, truth: np.ndarray, obs_len: int, horizon: int,
                 stride: int) -> np.ndarray:
    """(N, obs_len + horizon, 2): measured history then true future, a pair every ``stride``
    points of each path (module docstring). CalibrationError when they do not fit the paths."""
    hist, fut = path_pairs(measured, truth, obs_len, horizon, stride)
    return np.concatenate([hist, fut], axis=1)


def pretraining_walks(data_dir: str | Path, measured: np.ndarray, truth: np.ndarray,
                      cfg: DirectConfig, dt_s: float) -> np.ndarray:
    """(S, obs_len + horizon, 2) ETH/UCY walks for pre-training, metres: every pedestrian's walk
    from every annotated frame resampled to ``dt_s``, each turned by a random angle
    (:func:`blindspot.traj.pretrain.ethucy_sequences`), at most ``cfg.pretrain_walks`` of them
    (a random subset; 0 = all), each history point moved by a measured-minus-true error drawn
    from the given paths' radar points (:func:`blindspot.traj.pretrain.with_point_errors`; pass
    the training paths only). Seeded by ``cfg.model.seed``, rotations and draws on separate
    streams.

    Measured (studies/pretrain_direct.py, 21 held-out radar paths): pre-training 5 epochs on all
    39,649 walks, then fine-tuning, cut the 3 s ADE / FDE by 10 % against training from scratch.

    Raises EthUcyDataError (folder, frame period, shapes) and ValueError when the paths hold no
    radar point."""
    m = cfg.model
    walks = ethucy_sequences(data_dir, m.obs_len + m.horizon, dt_s, seed=m.seed)
    pick, noise = (np.random.default_rng(s) for s in np.random.SeedSequence(m.seed).spawn(2))
    if 0 < cfg.pretrain_walks < len(walks):
        walks = walks[np.sort(pick.choice(len(walks), cfg.pretrain_walks, replace=False))]
    errors = radar_point_errors(measured, truth)
    if not len(errors):
        raise ValueError("pretraining_walks: the paths hold no radar point to draw errors from")
    return with_point_errors(walks, m.obs_len, errors, noise)


def train_direct(measured: np.ndarray, truth: np.ndarray, ids: dict[str, np.ndarray],
                 cfg: DirectConfig, pretrain: np.ndarray | None = None
                 ) -> tuple[Seq2SeqEnsemble, list[FitReport], list[FitReport]]:
    """Train ``cfg.model.ensemble`` members (seeds ``cfg.model.seed + k``, ``cfg.jobs``
    processes) on the pairs of the ``train`` paths; each keeps the epoch of lowest ADE on the
    ``val`` paths' pairs. With ``pretrain`` walks ((S, obs_len + horizon, 2), metres; see
    :func:`pretraining_walks`) and ``cfg.pretrain_epochs`` > 0, the members are first trained
    that many epochs on them (epoch chosen on the same ``val`` pairs), then fine-tuned on the
    radar pairs (:func:`blindspot.traj.seq2seq.train_ensemble` ``init``), or, with
    ``cfg.finetune`` false, kept as they are.

    Returns the ensemble (named :data:`NAME`), each member's report (the pre-training's when
    not fine-tuned), and each member's pre-training report (empty without pre-training).

    Raises CalibrationError (from :func:`~blindspot.traj.calibration.path_pairs`) when the paths
    are shorter than ``obs_len + horizon``, ValueError when a split yields no pair (every
    window holding a miss) or when ``cfg.finetune`` is false and no ``pretrain`` walks are
    given, HistoryError for malformed ``pretrain`` walks."""
    m = cfg.model
    xy = {s: direct_pairs(measured[ids[s]], truth[ids[s]], m.obs_len, m.horizon, cfg.stride)
          for s in ("train", "val")}
    for split, a in xy.items():
        if not len(a):
            raise ValueError(f"train_direct: the {split} paths yield no (obs_len={m.obs_len}, "
                             f"horizon={m.horizon}) pair")
    init, pre_reports = None, []
    if pretrain is not None and cfg.pretrain_epochs > 0:
        init, pre_reports = train_ensemble(pretrain, xy["val"],
                                           replace(m, epochs=cfg.pretrain_epochs), name=NAME,
                                           jobs=cfg.jobs)
        if not cfg.finetune:
            return init, pre_reports, pre_reports
    elif not cfg.finetune:
        raise ValueError("train_direct: direct.finetune is false, so the model is the "
                         "pre-trained one, but no pre-training walks were given")
    model, reports = train_ensemble(xy["train"], xy["val"], m, name=NAME, jobs=cfg.jobs,
                                    init=init)
    return model, reports, pre_reports


def direct_scores(predictors: dict, measured: np.ndarray, truth: np.ndarray, obs_len: int,
                  steps: tuple[int, ...], stride: int) -> dict[str, dict[str, float]]:
    """ADE / FDE (m) of each predictor over the first ``k`` future steps, for every ``k`` in
    ``steps``, on the pairs of the given paths (history: the last ``obs_len`` measured points,
    or as many as a predictor's ``window`` asks when it reads more; future: the truth).

    Returns ``{name: {"ade_<k>": .., "fde_<k>": .., "n_pairs": N}}``."""
    horizon = max(steps)
    window = max([obs_len] + [int(getattr(p, "window", 0) or 0) for p in predictors.values()])
    hist, fut = path_pairs(measured, truth, window, horizon, stride)
    out = {}
    for name, p in predictors.items():
        err = np.linalg.norm(np.asarray(p.predict(hist, horizon)) - fut, axis=-1)   # (N, H)
        out[name] = {**{f"ade_{k}": float(err[:, :k].mean()) for k in steps},
                     **{f"fde_{k}": float(err[:, k - 1].mean()) for k in steps},
                     "n_pairs": int(len(hist))}
    return out



# ----------------------------------------------------------------------------- the stage's report
STEPS_S = (1.0, 2.0, 3.0)   # the horizons train_direct.json reports, beside the model's own


def score_steps(dt: float, horizon: int) -> tuple[int, ...]:
    """The frames scored: 1, 2 and 3 s (:data:`STEPS_S`, at most ``horizon``) and ``horizon``."""
    return tuple(sorted({min(int(round(s / dt)), horizon) for s in STEPS_S} | {horizon}))


def direct_metrics(scores: dict, predictors, steps, dt: float, ids: dict, d, reports,
                   pre_reports, walks) -> dict:
    """train_direct.json: each predictor's scores by split, the steps, the paths per split,
    each member's chosen epoch and the pre-training's (no wall times: same bytes each run)."""
    return {**{name: {s: scores[s][name] for s in scores} for name in predictors},
            "steps_frames": list(steps), "frame_period_s": dt,
            "n_paths": {s: int(len(v)) for s, v in ids.items()},
            "members": [{"seed": d.model.seed + k, "best_epoch": r.best_epoch,
                         "val_ade_m": r.best_val_ade} for k, r in enumerate(reports)],
            "pretrain": {"epochs": d.pretrain_epochs,
                         "n_walks": 0 if walks is None else int(len(walks)),
                         "best_epochs": [r.best_epoch for r in pre_reports],
                         "val_ade_m": [r.best_val_ade for r in pre_reports]}}


def direct_line(metrics: dict, predictors, steps, dt: float, d, reports, pre_reports,
                walks) -> str:
    """One log line: members, best epochs, training times, held-out ADE/FDE over ~3 s."""
    k = steps[min(2, len(steps) - 1)]
    pre = (f"pre-trained {d.pretrain_epochs} epochs on {len(walks)} ETH/UCY walks (best epochs "
           f"{[r.best_epoch for r in pre_reports]}, {max(r.seconds for r in pre_reports):.0f} s "
           "each at most), " if pre_reports else "")
    return (f"train_direct: {len(reports)} members, {pre}best epochs "
            f"{[r.best_epoch for r in reports]}, {max(r.seconds for r in reports):.0f} s each at "
            f"most; held-out ADE/FDE over {k * dt:.1f} s: "
            + ", ".join(f"{n} {v['test'][f'ade_{k}']:.3f}/{v['test'][f'fde_{k}']:.3f} m"
                        for n, v in metrics.items() if n in predictors))


def logged_direct(metrics: dict, predictors, reports) -> dict:
    """:func:`direct_metrics` as MLflow metrics, each member's training time added."""
    logged = {n: metrics[n] for n in predictors}
    logged["members"] = {f"seed{m['seed']}": {**{kk: v for kk, v in m.items() if kk != "seed"},
                                              "seconds": r.seconds}
                         for m, r in zip(metrics["members"], reports)}
    return logged
