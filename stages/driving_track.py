"""driving_track: tracks of the driving scenes' pedestrians, in the blindspot.track schema
(blindspot.synth.driving_tracks.driving_tracks).

The headline input: the multi-target tracker (Hydra group ``tracker``) on every radar point of
every frame of a scene (data/driving/points.parquet, world frame, static world included; the
points' truth label is not read), each confirmed track classed moving or not by the tracker's
moving-object test (``tracker.moving``: Doppler-first, kinematic, Doppler refutation, static
evidence grid; blindspot.track.moving.moving_tracks). The truth labels only score that split
(driving_track.json ``classifier``). The references: "oracle association" (each pedestrian's
own points by their truth label, Kalman filtered) and "noisy_position" (the true positions at
every frame in line of sight, plus measurement noise), so the safety results separate what
perception misses from what the warning logic does.
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import pandas as pd

from blindspot.radar.config import RadarConfig
from blindspot.safety.config import WarningConfig
from blindspot.track.config import TrackerConfig
from blindspot.cli import main_stage
from blindspot.io import write_json, write_parquet
from blindspot.stage import StageResult
from blindspot.synth.driving_tracks import driving_tracks


def run(cfg, ctx):
    w = WarningConfig.from_cfg(cfg)
    truth = pd.read_parquet(ctx.dep("truth.parquet"))
    points = pd.read_parquet(ctx.dep("points.parquet"))
    tables, metrics = driving_tracks(
        truth, points, TrackerConfig.from_cfg(cfg), w.oracle, seed=w.seed,
        frame_period_s=float(RadarConfig.from_cfg(cfg, "driving_radar").frame_period_s),
        jobs=int(cfg.jobs), where=str(ctx.dep("points.parquet")))
    for name, table in tables.items():
        write_parquet(ctx.out(f"{name}.parquet"), table)
    write_json(ctx.out("driving_track.json"), metrics)
    m = metrics["tracker"]
    print(f"driving_track: tracker on {len(points)} points, {m['n_tracks']} tracks "
          f"({m['n_moving_tracks']} moving), {m['n_rows']} rows")
    for k, c in m["classifier"].items():
        if isinstance(c, dict):
            print(f"driving_track: classifier {k}: static-world tracks classed moving "
                  f"{c['static_world_moving']} of {c['static_world_tracks']}; intruding scenes "
                  f"whose lead pedestrian is never classed moving "
                  f"{c['intruding_scenes_missed']} of {c['intruding_scenes']}; TTC at its "
                  f"first moving frame median {c['ttc_at_moving_s_median']} s")
    return StageResult(metrics=metrics)


if __name__ == "__main__":
    main_stage(run, "driving_track")
