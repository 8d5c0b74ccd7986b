"""ethucy: the standard ETH/UCY benchmark (observe 8, predict 12): CVM, Kalman and our learned
predictors, their ADE/FDE and the calibration of their predictive distributions.

The protocol of blindspot.traj.ethucy_protocol with the settings of cfg.ethucy (conf/ethucy/;
a subset with Hydra overrides: `python -m blindspot ethucy ethucy.models=[cvm] ethucy.folds=[eth]`).
Writes
reports/metrics/ethucy.json (ADE/FDE per model and fold, "best", "seeds", "best_of_20"),
reports/metrics/calibration_ethucy.json ({method: {fold: {coverage_50, coverage_90,
coverage_95, nll}}}, the ETH/UCY part of calibration.json), the reliability curves behind the
figure (reports/metrics/reliability_ethucy.json), the figure reports/figures/ethucy_reliability.png
and the page reports/ethucy.md.
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
from dataclasses import asdict

from blindspot.cli import main_stage
from blindspot.config import shared_dir
from blindspot.io import save_figure, write_json, write_text
from blindspot.report.calibration_figures import reliability_figure
from blindspot.report.ethucy_report import format_report
from blindspot.stage import StageResult
from blindspot.traj.config import EthUcyConfig
from blindspot.traj.ethucy_protocol import EthUcySettings, calibration_table, run_benchmark


def run(cfg, ctx):
    settings = EthUcySettings.from_config(EthUcyConfig.from_cfg(cfg), shared_dir=shared_dir(cfg),
                                          seed=int(cfg.seed))
    bench = run_benchmark(settings, progress=bool(cfg.progress), jobs=int(cfg.jobs))
    write_json(ctx.out("ethucy.json"), bench.results)
    calibration = calibration_table(bench.per_fold)
    write_json(ctx.out("calibration_ethucy.json"), calibration)
    detail = calibration_table(bench.per_fold, reliability=True)
    write_json(ctx.out("reliability_ethucy.json"), detail)
    figure = save_figure(reliability_figure(detail, settings.folds),
                         ctx.out("ethucy_reliability.png"), dpi=130)
    lstm = asdict(settings.lstm) if "lstm_rollout" in settings.models else None
    details = bench.details()
    report = write_text(ctx.out("ethucy.md"), format_report(
        bench.results, bench.validation(), details, settings.folds, lstm,
        "python -m blindspot ethucy", None, seq2seq={**asdict(settings.seq2seq), "mix_cell":
                                                     settings.mix_cell, "mix_modes": settings.mix_modes},
        calibration=calibration, calibration_method=settings.calibration))
    metrics = {m: r["avg"] for m, r in bench.results.items() if isinstance(r, dict) and "avg" in r}
    metrics.update({k: {m: v["avg"] for m, v in r.items()}       # best_of_20: {model: avg}
                    for k, r in bench.results.items() if k.startswith("best_of_")})
    # the wall times go to MLflow and the log, not to the page, whose bytes a rerun reproduces
    seconds = {m: sum(details[f][m]["seconds"] for f in settings.folds)
               for m in settings.models}
    metrics["seconds"] = {"total": bench.seconds, **seconds}
    print(f"ethucy: wall time {bench.seconds:.0f} s ("
          + ", ".join(f"{m} {s:.0f} s" for m, s in seconds.items()) + ")")
    return StageResult(metrics=metrics, artifacts=[report, figure])


if __name__ == "__main__":
    main_stage(run, "ethucy")
