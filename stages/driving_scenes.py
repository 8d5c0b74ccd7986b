"""driving_scenes: the driving scenarios' truth (issue 11): the named Euro NCAP scenes of
conf/scenario and the seeded Monte-Carlo set around the figure scene; per frame the ego pose,
every pedestrian's position, velocity, occluded flag and the collision without braking
(blindspot.radar.driving)."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import pandas as pd

from blindspot.radar.config import RadarConfig
from blindspot.radar.scenario import load_scenarios
from blindspot.cli import main_stage
from blindspot.io import write_json, write_parquet
from blindspot.radar.driving import (describe_scenes, draw_scenarios, monte_carlo_metrics,
                                     scene_truth)
from blindspot.safety.ncap import nominal_scenes
from blindspot.stage import StageResult


def run(cfg, ctx):
    group, named = load_scenarios(cfg.scenario)
    radar = RadarConfig.from_cfg(cfg, "driving_radar")
    mc = draw_scenarios(group, named[group.figure_scene])
    ncap = nominal_scenes(named, group.monte_carlo.speeds_kmh)      # Euro NCAP nominal grids
    sets = ([("named", s) for s in named.values()] + [("ncap", s) for s in ncap]
            + [("monte_carlo", s) for s in mc])
    truth = pd.concat([scene_truth(s, group, radar.frame_period_s).assign(set=k) for k, s in sets],
                      ignore_index=True)
    scenes = describe_scenes(sets, truth)
    write_parquet(ctx.out("truth.parquet"), truth)
    write_json(ctx.out("scenes.json"), scenes)
    metrics = {"n_named_scenes": len(named), "n_monte_carlo_scenes": len(mc),
               "n_frames": int(truth.drop_duplicates(["scene", "frame"]).shape[0]),
               **monte_carlo_metrics(truth)}
    write_json(ctx.out("driving_scenes.json"), metrics)
    print(f"driving_scenes: {len(named)} named + {len(mc)} Monte-Carlo scenes, "
          f"{metrics['n_frames']} frames; collisions without braking: intruding "
          f"{metrics['monte_carlo.collision_rate_intruding']:.2f}, non-intruding "
          f"{metrics['monte_carlo.collision_rate_non_intruding']:.2f}")
    return StageResult(metrics=metrics)


if __name__ == "__main__":
    main_stage(run, "driving_scenes")
