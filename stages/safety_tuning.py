"""safety_tuning: the independent tuning Monte-Carlo draw (issue 40; blindspot.safety.draws):
scenario.monte_carlo.tuning_seed, tuning_scenes_per_cell scenes per cell of the main grid,
through the radar measurement, the tracker and the decision (blindspot.synth.independent_draw);
per predictor its rates at the configured thresholds and its operating characteristic, on which
the safety stage chooses each predictor's AEB operating point (blindspot.safety.operating_point).
Writes reports/metrics/safety_tuning.json (git-tracked so that a fresh clone's repro reuses it)."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)

from blindspot.cli import main_stage
from blindspot.io import write_json
from blindspot.radar.scenario import load_scenarios
from blindspot.safety.assess import logged_metrics
from blindspot.safety.draws import draw_summary
from blindspot.safety.predict import stage_predictors
from blindspot.stage import StageResult
from blindspot.synth.independent_draw import draw_stage_block
from blindspot.typed_config import jobs


def run(cfg, ctx):
    mc = load_scenarios(cfg.scenario)[0].monte_carlo
    block, _ = draw_stage_block(cfg, stage_predictors(cfg, ctx.dep, jobs=jobs(cfg)),
                                seed=mc.tuning_seed, per_cell=mc.tuning_scenes_per_cell,
                                jobs=jobs(cfg), progress=cfg.progress, where="tuning")
    write_json(ctx.out("safety_tuning.json"), block)
    print("\n".join(draw_summary("safety_tuning", block)))
    return StageResult(metrics=logged_metrics({"tuning_draw": block}))


if __name__ == "__main__":
    main_stage(run, "safety_tuning")
