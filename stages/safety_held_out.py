"""safety_held_out: the independent held-out Monte-Carlo draw (issue 40; blindspot.safety.draws):
scenario.monte_carlo.held_out_seed, held_out_scenes_per_cell scenes per cell of the main grid,
through the radar measurement, the tracker and the decision (blindspot.synth.independent_draw);
per predictor its rates at the configured thresholds and its operating characteristic, which the
safety stage reads at the operating point chosen on the tuning draw
(blindspot.safety.operating_point); and the draw's perception bounds (blindspot.safety.bound: a
perfect decision from the first frame in line of sight, the first radar point, the first
M-of-N confirmable track), the safety_bound stage's on this draw. Writes
reports/metrics/safety_held_out.json and safety_held_out_bound.json (git-tracked so that a fresh
clone's repro reuses them)."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)

from blindspot.cli import main_stage
from blindspot.io import write_json
from blindspot.radar.scenario import load_scenarios
from blindspot.safety.assess import logged_metrics
from blindspot.safety.bound import bound_summary, logged_bounds
from blindspot.safety.draws import draw_summary
from blindspot.safety.predict import stage_predictors
from blindspot.stage import StageResult
from blindspot.synth.independent_draw import draw_stage_block
from blindspot.typed_config import jobs


def run(cfg, ctx):
    mc = load_scenarios(cfg.scenario)[0].monte_carlo
    block, bounds = draw_stage_block(cfg, stage_predictors(cfg, ctx.dep, jobs=jobs(cfg)),
                                     seed=mc.held_out_seed, per_cell=mc.held_out_scenes_per_cell,
                                     jobs=jobs(cfg), progress=cfg.progress, where="held-out",
                                     with_bounds=True)
    write_json(ctx.out("safety_held_out.json"), block)
    write_json(ctx.out("safety_held_out_bound.json"), bounds)
    print("\n".join(draw_summary("safety_held_out", block)
                    + bound_summary("safety_held_out bound", bounds)))
    return StageResult(metrics={**logged_metrics({"held_out": block}),
                                "held_out_bound": logged_bounds(bounds)})


if __name__ == "__main__":
    main_stage(run, "safety_held_out")
