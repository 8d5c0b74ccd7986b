"""driving_track: tracks of the driving scenes' pedestrians, in the blindspot.track schema.

The headline input: the multi-target tracker (blindspot.track.track_points, Hydra group
tracker) on every radar point of every frame of a scene (data/driving/points.parquet, world
frame, the static world's points included; the points' ``source`` truth label is not read),
frames without a point stepped too, so tracks coast through them; the scenes spread over
``jobs`` worker processes. Its DBSCAN groups the points of a frame into objects, and each track
row carries its object's point count and median ego-motion-compensated radial speed
(``velocity_over_ground_mps``). A confirmed track is a moving object (what the warning assesses)
from its first frame whose filtered world-frame velocity is above ``warning.moving_speed_mps``,
significantly non-zero (``warning.moving_probability``) and not refuted by the track's own
Doppler (the summed log-likelihood ratio "moves as tracked" vs "static", of form
``warning.moving_doppler_llr``, held above ``warning.moving_doppler_log_ratio_floor``, above
``warning.moving_doppler_log_ratio_min``, point spread ``warning.moving_doppler_std_mps``,
optionally with the objects' Doppler spread ratio ``warning.moving_doppler_spread_std_mps``
and judged against the velocity of the frame or the current one,
``warning.moving_doppler_reference``;
blindspot.track.moving.moving_tracks) and, per row, not standing on the static environment
(the static points of frames ``warning.moving_static_lag_frames`` and more before, in the 3 x 3
cells of ``warning.moving_static_cell_m`` around the track, fewer than
``warning.moving_static_evidence_min``, a coasting row read at its track's last measured row;
blindspot.track.moving.track_static_evidence), so parked cars and kerb clutter are tracked
and left out by their own motion and by where they are, and a child crossing near boresight,
whose Doppler looks static, is found by its motion over frames. The points' truth labels only score that split
(driving_track.json ``classifier``; ``doppler_spread`` measures the objects' Doppler spread
per label): static-world tracks classed moving, the lead pedestrian's
tracks of the intruding Monte-Carlo scenes never classed moving, and the time to collision
(without braking) when the first of them is, for the kinematic test alone ("kinematic") and
with the Doppler test ("doppler").

The "oracle association" reference input (blindspot.safety.oracle): each pedestrian's own radar
points (points.parquet, associated by their truth label ``source``, one centroid per frame)
filtered by a constant-velocity Kalman filter; an upper bound for a tracker on the same points.
(measured.parquet is not that: it holds the frame's largest off-curve cluster attributed to the
nearest pedestrian, clutter clusters included.) And "visible truth": the same filter on the true
positions at every frame the pedestrian is in line of sight (plus measurement noise), so the
safety results separate what perception misses from what the warning logic does.
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import numpy as np
import pandas as pd

from blindspot.radar.config import RadarConfig
from blindspot.safety.config import WarningConfig
from blindspot.track.config import TrackerConfig
from blindspot.cli import main_stage
from blindspot.io import write_json, write_parquet
from blindspot.safety.oracle import oracle_tracks, visible_truth_points
from blindspot.track.moving import moving_test_settings, moving_tracks
from blindspot.synth.driving_tracks import (confusion, doppler_spread_by_label,
                                            monte_carlo_objects, own_points, track_counts,
                                            track_labels, tracker_input)
from blindspot.track.tracker import track_points
from blindspot.stage import StageResult


def run(cfg, ctx):
    w = WarningConfig.from_cfg(cfg)
    tcfg = TrackerConfig.from_cfg(cfg)
    dt = float(RadarConfig.from_cfg(cfg, "driving_radar").frame_period_s)
    truth = pd.read_parquet(ctx.dep("truth.parquet"))
    last = truth.groupby("scene").frame.max().to_dict()
    every = pd.read_parquet(ctx.dep("points.parquet"))
    need = {"scene", "frame", "x_m", "y_m", "velocity_over_ground_mps", "static", "source"}
    if need - set(every.columns):
        raise ValueError(f"{ctx.dep('points.parquet')}: missing columns "
                         f"{sorted(need - set(every.columns))}")
    inputs = {
        "oracle": (own_points(every), f"{ctx.dep('points.parquet')} (own points by source)"),
        "visible_truth": (visible_truth_points(truth, w.oracle.meas_std_m, w.seed),
                          "visible truth points"),
    }
    pts, ego = tracker_input(truth, every)
    tracks = track_points(pts, tcfg, jobs=int(cfg.jobs),
                          source=str(ctx.dep("points.parquet")))
    kinematic = moving_tracks(tracks, w.moving_speed_mps, w.moving_probability)
    tracks["moving"] = moving_tracks(tracks, ego=ego, **moving_test_settings(w),
                                     points=every[["scene", "frame", "x_m", "y_m", "static"]])
    write_parquet(ctx.out("tracks.parquet"), tracks)
    labels = track_labels(tracks, every, tcfg.cluster_eps_m)
    metrics = {"tracker": {**track_counts(tracks), "classifier": {
        "kinematic": confusion(tracks, kinematic, labels, truth),
        "doppler": confusion(tracks, tracks.moving.to_numpy(), labels, truth),
        "moving_speed_mps": w.moving_speed_mps, "moving_probability": w.moving_probability,
        "moving_doppler_std_mps": w.moving_doppler_std_mps,
        "moving_doppler_log_ratio_min": w.moving_doppler_log_ratio_min,
        "moving_static_evidence_min": w.moving_static_evidence_min,
        "moving_static_cell_m": w.moving_static_cell_m,
        "moving_static_lag_frames": w.moving_static_lag_frames}},
        "doppler_spread": doppler_spread_by_label(monte_carlo_objects(every, tcfg))}
    m = metrics["tracker"]
    print(f"driving_track: tracker on {len(every)} points, {m['n_tracks']} tracks "
          f"({m['n_moving_tracks']} moving), {m['n_rows']} rows")
    for k in ("kinematic", "doppler"):
        c = m["classifier"][k]
        print(f"driving_track: classifier {k}: static-world tracks classed moving "
              f"{c['static_world_moving']} of {c['static_world_tracks']}; intruding scenes whose "
              f"lead pedestrian is never classed moving {c['intruding_scenes_missed']} of "
              f"{c['intruding_scenes']}; TTC at its first moving frame median "
              f"{c['ttc_at_moving_s_median']} s")
    for name, (points, where) in inputs.items():       # the two reference inputs
        tracks = oracle_tracks(points, w.oracle, dt, last_frame=last, where=where)
        write_parquet(ctx.out(f"tracks_{name}.parquet"), tracks)
        metrics[name] = track_counts(tracks)
        print(f"driving_track: {name}, {metrics[name]['n_tracks']} tracks, {len(tracks)} rows")
    write_json(ctx.out("driving_track.json"), metrics)
    return StageResult(metrics=metrics)


if __name__ == "__main__":
    main_stage(run, "driving_track")
