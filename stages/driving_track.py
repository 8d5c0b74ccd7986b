"""driving_track: tracks of the driving scenes' pedestrians, in the blindspot.track schema.

The headline input: the multi-target tracker (blindspot.track.track_points, Hydra group
tracker) on every measured point of every frame of a scene, without labels (frames without a
point are stepped too, so tracks coast through them). The "oracle association" reference input (blindspot.safety.oracle): each pedestrian's measured
points (data/driving/measured.parquet) associated by their truth label and filtered by a
constant-velocity Kalman filter; an upper bound for a tracker on the same points, never the
headline once the tracker's own tracks are here. And "visible truth": the same filter on the true
positions at every frame the pedestrian is in line of sight (plus measurement noise), so the
safety results separate what perception misses from what the warning logic does.
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import pandas as pd

from blindspot import experiment
from blindspot.cli import main_stage
from blindspot.io import write_json, write_parquet
from blindspot.safety.oracle import oracle_tracks, visible_truth_points
from blindspot.track.tracker import track_points
from blindspot.safety.config import WarningConfig
from blindspot.stage import StageResult


def run(cfg, ctx):
    w = WarningConfig.from_mapping(cfg.warning)
    dt = float(experiment.driving_radar(cfg).frame_period_s)
    measured = pd.read_parquet(ctx.dep("measured.parquet"))
    truth = pd.read_parquet(ctx.dep("truth.parquet"))
    last = truth.groupby("scene").frame.max().to_dict()
    inputs = {
        "oracle": (measured, str(ctx.dep("measured.parquet"))),
        "visible_truth": (visible_truth_points(truth, w.oracle.meas_std_m, w.seed),
                          "visible truth points"),
    }
    frames = truth[["scene", "frame", "time_s"]].drop_duplicates(["scene", "frame"])
    pts = frames.merge(measured[["scene", "frame", "x_m", "y_m"]], on=["scene", "frame"],
                       how="left").rename(columns={"scene": "group"})
    tracks = track_points(pts, experiment.tracker(cfg))
    write_parquet(ctx.out("tracks.parquet"), tracks)
    n_tracks = int(tracks.groupby(["group", "track_id"]).ngroups) if len(tracks) else 0
    metrics = {"tracker": {"n_tracks": n_tracks, "n_rows": int(len(tracks)),
                           "n_confirmed_rows": int(tracks.confirmed.sum())}}
    print(f"driving_track: tracker, {n_tracks} tracks, {len(tracks)} rows")
    for name, (points, where) in inputs.items():       # the two reference inputs
        tracks = oracle_tracks(points, w.oracle, dt, last_frame=last, where=where)
        write_parquet(ctx.out(f"tracks_{name}.parquet"), tracks)
        n_tracks = int(tracks.groupby(["group", "track_id"]).ngroups) if len(tracks) else 0
        metrics[name] = {"n_tracks": n_tracks, "n_rows": int(len(tracks)),
                         "n_confirmed_rows": int(tracks.confirmed.sum())}
        print(f"driving_track: {name}, {n_tracks} tracks, {len(tracks)} rows")
    write_json(ctx.out("driving_track.json"), metrics)
    return StageResult(metrics=metrics)


if __name__ == "__main__":
    main_stage(run, "driving_track")
