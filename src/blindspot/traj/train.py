"""Training of the next-point LSTM (paper Table 1: Adam, lr 0.001, 15 epochs).

Loss: mean squared error in the network's (normalised) target units. Metrics are in metres:

- ``val_rmse_m`` = ``sqrt(mean over windows and over the x and y coordinates of error^2)``, the
  per-coordinate RMSE that Keras' ``RootMeanSquaredError`` / ``sqrt(val_mse)`` reports for a 2-output
  regression; this is the number we put beside the paper's "validation RMSE 0.07" (the paper's code
  is not public; Keras is the likely source of its number).
- ``val_rmse_euclid_m`` = ``sqrt(mean over windows of |error|^2)`` (Euclidean distance), which is
  ``sqrt(2)`` times the former for isotropic errors. Both are in the history.
- ``train_rmse_m`` is the running per-coordinate RMSE over the epoch's batches (weights change
  during the epoch, as in Keras' progress figures).

Determinism: the seed drives ``torch.manual_seed`` (weight init, dropout) and a private
``torch.Generator`` (batch order); deterministic algorithms are switched on for the run and the
previous setting restored afterwards. The same seed, data, config and thread count give
bit-identical weights. With ``checkpoint_dir`` the state after each epoch (model, optimiser, RNG
states, history) is written to ``last.pt``; ``resume=True`` continues from it and reaches the same
final weights as an uninterrupted run.
"""

from __future__ import annotations

import hashlib
import math
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from functools import partial
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import torch
from torch import nn
from tqdm.auto import tqdm

from blindspot.arrays import check_array
from blindspot.io import atomic_path, write_now
from blindspot.traj.config import LSTMConfig, TrainConfig
from blindspot.traj.lstm import LSTMPredictor, LSTMRegressor, NormStats
from blindspot.traj.metrics import MetricShapeError, ade, fde
from blindspot.traj.windows import WindowSet

_CKPT_FORMAT = "blindspot.train-checkpoint/1"
CHECKPOINT_NAME = "last.pt"
HISTORY_COLUMNS = ("epoch", "train_loss", "train_rmse_m", "val_rmse_m", "val_rmse_euclid_m", "seconds")


@dataclass
class EnsembleResult:
    """Outcome of :func:`train_ensemble`.

    Attributes:
        predictor: one :class:`LSTMPredictor` averaging every member.
        members: each member's :class:`TrainResult`, in seed order.
        seeds: the members' seeds.
    """

    predictor: LSTMPredictor
    members: list[TrainResult]
    seeds: list[int]

    @property
    def history(self) -> pd.DataFrame:
        """Every member's history, with ``member`` and ``seed`` columns in front."""
        return pd.concat([r.history.assign(member=i, seed=s)[["member", "seed", *HISTORY_COLUMNS]]
                          for i, (r, s) in enumerate(zip(self.members, self.seeds))],
                         ignore_index=True)


@dataclass
class TrainResult:
    """Outcome of :func:`train_lstm`.

    Attributes:
        predictor: the trained model with its normalisation (weights after the last epoch).
        history: one row per epoch, columns :data:`HISTORY_COLUMNS` (epoch counts from 1);
            ``seconds`` is NaN for the epochs a resumed run read from its checkpoint (the
            checkpoint keeps no wall times, so its bytes repeat).
        val_rmse_m: per-coordinate validation RMSE in metres after the last epoch.
    """

    predictor: LSTMPredictor
    history: pd.DataFrame
    val_rmse_m: float


def _difference(pred, truth, who: str) -> np.ndarray:
    """pred - truth for (N, 2) real arrays (NaN propagates, inf is refused)."""
    p = check_array(pred, "pred", ("N", 2), error=MetricShapeError, who=who, allow_nan=True)
    t = check_array(truth, "truth", (len(p), 2), error=MetricShapeError, who=who, allow_nan=True)
    return p - t


def rmse_per_coordinate(pred: np.ndarray, truth: np.ndarray) -> float:
    """sqrt(mean of squared error over all points and both coordinates); (N, 2) inputs, metres.
    Raises MetricShapeError for inputs that are not real (N, 2) arrays of one shape, or inf."""
    d = _difference(pred, truth, "rmse_per_coordinate")
    return float(np.sqrt(np.mean(d**2)))


