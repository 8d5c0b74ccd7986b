"""ethucy: the standard ETH/UCY benchmark (observe 8, predict 12) for CVM, Kalman and the LSTM.

The protocol of blindspot.traj.ethucy_benchmark with the settings of cfg.ethucy (conf/ethucy/);
the same as `python -m blindspot.bench.ethucy` with the matching flags. Writes
reports/metrics/ethucy.json and the page reports/ethucy.md.
"""

from dataclasses import asdict

from blindspot import experiment, tracking
from blindspot.cli import main_stage
from blindspot.config import shared_dir
from blindspot.io import write_json, write_text
from blindspot.report.ethucy_report import format_report
from blindspot.traj.ethucy_benchmark import EthUcySettings, run_benchmark


def run(cfg):
    settings = EthUcySettings.from_mapping(cfg.ethucy, shared_dir=shared_dir(cfg), seed=int(cfg.seed))
    bench = run_benchmark(settings, progress=bool(cfg.progress))
    write_json(experiment.reports_path(cfg, "metrics", "ethucy.json"), bench.results)
    lstm = asdict(settings.lstm) if "lstm" in settings.models else None
    report = write_text(experiment.reports_path(cfg, "ethucy.md"), format_report(
        bench.results, bench.validation(), bench.details(), settings.folds, lstm,
        "python -m blindspot ethucy", bench.seconds))
    tracker = tracking.current()
    tracker.log_metrics({m: r["avg"] for m, r in bench.results.items()})
    tracker.log_artifact(report)


if __name__ == "__main__":
    main_stage(run, "ethucy")
