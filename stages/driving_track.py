"""driving_track: tracks of the driving scenes' pedestrians, in the blindspot.track schema.

The headline input: the multi-target tracker (blindspot.track.track_points, Hydra group
tracker) on every radar point of every frame of a scene (data/driving/points.parquet, world
frame, the static world's points included; the points' ``static`` flag and ``source`` truth
label are not read), frames without a point stepped too, so tracks coast through them. Its
DBSCAN groups the points of a frame into objects; a confirmed track is a moving object (what the
warning assesses) from its first frame with a filtered world-frame speed above
``warning.moving_speed_mps`` and significantly non-zero (``warning.moving_probability``) on (blindspot.safety.predict.moving_tracks), so parked cars and
kerb clutter are tracked and left out by their own motion, and a child crossing near boresight,
whose Doppler looks static, is found by its motion over frames. The points' truth labels only
score that split (driving_track.json: tracks whose points are all static-world points, their
filtered-speed p99, and how many of them pass as moving).

The "oracle association" reference input (blindspot.safety.oracle): each pedestrian's measured
points (data/driving/measured.parquet) associated by their truth label and filtered by a
constant-velocity Kalman filter; an upper bound for a tracker on the same points. And "visible
truth": the same filter on the true positions at every frame the pedestrian is in line of sight
(plus measurement noise), so the safety results separate what perception misses from what the
warning logic does.
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import numpy as np
import pandas as pd

from blindspot import experiment
from blindspot.cli import main_stage
from blindspot.io import write_json, write_parquet
from blindspot.safety.oracle import oracle_tracks, visible_truth_points
from blindspot.safety.predict import moving_tracks
from blindspot.track.tracker import track_points
from blindspot.stage import StageResult


def run(cfg, ctx):
    w = experiment.warning(cfg)
    dt = float(experiment.driving_radar(cfg).frame_period_s)
    measured = pd.read_parquet(ctx.dep("measured.parquet"))
    truth = pd.read_parquet(ctx.dep("truth.parquet"))
    last = truth.groupby("scene").frame.max().to_dict()
    inputs = {
        "oracle": (measured, str(ctx.dep("measured.parquet"))),
        "visible_truth": (visible_truth_points(truth, w.oracle.meas_std_m, w.seed),
                          "visible truth points"),
    }
    every = pd.read_parquet(ctx.dep("points.parquet"))
    need = {"scene", "frame", "x_m", "y_m", "source"}
    if need - set(every.columns):
        raise ValueError(f"{ctx.dep('points.parquet')}: missing columns "
                         f"{sorted(need - set(every.columns))}")
    frames = truth[["scene", "frame", "time_s"]].drop_duplicates(["scene", "frame"])
    pts = frames.merge(every[["scene", "frame", "x_m", "y_m"]], on=["scene", "frame"],
                       how="left").rename(columns={"scene": "group"})
    tracks = track_points(pts, experiment.tracker(cfg))
    tracks["moving"] = moving_tracks(tracks, w.moving_speed_mps, w.moving_probability)
    write_parquet(ctx.out("tracks.parquet"), tracks)
    metrics = {"tracker": {**_counts(tracks), **_static_score(tracks, every, cfg, w)}}
    m = metrics["tracker"]
    print(f"driving_track: tracker on {len(every)} points, {m['n_tracks']} tracks "
          f"({m['n_moving_tracks']} moving), {m['n_rows']} rows; static-world tracks "
          f"{m['n_static_world_tracks']}, their filtered speed p99 "
          f"{m['static_world_speed_p99_mps']:.2f} m/s, {m['n_static_world_moving']} classified "
          "moving")
    for name, (points, where) in inputs.items():       # the two reference inputs
        tracks = oracle_tracks(points, w.oracle, dt, last_frame=last, where=where)
        write_parquet(ctx.out(f"tracks_{name}.parquet"), tracks)
        metrics[name] = _counts(tracks)
        print(f"driving_track: {name}, {metrics[name]['n_tracks']} tracks, {len(tracks)} rows")
    write_json(ctx.out("driving_track.json"), metrics)
    return StageResult(metrics=metrics)


def _counts(tracks):
    n = int(tracks.groupby(["group", "track_id"]).ngroups) if len(tracks) else 0
    out = {"n_tracks": n, "n_rows": int(len(tracks)),
           "n_confirmed_rows": int(tracks.confirmed.sum())}
    if "moving" in tracks.columns:
        out["n_moving_tracks"] = int(tracks[tracks.moving].groupby(["group", "track_id"]).ngroups)
        out["n_moving_rows"] = int(tracks.moving.sum())
    return out


def _static_score(tracks, points, cfg, w):
    """Truth only scores the split: a confirmed track is a static-world track when every point
    within the tracker's cluster radius of its positions is a static-world point (``source``)."""
    eps = float(experiment.tracker(cfg).cluster_eps_m)
    conf = tracks[tracks.confirmed]
    near = conf[["group", "frame", "track_id", "x_m", "y_m"]].merge(
        points[["scene", "frame", "x_m", "y_m", "source"]].rename(
            columns={"scene": "group", "x_m": "px", "y_m": "py"}), on=["group", "frame"])
    near = near[np.hypot(near.x_m - near.px, near.y_m - near.py) <= eps]
    ped = (near.source != "static").groupby([near.group, near.track_id]).any()
    static_ids = ped.index[~ped.to_numpy()]
    key = pd.MultiIndex.from_frame(conf[["group", "track_id"]])
    st = conf[key.isin(static_ids)]
    speed = np.hypot(st.vx_mps, st.vy_mps)
    moving = st.groupby(["group", "track_id"]).moving.any()
    return {"n_static_world_tracks": int(len(static_ids)),
            "static_world_speed_p99_mps": float(np.percentile(speed, 99)) if len(st) else 0.0,
            "n_static_world_moving": int(moving.sum()),
            "moving_speed_mps": w.moving_speed_mps, "moving_probability": w.moving_probability}


if __name__ == "__main__":
    main_stage(run, "driving_track")