def rmse_euclidean(pred: np.ndarray, truth: np.ndarray) -> float:
    """sqrt(mean over points of the squared Euclidean error); (N, 2) inputs, metres.
    Raises MetricShapeError as :func:`rmse_per_coordinate`."""
    d = _difference(pred, truth, "rmse_euclidean")
    return float(np.sqrt(np.mean(np.sum(d**2, axis=-1))))


def evaluate(predictor: LSTMPredictor, ws: WindowSet, batch_size: int = 4096) -> dict[str, float]:
    """One-step errors of ``predictor`` on ``ws``: {"rmse_m", "rmse_euclid_m"} (NaN if empty)."""
    if len(ws) == 0:
        return {"rmse_m": float("nan"), "rmse_euclid_m": float("nan")}
    x = torch.from_numpy(ws.x)
    pred = torch.cat([predictor.step(x[i : i + batch_size]) for i in range(0, len(ws), batch_size)]).numpy()
    return {"rmse_m": rmse_per_coordinate(pred, ws.y), "rmse_euclid_m": rmse_euclidean(pred, ws.y)}


def rollout_errors(predictor, ws: WindowSet, horizon: int) -> dict[str, float]:
    """Multi-step errors of a rollout from each window of ``ws`` whose next ``horizon`` points
    the set holds (:meth:`WindowSet.futures`): {"ade_m", "fde_m", "n_windows"}.

    The same measure as the evaluation's ADE/FDE (``blindspot.traj.metrics``), on windows instead
    of the scenes, so a model can be selected on its validation split by the error a path
    prediction makes (the hyper-parameter search's objective) rather than by the one-step RMSE.

    Args:
        predictor: anything with ``predict(history (B, T, 2), horizon) -> (B, H, 2)`` (the LSTM,
            constant velocity, Kalman).
        ws: windows (N, W, 2) with their start indices.
        horizon: H >= 1 future points (frames).

    Returns:
        ADE and FDE in metres (NaN when no window has a whole future) and the windows used.

    Raises:
        WindowError: from :meth:`WindowSet.futures`.
    """
    index, future = ws.futures(horizon)
    if len(index) == 0:
        return {"ade_m": float("nan"), "fde_m": float("nan"), "n_windows": 0}
    pred = predictor.predict(ws.x[index].astype(np.float64), horizon)
    return {"ade_m": ade(pred, future), "fde_m": fde(pred, future), "n_windows": int(len(index))}


def _check_windows(ws: WindowSet, window: int, what: str) -> None:
    if not isinstance(ws, WindowSet):
        raise TypeError(f"{what}: expected a WindowSet, found {type(ws).__name__}")
    if ws.window != window:
        raise ValueError(f"{what}: windows have {ws.window} points but model.window is {window}")
    if not (np.isfinite(ws.x).all() and np.isfinite(ws.y).all()):
        raise ValueError(f"{what}: windows contain NaN/inf; build them with nan_policy='drop' or fill gaps first")


def _fingerprint(train: WindowSet, val: WindowSet) -> str:
    h = hashlib.blake2b(digest_size=16)
    for arr in (train.x, train.y, val.x, val.y):
        h.update(str(arr.shape).encode())
        h.update(np.ascontiguousarray(arr).tobytes())
    return h.hexdigest()


def _weights_fingerprint(predictor: LSTMPredictor | None) -> str | None:
    """A digest of a starting network's weights (None: a fresh initialisation)."""
    if predictor is None:
        return None
    h = hashlib.blake2b(digest_size=16)
    for name, tensor in predictor.members[0][0].state_dict().items():
        h.update(name.encode())
        h.update(tensor.detach().contiguous().numpy().tobytes())
    return h.hexdigest()


