"""driving_scenes: the driving scenarios' truth (issue 11): the named Euro NCAP scenes of
conf/scenario and the seeded Monte-Carlo set around the figure scene; per frame the ego pose,
every pedestrian's position, velocity, occluded flag and the collision without braking
(blindspot.radar.driving)."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import numpy as np
import pandas as pd

from blindspot.radar.config import RadarConfig
from blindspot.radar.scenario import load_scenarios
from blindspot.cli import main_stage
from blindspot.io import write_json, write_parquet
from blindspot.radar.driving import car_polygons, draw_scenarios, scene_truth
from blindspot.safety.ncap import nominal_scenes
from blindspot.stage import StageResult


def _finite(x):
    """A float, or None (JSON null) for NaN: no collision."""
    return float(x) if np.isfinite(x) else None


def run(cfg, ctx):
    group, named = load_scenarios(cfg.scenario)
    radar = RadarConfig.from_cfg(cfg, "driving_radar")
    mc = draw_scenarios(group, named[group.figure_scene])
    ncap = nominal_scenes(named, group.monte_carlo.speeds_kmh)      # Euro NCAP nominal grids
    sets = ([("named", s) for s in named.values()] + [("ncap", s) for s in ncap]
            + [("monte_carlo", s) for s in mc])
    truth = pd.concat([scene_truth(s, group, radar.frame_period_s).assign(set=k) for k, s in sets],
                      ignore_index=True)
    first = truth.drop_duplicates(["scene", "pedestrian"]).set_index(["scene", "pedestrian"])
    scenes = {
        s.name: {
            "set": k, "speed_kmh": s.speed_kmh, "seed": s.seed,
            "car_polygons_xy_m": car_polygons(s).tolist(),
            "pedestrians": [{"name": p.name, "body": p.body, "behaviour": p.behaviour,
                             "side": p.side, "impact_pct": p.impact_pct,
                             "collision": bool(first.loc[(s.name, p.name), "collision"]),
                             "collision_time_s": _finite(first.loc[(s.name, p.name), "collision_time_s"]),
                             "impact_point_pct": _finite(first.loc[(s.name, p.name), "impact_point_pct"])}
                            for p in s.pedestrians],
        }
        for k, s in sets
    }
    write_parquet(ctx.out("truth.parquet"), truth)
    write_json(ctx.out("scenes.json"), scenes)
    lead = truth[(truth.set == "monte_carlo") & (truth.pedestrian == "p0")]
    per = lead.drop_duplicates("scene")
    intr = per.behaviour == "cross"
    metrics = {
        "n_named_scenes": len(named), "n_monte_carlo_scenes": len(mc),
        "n_frames": int(truth.drop_duplicates(["scene", "frame"]).shape[0]),
        "monte_carlo.collision_rate_intruding": float(per.collision[intr].mean()),
        "monte_carlo.collision_rate_non_intruding": float(per.collision[~intr].mean()),
        "monte_carlo.lead_hidden_fraction": float(lead.occluded.mean()),
        "monte_carlo.impact_point_pct_sd": float(np.nanstd(per.impact_point_pct[intr])),
    }
    write_json(ctx.out("driving_scenes.json"), metrics)
    print(f"driving_scenes: {len(named)} named + {len(mc)} Monte-Carlo scenes, "
          f"{metrics['n_frames']} frames; collisions without braking: intruding "
          f"{metrics['monte_carlo.collision_rate_intruding']:.2f}, non-intruding "
          f"{metrics['monte_carlo.collision_rate_non_intruding']:.2f}")
    return StageResult(metrics=metrics)


if __name__ == "__main__":
    main_stage(run, "driving_scenes")
