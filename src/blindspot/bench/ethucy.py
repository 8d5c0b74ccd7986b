"""ETH/UCY benchmark: CVM, Kalman and the LSTM under the standard protocol.

    python -m blindspot.bench.ethucy --data DIR --out FILE.json [--report FILE.md]
        [--models cvm,kalman,lstm] [--folds eth,hotel,...] [--epochs N] [--quiet]

Protocol (see ``blindspot.traj.ethucy``): observe 8 positions (3.2 s), predict 12 (4.8 s),
leave-one-scene-out folds eth/hotel/univ/zara1/zara2, Social-GAN windows; every model that learns
anything learns it from its fold's ``train`` split (and ``val`` for the LSTM's validation) only.

* ``cvm``: constant velocity from the last two observed positions (Schöller et al. 2020).
* ``kalman``: constant-velocity Kalman filter, process noise fitted on the fold's train windows
  to minimise their 8 -> 12 ADE (``KalmanCV.fit(objective="forecast")``).
* ``lstm``: the project's next-point LSTM with a window of 8, trained on every fully observed
  9-frame stretch (8 in, 1 out) of the fold's train split, optionally augmented by random
  rotations, validated on the val split, rolled out 12 steps.

Writes JSON ``{model: {fold: {"ade", "fde", "n_windows"}, ..., "avg": {"ade", "fde"}}}`` (avg =
unweighted mean over the folds run, as in the literature) and a Markdown table with the published
numbers beside ours.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from blindspot.traj.baselines import ConstantVelocity, KalmanCV
from blindspot.traj.ethucy import (
    FOLDS,
    OBS_LEN,
    PRED_LEN,
    PUBLISHED,
    EthUcyDataError,
    Windows,
    default_data_dir,
    load_split,
    random_rotations,
)
from blindspot.traj.metrics import ade, fde
from blindspot.traj.predictor import (
    HeadingFrameRollout,
    MeanNextPoint,
    NextPointRollout,
    PathPredictor,
    heading_frame_pairs,
)

MODELS: tuple[str, ...] = ("cvm", "kalman", "lstm")


@dataclass(frozen=True)
class LSTMBenchSettings:
    """LSTM settings for the benchmark (passed to ``LSTMConfig`` / ``TrainConfig``).

    Attributes:
        hidden_size, num_layers, head_hidden, target: model (window is fixed to 8).
        epochs, batch_size, lr, seed: training.
        frame: ``"heading"`` - every window is expressed in its own heading frame (origin at the
            last point, +x along the last step) for training and for each rollout step
            (:class:`~blindspot.traj.predictor.HeadingFrameRollout`); ``"world"`` - the LSTM
            sees world coordinates (its own translation to the last point still applies).
        residual: (heading frame) the LSTM predicts the correction to constant velocity.
        mirror: (heading frame) train on mirrored copies too and average the prediction with
            the mirrored window's (left/right symmetry).
        speed_floor: (heading frame) also scale each window by its last step length, floored
            at this many metres (None = no scaling): the LSTM then sees the shape of the motion
            independent of walking speed.
        rotations: (world frame) random-rotation copies added per training window.
        ensemble: train this many LSTMs with seeds ``seed, seed + 1, ...`` and
            average their next-point predictions at every rollout step.
        num_threads: torch threads (None = leave torch's default).
    """

    hidden_size: int = 64
    num_layers: int = 1
    head_hidden: int = 32
    target: str = "displacement"
    epochs: int = 8
    batch_size: int = 256
    lr: float = 1e-3
    seed: int = 0
    frame: str = "heading"
    residual: bool = True
    mirror: bool = True
    speed_floor: float | None = None
    rotations: int = 0
    ensemble: int = 5
    num_threads: int | None = None

    def __post_init__(self) -> None:
        if self.frame not in ("heading", "world"):
            raise ValueError(f"lstm frame: expected 'heading' or 'world', found {self.frame!r}")
        if self.frame == "heading" and self.rotations:
            raise ValueError("lstm rotations: random rotations do nothing in the heading frame "
                             "(it is rotation invariant); use frame='world' or rotations=0")
        if int(self.ensemble) != self.ensemble or self.ensemble < 1:
            raise ValueError(f"lstm ensemble: expected an integer >= 1, found {self.ensemble!r}")


@dataclass
class FoldOutcome:
    """Scores of one model on one fold plus what was fitted (for the report)."""

    ade: float
    fde: float
    n_windows: int
    seconds: float
    fitted: dict[str, Any] = field(default_factory=dict)


def score(predictor: PathPredictor, test: Windows, obs_len: int = OBS_LEN,
          pred_len: int = PRED_LEN) -> tuple[float, float]:
    """ADE and FDE (m) of ``predictor`` on test windows (N, obs_len + pred_len, 2)."""
    pred = predictor.predict(test.observed(obs_len), pred_len)
    truth = test.future(obs_len)
    return ade(pred, truth), fde(pred, truth)


def lstm_window_set(data_dir: Path, fold: str, split: str, s: LSTMBenchSettings, *,
                    augment: bool = True):
    """Next-point windows (8 in -> 1 out) of a fold's split as a ``WindowSet``.

    Every fully observed 9-frame stretch of every pedestrian (no minimum-neighbour filter: the
    LSTM sees one pedestrian at a time). In the heading frame the pairs come from
    :func:`~blindspot.traj.predictor.heading_frame_pairs` (mirrored copies when ``augment`` and
    ``s.mirror``); in the world frame ``s.rotations`` random rotations are added when
    ``augment``.
    """
    from blindspot.traj.windows import WindowSet

    w = load_split(data_dir, fold, split, seq_len=OBS_LEN + 1, min_peds=1)
    xy, pid = w.xy, w.track_id
    if s.frame == "heading":
        mirror = augment and s.mirror
        x, y = heading_frame_pairs(xy, residual=s.residual, mirror=mirror,
                                   speed_floor=s.speed_floor)
        return WindowSet(x=x, y=y, path_id=np.tile(pid, 2) if mirror else pid)
    if augment and s.rotations:
        xy = np.concatenate([xy, random_rotations(xy, s.rotations, np.random.default_rng(s.seed))])
        pid = np.tile(pid, s.rotations + 1)
    return WindowSet(x=xy[:, :OBS_LEN], y=xy[:, OBS_LEN], path_id=pid)


def train_fold_lstm(data_dir: Path, fold: str, s: LSTMBenchSettings, progress: bool
                    ) -> tuple[PathPredictor, float, int, int]:
    """Train the LSTM on a fold's train split (validated on its val split).

    Returns:
        ``(predictor, val_rmse_m, n_train, n_val)``: the predictor to score (the LSTM itself,
        or the LSTM / ensemble mean wrapped in a rollout), the one-step
        validation RMSE in metres per coordinate (mean over ensemble members), and the window
        counts.
    """
    from blindspot.traj.lstm import LSTMConfig
    from blindspot.traj.train import TrainConfig, train_lstm

    train = lstm_window_set(data_dir, fold, "train", s)
    val = lstm_window_set(data_dir, fold, "val", s, augment=False)
    model_cfg = LSTMConfig(window=OBS_LEN, hidden_size=s.hidden_size, num_layers=s.num_layers,
                           head_hidden=s.head_hidden, target=s.target)
    train_cfg = TrainConfig(epochs=s.epochs, batch_size=s.batch_size, lr=s.lr, seed=s.seed,
                            num_threads=s.num_threads)
    results = [train_lstm(train, val, model_cfg, replace(train_cfg, seed=s.seed + k),
                          progress=progress) for k in range(s.ensemble)]
    val_rmse = float(np.mean([r.val_rmse_m for r in results]))
    model = (results[0].predictor if s.ensemble == 1
             else MeanNextPoint([r.predictor for r in results]))
    predictor: PathPredictor
    if s.frame == "heading":
        predictor = HeadingFrameRollout(model, residual=s.residual, symmetric=s.mirror,
                                        speed_floor=s.speed_floor, name="lstm")
    elif s.ensemble == 1:
        predictor = results[0].predictor      # the LSTM's own rollout (fills gaps itself)
    else:
        predictor = NextPointRollout(model, name="lstm")
    return predictor, val_rmse, len(train), len(val)


def val_windows(data_dir: Path, fold: str) -> Windows:
    """The fold's val split under the test protocol (20-frame Social-GAN windows)."""
    return load_split(data_dir, fold, "val")


def run_fold(data_dir: Path, fold: str, models: Sequence[str], lstm: LSTMBenchSettings,
             progress: bool = True) -> dict[str, FoldOutcome]:
    """Evaluate the requested models on one fold."""
    test = load_split(data_dir, fold, "test")
    out: dict[str, FoldOutcome] = {}
    for name in models:
        t0 = time.perf_counter()
        fitted: dict[str, Any] = {}
        if name == "cvm":
            predictor: PathPredictor = ConstantVelocity()
        elif name == "kalman":
            train = load_split(data_dir, fold, "train")
            predictor = KalmanCV().fit(train.xy, objective="forecast", obs_len=OBS_LEN)
            fitted = {"process_psd_m2_s3": predictor.process_psd, "meas_std_m": predictor.meas_std}
        elif name == "lstm":
            predictor, val_rmse, n_train, n_val = train_fold_lstm(data_dir, fold, lstm, progress)
            val_ade, val_fde = score(predictor, val_windows(data_dir, fold))
            fitted = {"val_rmse_m": val_rmse, "val_ade_m": val_ade, "val_fde_m": val_fde,
                      "n_train_windows": n_train, "n_val_windows": n_val}
        else:  # guarded by parse_models
            raise ValueError(f"unknown model {name!r}")
        a, f = score(predictor, test)
        if "val_ade_m" not in fitted:
            fitted["val_ade_m"], fitted["val_fde_m"] = score(predictor, val_windows(data_dir, fold))
        out[name] = FoldOutcome(a, f, len(test), time.perf_counter() - t0, fitted)
    return out


def summarise(per_fold: dict[str, dict[str, FoldOutcome]], models: Sequence[str]
              ) -> dict[str, dict[str, dict[str, float]]]:
    """JSON-ready ``{model: {fold: {ade, fde, n_windows}, "avg": {ade, fde}}}``."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for m in models:
        rows = {fold: {"ade": r[m].ade, "fde": r[m].fde, "n_windows": r[m].n_windows}
                for fold, r in per_fold.items()}
        rows["avg"] = {"ade": float(np.mean([v["ade"] for v in rows.values()])),
                       "fde": float(np.mean([v["fde"] for v in rows.values()]))}
        out[m] = rows
    return out


def _cell(d: dict[str, float] | None) -> str:
    return "-" if d is None else f"{d['ade']:.2f} / {d['fde']:.2f}"


def format_table(results: dict[str, dict[str, dict[str, float]]], folds: Sequence[str],
                 published: bool = True) -> str:
    """Markdown table of ADE / FDE (m) per fold and average, ours then published."""
    cols = [*folds, "avg"]
    lines = ["| model | " + " | ".join(cols) + " |", "|---|" + "---|" * len(cols)]
    for m, rows in results.items():
        lines.append(f"| {m} (ours) | " + " | ".join(_cell(rows.get(c)) for c in cols) + " |")
    if published:
        for m, rows in PUBLISHED.items():
            lines.append(f"| published: {m} | " + " | ".join(_cell(rows.get(c)) for c in cols)
                         + " |")
    return "\n".join(lines)


def compare_to_cvm(results: dict[str, dict[str, dict[str, float]]]) -> list[str]:
    """Report lines: each model's average ADE/FDE minus the CVM's (negative = better)."""
    if "cvm" not in results:
        return []
    base = results["cvm"]["avg"]
    lines = []
    for m, rows in results.items():
        if m == "cvm":
            continue
        d_ade, d_fde = rows["avg"]["ade"] - base["ade"], rows["avg"]["fde"] - base["fde"]
        verdict = ("beats" if d_ade < 0 and d_fde < 0 else
                   "does not beat" if d_ade >= 0 and d_fde >= 0 else "splits with")
        lines.append(f"- {m} {verdict} CVM on the test-fold average: ADE {d_ade:+.3f} m, "
                     f"FDE {d_fde:+.3f} m.")
    return lines + [""] if lines else []


def format_report(results, per_fold, folds, lstm: LSTMBenchSettings | None, command: str,
                  seconds: float) -> str:
    """The Markdown page: table, protocol, fitted values, command."""
    parts = [
        "# ETH/UCY benchmark",
        "",
        "ADE / FDE in metres (observe 8 = 3.2 s, predict 12 = 4.8 s; leave-one-scene-out; "
        "Social-GAN windows; single deterministic prediction). `avg` is the unweighted mean of "
        "the folds.",
        "",
        format_table(results, folds),
        "",
        "Test windows per fold: "
        + ", ".join(f"{f} {next(iter(per_fold[f].values())).n_windows}" for f in folds) + ".",
        "",
        *compare_to_cvm(results),
        "## Models",
        "",
    ]
    if "cvm" in results:
        parts.append("- **cvm**: constant velocity from the last two observed positions, "
                     "`x_t - x_(t-1)` (Schöller et al. 2020).")
    if "kalman" in results:
        parts.append("- **kalman**: constant-velocity Kalman filter (white-noise acceleration, "
                     "dt = 0.4 s), process noise fitted per fold on that fold's train windows "
                     "to minimise their ADE.")
    if "kalman" in results:
        fitted = ", ".join(f"{f} {per_fold[f]['kalman'].fitted['process_psd_m2_s3']:.3g}"
                           for f in folds)
        parts.append(f"  Fitted process noise q (m^2/s^3), meas_std 0.05 m: {fitted}.")
    if lstm is not None and "lstm" in results:
        parts += [
            "- **lstm**: the project's next-point LSTM (window 8), trained per fold on every "
            "fully observed 9-frame stretch of the train split, validated on the val split, "
            "rolled out 12 steps autoregressively"
            + (" in each window's heading frame (origin at the last point, +x along the last "
               "step; recomputed at every rollout step)" if lstm.frame == "heading" else "")
            + (", predicting the correction to constant velocity" if lstm.frame == "heading"
               and lstm.residual else "")
            + (", mirrored copies in training and left/right-symmetrised predictions"
               if lstm.frame == "heading" and lstm.mirror else "")
            + (f", windows scaled by their last step (floor {lstm.speed_floor} m)"
               if lstm.frame == "heading" and lstm.speed_floor else "")
            + (f"; the mean of {lstm.ensemble} LSTMs trained with consecutive seeds"
               if lstm.ensemble > 1 else "")
            + f". Settings: `{json.dumps(asdict(lstm))}`.",
            "  On each fold's val split (for model selection; never the test scene): one-step "
            "RMSE per coordinate (m) "
            + ", ".join(f"{f} {per_fold[f]['lstm'].fitted['val_rmse_m']:.4f}" for f in folds)
            + "; 12-step ADE / FDE (m) "
            + ", ".join(f"{f} {per_fold[f]['lstm'].fitted['val_ade_m']:.2f} / "
                        f"{per_fold[f]['lstm'].fitted['val_fde_m']:.2f}" for f in folds)
            + ".",
        ]
    val = {m: {f: {"ade": per_fold[f][m].fitted["val_ade_m"], "fde": per_fold[f][m].fitted["val_fde_m"]}
               for f in folds} for m in results}
    for rows in val.values():
        rows["avg"] = {k: float(np.mean([rows[f][k] for f in folds])) for k in ("ade", "fde")}
    parts += ["", "## Validation splits", "",
              "The same metrics on each fold's val split (parts of the training scenes, never "
              "the test scene): settings are to be chosen on these, not on the test table.",
              "", format_table(val, folds, published=False)]
    timing = ", ".join(f"{m} {sum(per_fold[f][m].seconds for f in folds):.0f} s" for m in results)
    parts += ["", "## Run", "", f"Command: `{command}`", "",
              f"Wall time {seconds:.0f} s ({timing}).", ""]
    return "\n".join(parts)


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to a temporary file next to ``path``, then rename it into place."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def parse_list(value: str, allowed: Sequence[str], option: str) -> list[str]:
    """Comma-separated choices, validated against ``allowed`` (order kept, duplicates dropped)."""
    items = [v.strip() for v in value.split(",") if v.strip()]
    bad = [v for v in items if v not in allowed]
    if bad or not items:
        raise argparse.ArgumentTypeError(f"{option}: expected a comma-separated subset of "
                                         f"{','.join(allowed)}, found {value!r}")
    return list(dict.fromkeys(items))


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m blindspot.bench.ethucy",
                                description="ETH/UCY ADE/FDE benchmark (observe 8, predict 12).")
    p.add_argument("--data", type=Path, default=None,
                   help="folder holding eth/ hotel/ univ/ zara1/ zara2/ "
                        "(default: $BLINDSPOT_SHARED/data/ethucy or <repo>/../shared/data/ethucy)")
    p.add_argument("--out", type=Path, required=True, help="JSON file to write")
    p.add_argument("--report", type=Path, default=None,
                   help="Markdown report to write (default: none)")
    p.add_argument("--models", default=",".join(MODELS),
                   type=lambda v: parse_list(v, MODELS, "--models"))
    p.add_argument("--folds", default=",".join(FOLDS),
                   type=lambda v: parse_list(v, FOLDS, "--folds"))
    d = LSTMBenchSettings()
    p.add_argument("--epochs", type=int, default=d.epochs, help="LSTM training epochs")
    p.add_argument("--batch-size", type=int, default=d.batch_size)
    p.add_argument("--lr", type=float, default=d.lr)
    p.add_argument("--hidden-size", type=int, default=d.hidden_size)
    p.add_argument("--num-layers", type=int, default=d.num_layers)
    p.add_argument("--head-hidden", type=int, default=d.head_hidden)
    p.add_argument("--target", choices=("displacement", "absolute"), default=d.target)
    p.add_argument("--frame", choices=("heading", "world"), default=d.frame,
                   help="coordinates the LSTM sees (heading: each window's own heading frame)")
    p.add_argument("--no-residual", dest="residual", action="store_false",
                   help="heading frame: predict the next point, not the correction to CVM")
    p.add_argument("--no-mirror", dest="mirror", action="store_false",
                   help="heading frame: no mirrored copies / symmetric averaging")
    p.add_argument("--speed-floor", type=float, default=d.speed_floor,
                   help="heading frame: scale windows by their last step (floor in m)")
    p.add_argument("--rotations", type=int, default=d.rotations,
                   help="world frame: random-rotation copies per training window")
    p.add_argument("--ensemble", type=int, default=d.ensemble,
                   help="average this many LSTMs (seeds seed, seed+1, ...) at every step")
    p.add_argument("--seed", type=int, default=d.seed)
    p.add_argument("--threads", type=int, default=None, help="torch threads for the LSTM")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    data_dir = args.data if args.data is not None else default_data_dir()
    if not data_dir.is_dir():
        print(f"error: --data {data_dir}: no such folder (expected the ETH/UCY folder holding "
              f"{', '.join(FOLDS)})", file=sys.stderr)
        return 2
    try:
        lstm = LSTMBenchSettings(hidden_size=args.hidden_size, num_layers=args.num_layers,
                                 head_hidden=args.head_hidden, target=args.target,
                                 epochs=args.epochs, batch_size=args.batch_size, lr=args.lr,
                                 seed=args.seed, frame=args.frame, residual=args.residual,
                                 mirror=args.mirror, speed_floor=args.speed_floor,
                                 rotations=args.rotations, ensemble=args.ensemble,
                                 num_threads=args.threads)
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    progress = not args.quiet
    t0 = time.perf_counter()
    per_fold: dict[str, dict[str, FoldOutcome]] = {}
    try:
        for fold in tqdm(args.folds, desc="ETH/UCY folds", unit="fold", disable=not progress):
            per_fold[fold] = run_fold(data_dir, fold, args.models, lstm, progress)
    except EthUcyDataError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    seconds = time.perf_counter() - t0
    results = summarise(per_fold, args.models)
    write_atomic(args.out, json.dumps(results, indent=2) + "\n")
    table = format_table(results, args.folds)
    print(table)
    if args.report is not None:
        command = "python -m blindspot.bench.ethucy " + " ".join(
            str(a) for a in (argv if argv is not None else sys.argv[1:]))
        write_atomic(args.report, format_report(results, per_fold, args.folds,
                                                lstm if "lstm" in args.models else None,
                                                command, seconds))
    print(f"wrote {args.out}" + (f" and {args.report}" if args.report else "")
          + f" in {seconds:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
