"""safety_bound: what any decision logic could reach on the Monte-Carlo driving scenes, given
when the information about the lead pedestrian first exists (line of sight, the first radar
point, an M-of-N confirmed track): the AEB requested on every intruding scene at the best frame
from the first one with that information, never on the others, scored like the predictors
(blindspot.safety.bound, issue 12)."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import json

import pandas as pd

from blindspot.radar.scenario import load_scenarios
from blindspot.safety.config import WarningConfig
from blindspot.track.config import TrackerConfig
from blindspot.cli import main_stage
from blindspot.io import write_json
from blindspot.safety.assess import perception_bounds
from blindspot.safety.bound import bound_summary, logged_bounds
from blindspot.safety.outcome import body_boxes
from blindspot.safety.risk import EgoShape
from blindspot.stage import StageResult


def run(cfg, ctx):
    w = WarningConfig.from_cfg(cfg)
    group, _ = load_scenarios(cfg.scenario)
    tracker = TrackerConfig.from_cfg(cfg)
    truth = pd.read_parquet(ctx.dep("truth.parquet"))
    meta = json.loads(ctx.dep("scenes.json").read_text())
    points = pd.read_parquet(ctx.dep("points.parquet"), columns=["scene", "frame", "source"])
    bodies = body_boxes(group)
    out = perception_bounds(truth, meta, points, w, bodies=bodies,
                            shape=EgoShape(group.ego.width_m, group.ego.length_m),
                            confirm=(tracker.confirm_m, tracker.confirm_n),
                            points_name=str(ctx.dep("points.parquet")))
    write_json(ctx.out("safety_bound.json"), out)
    print("\n".join(bound_summary("safety_bound", out)))
    return StageResult(metrics=logged_bounds(out))


if __name__ == "__main__":
    main_stage(run, "safety_bound")