def _resume_key(model_cfg: LSTMConfig, train_cfg: TrainConfig, fingerprint: str,
                init: str | None = None) -> dict[str, Any]:
    """What must match between a checkpoint and the run resuming it (epochs may grow, unless the
    learning-rate schedule depends on them)."""
    tc = asdict(train_cfg)
    for key in ("resume", "ensemble", "jobs", "val_horizon_frames"):  # not what a network learns
        tc.pop(key)
    if train_cfg.lr_schedule == "constant":
        tc.pop("epochs")
    key = {"model": asdict(model_cfg), "train": tc, "data": fingerprint}
    if init is not None:   # absent for a fresh start, so older checkpoints keep their key
        key["init"] = init
    return key


def _atomic_torch_save(obj: Any, path: Path) -> None:
    # io.atomic_path's temporary file has the target's own name (in a hidden folder): torch
    # names the archive's records after the file, so a random temporary name would change the
    # checkpoint's bytes on every save. Written at once even inside the stage runner's
    # io.all_or_none: the resume checkpoint must outlive a killed run
    with write_now(), atomic_path(path) as tmp:
        torch.save(obj, tmp)


def _make_optimizer(model: nn.Module, cfg: TrainConfig) -> torch.optim.Optimizer:
    cls = torch.optim.Adam if cfg.optimizer == "adam" else torch.optim.AdamW
    return cls(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)


def train_lstm(
    train: WindowSet,
    val: WindowSet,
    model_cfg: LSTMConfig,
    train_cfg: TrainConfig,
    *,
    on_epoch: Callable[[int, dict[str, float]], None] | None = None,
    checkpoint_dir: str | Path | None = None,
    resume: bool = False,
    progress: bool = True,
    init_from: LSTMPredictor | None = None,
) -> TrainResult:
    """Train an :class:`LSTMRegressor` on ``train`` and report one-step errors on ``val``.

    Args:
        train, val: windows of ``model_cfg.window`` points (val may be empty: NaN metrics).
        model_cfg, train_cfg: settings.
        on_epoch: called as ``on_epoch(epoch, metrics)`` after each epoch (epoch counts from 1,
            metrics = that history row without "epoch"), after its checkpoint is written.
        checkpoint_dir: write ``<dir>/last.pt`` after every epoch (temp name, then rename).
        resume: continue from ``<dir>/last.pt`` if it exists (else start fresh); the checkpoint
            must come from the same model config, training config (except ``epochs`` with a
            constant learning rate) and data, otherwise ValueError.
        progress: show tqdm bars.
        init_from: fine-tune: start from this predictor's (first) network and its
            normalisation instead of a fresh initialisation (e.g. pre-trained on ETH/UCY,
            :mod:`blindspot.traj.pretrain`); its model config must equal ``model_cfg``. The
            optimiser starts afresh. Part of the resume key, so a checkpoint is only resumed from
            the same starting weights.

    Returns:
        :class:`TrainResult`.

    Raises:
        ValueError: mismatched windows, no training windows, ``resume`` without a checkpoint
            folder, a checkpoint from another run, or ``init_from`` of another model config.
    """
    _check_windows(train, model_cfg.window, "train")
    _check_windows(val, model_cfg.window, "val")
    if len(train) == 0:
        raise ValueError("train: no windows")
    if resume and checkpoint_dir is None:
        raise ValueError("resume=True needs checkpoint_dir")
    if init_from is not None and asdict(init_from.config) != asdict(model_cfg):
        diff = [k for k, v in asdict(model_cfg).items() if asdict(init_from.config).get(k) != v]
        raise ValueError(f"init_from: the starting network's model config differs from model_cfg "
                         f"in {', '.join(diff)}; fine-tuning needs the same architecture")
    ckpt_path = None if checkpoint_dir is None else Path(checkpoint_dir) / CHECKPOINT_NAME
    if ckpt_path is not None:
        ckpt_path.parent.mkdir(parents=True, exist_ok=True)

    prev_det = torch.are_deterministic_algorithms_enabled()
    try:
        with torch_threads(train_cfg.num_threads):
            torch.use_deterministic_algorithms(True)
            return _train(train, val, model_cfg, train_cfg, on_epoch, ckpt_path, resume,
                          progress, init_from)
    finally:
        torch.use_deterministic_algorithms(prev_det)


