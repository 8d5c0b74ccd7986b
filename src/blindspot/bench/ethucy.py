"""ETH/UCY benchmark from the command line: CVM, Kalman and the learned predictors under the
standard protocol.

    python -m blindspot.bench.ethucy --data DIR --out FILE.json [--report FILE.md]
        [--models cvm,kalman,lstm,gru,mlp] [--folds eth,hotel,...] [--epochs N] [--ensemble K]
        [--calibration mle|quantile|mixture|conditional] [--quiet]

``--epochs``, ``--ensemble``, ``--seed``, ``--threads`` apply to every learned model (the direct
predictors ``lstm``/``gru``/``mlp``, whose other settings are ``Seq2SeqConfig``'s defaults, and the
next-point ``lstm_rollout``, configured by the remaining flags).

The protocol is :mod:`blindspot.traj.ethucy_protocol` (the pipeline's ``ethucy`` stage calls it
with the settings of ``conf/ethucy/``); the page is :mod:`blindspot.report.ethucy_report`. This
command parses the flags into :class:`~blindspot.traj.ethucy_protocol.EthUcySettings`, runs the
benchmark, writes the JSON ``{model: {fold: {"ade", "fde", "n_windows"}, ..., "avg": {"ade",
"fde"}}}`` and, with ``--report``, the Markdown page (both atomically), and prints the table.
Exit status 2 for a bad flag value or a missing or malformed data folder.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path

from blindspot.io import write_json, write_text
from blindspot.report.ethucy_report import format_report, format_table
from blindspot.traj.ethucy import FOLDS, EthUcyDataError, default_data_dir
from blindspot.traj.config import Seq2SeqConfig
from blindspot.traj.ethucy_protocol import MODELS, EthUcySettings, LSTMBenchSettings, run_benchmark


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
    p.add_argument("--calibration", choices=("mle", "quantile", "mixture", "conditional"),
                   default="conditional",
                   help="calibration fitted on val: per-step scale (mle, quantile) or scale mixture")
    p.add_argument("--neighbours", type=int, default=Seq2SeqConfig.neighbours,
                   help="nearest pedestrians the direct predictors read as context (0 = none)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    return p


def settings_from_args(args: argparse.Namespace) -> EthUcySettings:
    """The benchmark settings the parsed flags ask for (ValueError for a refused combination)."""
    lstm = LSTMBenchSettings(hidden_size=args.hidden_size, num_layers=args.num_layers,
                             head_hidden=args.head_hidden, target=args.target,
                             epochs=args.epochs, batch_size=args.batch_size, lr=args.lr,
                             seed=args.seed, frame=args.frame, residual=args.residual,
                             mirror=args.mirror, speed_floor=args.speed_floor,
                             rotations=args.rotations, ensemble=args.ensemble,
                             num_threads=args.threads)
    s2s = Seq2SeqConfig(epochs=args.epochs, ensemble=args.ensemble, seed=args.seed,
                        threads=args.threads if args.threads is not None else 1,
                        neighbours=args.neighbours)
    data_dir = args.data if args.data is not None else default_data_dir()
    return EthUcySettings(data_dir=data_dir, models=tuple(args.models), folds=tuple(args.folds),
                          lstm=lstm, seq2seq=s2s, calibration=args.calibration)


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        settings = settings_from_args(args)
    except ValueError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if not settings.data_dir.is_dir():
        print(f"error: --data {settings.data_dir}: no such folder (expected the ETH/UCY folder "
              f"holding {', '.join(FOLDS)})", file=sys.stderr)
        return 2
    try:
        run = run_benchmark(settings, progress=not args.quiet)
    except EthUcyDataError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    write_json(args.out, run.results)
    print(format_table(run.results, settings.folds))
    if args.report is not None:
        command = "python -m blindspot.bench.ethucy " + " ".join(
            str(a) for a in (argv if argv is not None else sys.argv[1:]))
        from blindspot.traj.ethucy_protocol import calibration_table

        lstm = asdict(settings.lstm) if "lstm_rollout" in settings.models else None
        write_text(args.report, format_report(
            run.results, run.validation(), run.details(), settings.folds, lstm, command,
            run.seconds, seq2seq=asdict(settings.seq2seq),
            calibration=calibration_table(run.per_fold),
            calibration_method=settings.calibration))
    print(f"wrote {args.out}" + (f" and {args.report}" if args.report else "")
          + f" in {run.seconds:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
