"""ethucy: the standard ETH/UCY benchmark (observe 8, predict 12) for CVM, Kalman and the LSTM.

The protocol of blindspot.traj.ethucy_benchmark with the settings of cfg.ethucy (conf/ethucy/);
the same as `python -m blindspot.bench.ethucy` with the matching flags. Writes
reports/metrics/ethucy.json and the page reports/ethucy.md.
"""

from dataclasses import asdict

from blindspot import experiment
from blindspot.cli import main_stage
from blindspot.config import shared_dir
from blindspot.io import write_json, write_text
from blindspot.report.ethucy_report import format_report
from blindspot.stage import StageResult
from blindspot.traj.ethucy_benchmark import EthUcySettings, run_benchmark


def run(cfg, ctx):
    settings = EthUcySettings.from_config(experiment.ethucy(cfg), shared_dir=shared_dir(cfg),
                                          seed=int(cfg.seed))
    bench = run_benchmark(settings, progress=bool(cfg.progress), jobs=int(cfg.jobs))
    write_json(ctx.out("ethucy.json"), bench.results)
    lstm = asdict(settings.lstm) if "lstm" in settings.models else None
    report = write_text(ctx.out("ethucy.md"), format_report(
        bench.results, bench.validation(), bench.details(), settings.folds, lstm,
        "python -m blindspot ethucy", bench.seconds))
    return StageResult(metrics={m: r["avg"] for m, r in bench.results.items()},
                       artifacts=[report])


if __name__ == "__main__":
    main_stage(run, "ethucy")