@contextmanager
def torch_threads(n: int | None) -> Iterator[None]:
    """torch's intra-op pool at ``n`` threads inside the block, the previous count restored
    after it (None: leave it as it is).

    The scoring after a training (:func:`evaluate`, :func:`rollout_errors` of the ensemble)
    runs under ``train.num_threads`` too: the networks are small (64 hidden units, batches of
    a few thousand windows), where a second OpenMP thread mostly spins. Measured on this
    project's 2-core machine with the paper-profile ensemble on its 3,895 val + test windows
    (``benchmarks/bench_train.py --eval``): the 20-step rollouts take several times the CPU
    time with torch's default 2 threads as with 1, for the same bits.
    Raises ValueError for ``n`` < 1."""
    if n is None:
        yield
        return
    if int(n) < 1:
        raise ValueError(f"torch_threads: expected a thread count >= 1 or None, found {n!r}")
    previous = torch.get_num_threads()
    torch.set_num_threads(int(n))
    try:
        yield
    finally:
        torch.set_num_threads(previous)


def train_ensemble(
    train: WindowSet,
    val: WindowSet,
    model_cfg: LSTMConfig,
    train_cfg: TrainConfig,
    *,
    on_epoch: Callable[[int, dict[str, float]], None] | None = None,
    checkpoint_dir: str | Path | None = None,
    resume: bool = False,
    progress: bool = True,
) -> EnsembleResult:
    """Train ``train_cfg.ensemble`` networks with seeds ``seed + i`` and average them.

    Each member is exactly :func:`train_lstm` with its own seed, so member ``i`` has the same
    weights whether trained alone, in sequence or in a worker process (with ``train_cfg.jobs``
    > 1 one process per member, one torch thread each as ``num_threads`` says, all confined to
    ``jobs`` CPUs). Checkpoints go to
    ``checkpoint_dir/member<i>/`` (``checkpoint_dir`` itself for a single network).
    ``on_epoch(epoch, metrics)`` is called live in this process only (``jobs == 1``); metric
    names carry a ``member<i>.`` prefix when there are several members.
    """
    from blindspot.parallel import parallel_map

    n = int(train_cfg.ensemble)
    seeds = [int(train_cfg.seed) + i for i in range(n)]
    ckpt = None if checkpoint_dir is None else Path(checkpoint_dir)
    members = [(replace(train_cfg, seed=seeds[i]),
                None if ckpt is None else (ckpt if n == 1 else ckpt / f"member{i}")) for i in range(n)]
    if n == 1 or train_cfg.jobs <= 1:
        def callback(i: int):
            if on_epoch is None or n == 1:
                return on_epoch
            return lambda e, m: on_epoch(e, {f"member{i}.{k}": v for k, v in m.items()})
        results = [train_lstm(train, val, model_cfg, cfg, on_epoch=callback(i), checkpoint_dir=d,
                              resume=resume, progress=progress) for i, (cfg, d) in enumerate(members)]
    else:
        # every member in its own single-threaded process, the processes confined to ``jobs``
        # CPUs: they time-share the cores and end together (five members on two cores: 2.5
        # member-times, where rounds of two take 3 with one core idle in the last round)
        results = parallel_map(partial(_train_member, train, val, model_cfg, resume), members,
                               n, progress="ensemble" if progress else None,
                               cpus=int(train_cfg.jobs))
    return EnsembleResult(LSTMPredictor.ensemble([r.predictor for r in results]), results, seeds)


def _train_member(train: WindowSet, val: WindowSet, model_cfg: LSTMConfig, resume: bool,
                  member: tuple[TrainConfig, Path | None]) -> TrainResult:
    """One ensemble member in a worker process (module level, so it pickles)."""
    cfg, checkpoint_dir = member
    return train_lstm(train, val, model_cfg, cfg, checkpoint_dir=checkpoint_dir, resume=resume,
                      progress=False)


