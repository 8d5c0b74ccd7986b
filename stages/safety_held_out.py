"""safety_held_out: the independent held-out Monte-Carlo draw (issue 40; blindspot.safety.draws):
scenario.monte_carlo.held_out_seed, held_out_scenes_per_cell scenes per cell of the main grid,
through the radar measurement, the tracker and the decision (blindspot.synth.independent_draw),
read at the configured thresholds and at each predictor's AEB operating point chosen on the
tuning draw (safety_tuning.json; blindspot.safety.operating_point); writes the held-out block of
safety.json (reports/metrics/safety_held_out.json, git-tracked so that a fresh clone's repro
reuses it)."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import json

from blindspot.cli import main_stage
from blindspot.io import write_json
from blindspot.radar.scenario import load_scenarios
from blindspot.safety.assess import logged_metrics
from blindspot.safety.draws import draw_block
from blindspot.safety.operating_point import read_in_block
from blindspot.safety.predict import stage_predictors
from blindspot.stage import StageResult
from blindspot.synth.independent_draw import assess_draw
from blindspot.typed_config import jobs


def run(cfg, ctx):
    mc = load_scenarios(cfg.scenario)[0].monte_carlo
    seed, n_jobs = mc.held_out_seed, jobs(cfg)
    res = assess_draw(cfg, stage_predictors(cfg, ctx.dep, jobs=n_jobs), seed=seed,
                      per_cell=mc.held_out_scenes_per_cell, jobs=n_jobs, progress=cfg.progress,
                      where="held-out")
    tuning = json.loads(ctx.dep("safety_tuning.json").read_text())
    block = read_in_block(draw_block(res.metrics, seed), res.curves, tuning)
    write_json(ctx.out("safety_held_out.json"), block)
    for name, h in block.items():
        if isinstance(h, dict):
            op = h["at_tuning_operating_point"]
            print(f"safety_held_out {name}: avoided after visible "
                  f"{h['avoided_after_visible_rate']:.3f} at {h['false_activation_rate']:.3f} "
                  f"false activations; at the tuning draw's threshold {op['aeb_threshold']:.2f}: "
                  f"{op['avoided_after_visible_rate']:.3f} at {op['false_activation_rate']:.3f}; "
                  f"first point -> moving {h['first_point_to_moving_s_median']} s, -> AEB "
                  f"{h['first_point_to_aeb_s_median']} s")
    return StageResult(metrics=logged_metrics({"held_out": block}))


if __name__ == "__main__":
    main_stage(run, "safety_held_out")
