"""ethucy: the standard ETH/UCY benchmark (observe 8, predict 12) for CVM, Kalman and the LSTM.

The same as `python -m blindspot.bench.ethucy --data ... --out reports/metrics/ethucy.json
--report reports/ethucy.md`, with the settings from cfg.ethucy (conf/ethucy/).
"""

from blindspot.bench import ethucy as bench
from blindspot import experiment
from blindspot.cli import main_stage
from blindspot.config import shared_dir
from blindspot.stage import StageResult


def run(cfg, ctx):
    e = experiment.ethucy(cfg)
    out = ctx.out("ethucy.json")
    report = ctx.out("ethucy.md")
    argv = ["--data", str(shared_dir(cfg) / e.data), "--out", str(out), "--report", str(report),
            "--models", ",".join(e.models), "--folds", ",".join(e.folds),
            "--epochs", str(e.epochs), "--ensemble", str(e.ensemble), "--threads", str(e.threads),
            "--seed", str(cfg.seed)]
    if not cfg.progress:
        argv.append("--quiet")
    status = bench.main(argv)
    if status:
        raise SystemExit(status)
    import json

    results = json.loads(out.read_text())
    return StageResult(metrics={m: r["avg"] for m, r in results.items()}, artifacts=[report])


if __name__ == "__main__":
    main_stage(run, "ethucy")