def _train(
    train: WindowSet,
    val: WindowSet,
    model_cfg: LSTMConfig,
    cfg: TrainConfig,
    on_epoch: Callable[[int, dict[str, float]], None] | None,
    ckpt_path: Path | None,
    resume: bool,
    progress: bool,
    init_from: LSTMPredictor | None = None,
) -> TrainResult:
    torch.manual_seed(cfg.seed)
    model = LSTMRegressor(model_cfg)
    if init_from is None:
        stats = NormStats.fit(train.x, train.y, model_cfg)
    else:
        start_model, stats = init_from.members[0]
        model.load_state_dict(start_model.state_dict())
    optimizer = _make_optimizer(model, cfg)
    shuffle = torch.Generator().manual_seed(cfg.seed)
    key = (_resume_key(model_cfg, cfg, _fingerprint(train, val), _weights_fingerprint(init_from))
           if ckpt_path is not None else None)
    rows: list[dict[str, float]] = []
    first_epoch = 0

    if resume and ckpt_path is not None and ckpt_path.exists():
        ck = torch.load(ckpt_path, map_location="cpu", weights_only=True)
        if not isinstance(ck, dict) or ck.get("format") != _CKPT_FORMAT:
            raise ValueError(f"{ckpt_path}: not a training checkpoint (expected format {_CKPT_FORMAT!r})")
        if ck["key"] != key:
            diff = [k for k in {**ck["key"], **key} if ck["key"].get(k) != key.get(k)]
            raise ValueError(f"{ckpt_path}: checkpoint was made with a different {', '.join(diff)}; cannot resume")
        model.load_state_dict(ck["model"])
        optimizer.load_state_dict(ck["optimizer"])
        shuffle.set_state(ck["shuffle_rng"])
        torch.set_rng_state(ck["torch_rng"])
        rows = [dict(r) for r in ck["history"]]
        first_epoch = int(ck["epoch"])

    # translate in float64, then float32 for the network (a float32 UTM position is only good
    # to 0.5 m): training sees what inference feeds it (LSTMPredictor.step)
    x = torch.from_numpy(train.x.astype(np.float64))
    u_all = stats.encode(x).float()
    t_all = stats.encode_target(x, torch.from_numpy(train.y.astype(np.float64))).float()
    n = len(train)
    n_batches = math.ceil(n / cfg.batch_size)
    loss_fn = nn.MSELoss()
    predictor = LSTMPredictor(model, stats)

    epochs = tqdm(range(first_epoch, cfg.epochs), desc="train", unit="epoch", disable=not progress,
                  initial=first_epoch, total=cfg.epochs)
    for epoch in epochs:
        t0 = time.perf_counter()
        model.train()
        order = torch.randperm(n, generator=shuffle)
        loss_sum = 0.0
        for b in tqdm(range(n_batches), desc=f"epoch {epoch + 1}", leave=False, disable=not progress):
            idx = order[b * cfg.batch_size : (b + 1) * cfg.batch_size]
            if cfg.lr_schedule == "cosine":
                step = epoch * n_batches + b
                for group in optimizer.param_groups:
                    group["lr"] = cfg.lr * 0.5 * (1.0 + math.cos(math.pi * step / (cfg.epochs * n_batches)))
            optimizer.zero_grad(set_to_none=True)
            loss = loss_fn(model(u_all[idx]), t_all[idx])
            loss.backward()
            if cfg.grad_clip:
                nn.utils.clip_grad_norm_(model.parameters(), cfg.grad_clip)
            optimizer.step()
            loss_sum += float(loss.detach()) * idx.numel()
        model.eval()
        train_loss = loss_sum / n
        val_metrics = evaluate(predictor, val, cfg.eval_batch_size)
        row = {
            "epoch": epoch + 1,
            "train_loss": train_loss,
            # loss is a per-coordinate MSE in units of out_scale, so this is the RMSE in metres
            "train_rmse_m": math.sqrt(train_loss) * stats.out_scale,
            "val_rmse_m": val_metrics["rmse_m"],
            "val_rmse_euclid_m": val_metrics["rmse_euclid_m"],
            "seconds": time.perf_counter() - t0,
        }
        rows.append(row)
        epochs.set_postfix(train_rmse_m=f"{row['train_rmse_m']:.4f}", val_rmse_m=f"{row['val_rmse_m']:.4f}")
        if ckpt_path is not None:
            _atomic_torch_save(
                {
                    "format": _CKPT_FORMAT,
                    "key": key,
                    "epoch": epoch + 1,
                    "model": model.state_dict(),
                    "optimizer": optimizer.state_dict(),
                    "shuffle_rng": shuffle.get_state(),
                    "torch_rng": torch.get_rng_state(),
                    # without the wall times: the checkpoint's bytes repeat on a rerun
                    "history": [{k: v for k, v in r.items() if k != "seconds"} for r in rows],
                },
                ckpt_path,
            )
        if on_epoch is not None:
            on_epoch(epoch + 1, {k: v for k, v in row.items() if k != "epoch"})

    model.eval()
    history = pd.DataFrame(rows, columns=list(HISTORY_COLUMNS))
    val_rmse = float(history["val_rmse_m"].iloc[-1]) if len(history) else evaluate(predictor, val)["rmse_m"]
    return TrainResult(predictor=predictor, history=history, val_rmse_m=val_rmse)


# ----------------------------------------------------------------------------- the train stage's
def baseline_errors(predictor, ws: WindowSet, horizon: int) -> dict:
    """A baseline's one-step RMSE (per coordinate, Euclidean) and ``horizon``-frame rollout
    ADE/FDE on the windows ``ws``."""
    pred = predictor.predict(ws.x, 1)[:, 0]
    return {"rmse_m": rmse_per_coordinate(pred, ws.y), "rmse_euclid_m": rmse_euclidean(pred, ws.y),
            **rollout_errors(predictor, ws, horizon)}


def ensemble_scores(result: EnsembleResult, split: dict, baselines: dict, horizon: int,
                    workers: int = 1) -> dict:
    """train.json's errors: the ensemble's and each member's one-step errors, every
    predictor's ``horizon``-frame rollout ADE/FDE, on the val and test windows (the ensemble's
    rollouts on ``workers`` threads; the same bits for any number)."""
    lstm = result.predictor.with_workers(workers)
    return {
        "lstm": {**{s: {**evaluate(lstm, split[s]),
                        **rollout_errors(lstm, split[s], horizon)}
                    for s in ("val", "test")},
                 "n_members": len(result.members),
                 "members": [{"seed": seed,
                              "val": evaluate(m.predictor, split["val"]),
                              "test": evaluate(m.predictor, split["test"])}
                             for seed, m in zip(result.seeds, result.members)]},
        **{name: {s: baseline_errors(p, split[s], horizon) for s in ("val", "test")}
           for name, p in baselines.items()},
        "val_horizon_frames": horizon,
        "n_windows": {s: len(w) for s, w in split.items()},
    }


def member_steps(result: EnsembleResult) -> Iterator[tuple[dict, int]]:
    """(metrics, epoch) of every member's history, ``member<i>.<key>``: what members trained in
    worker processes could not log live."""
    for i, member in enumerate(result.members):
        for row in member.history.to_dict("records"):
            yield {f"member{i}.{k}": v for k, v in row.items() if k != "epoch"}, int(row["epoch"])


def logged_scores(metrics: dict, result: EnsembleResult) -> dict:
    """:func:`ensemble_scores` as MLflow metrics: members by seed, the paper's values left out,
    the mean seconds per epoch added."""
    logged = {k: v for k, v in metrics.items() if k != "paper"}
    logged["lstm"] = {**{k: v for k, v in metrics["lstm"].items() if k != "members"},
                      **{f"seed{m['seed']}": {"val": m["val"], "test": m["test"]}
                         for m in metrics["lstm"]["members"]},
                      "seconds_per_epoch": float(result.history.seconds.mean())}
    return logged


def scores_line(metrics: dict, baselines, paper_val_rmse: float) -> str:
    """One line of :func:`ensemble_scores` for the log."""
    val = {name: metrics[name]["val"] for name in ("lstm", *baselines)}
    return (f"train: val RMSE {val['lstm']['rmse_m']:.4f} m (paper {paper_val_rmse}), "
            f"test {metrics['lstm']['test']['rmse_m']:.4f} m; constant velocity val "
            f"{val['constant_velocity']['rmse_m']:.4f} m, Kalman {val['kalman']['rmse_m']:.4f} m; "
            f"val ADE/FDE over {metrics['val_horizon_frames']} frames: "
            + ", ".join(f"{k} {v['ade_m']:.3f}/{v['fde_m']:.3f} m" for k, v in val.items()))
