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
blindspot.safety.predict.moving_tracks) and, per row, not standing on the static environment
(the static points of frames ``warning.moving_static_lag_frames`` and more before, in the 3 x 3
cells of ``warning.moving_static_cell_m`` around the track, fewer than
``warning.moving_static_evidence_min``, a coasting row read at its track's last measured row;
blindspot.safety.predict.track_static_evidence), so parked cars and kerb clutter are tracked
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

from blindspot import experiment
from blindspot.cli import main_stage
from blindspot.io import write_json, write_parquet
from blindspot.safety.evaluation import replicate_half
from blindspot.safety.oracle import oracle_tracks, visible_truth_points
from blindspot.safety.predict import moving_test_settings, moving_tracks
from blindspot.track.tracker import label_objects, track_points
from blindspot.stage import StageResult


def run(cfg, ctx):
    w = experiment.warning(cfg)
    tcfg = experiment.tracker(cfg)
    dt = float(experiment.driving_radar(cfg).frame_period_s)
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
    metrics = {"tracker": {**_counts(tracks), "classifier": {
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
        metrics[name] = _counts(tracks)
        print(f"driving_track: {name}, {metrics[name]['n_tracks']} tracks, {len(tracks)} rows")
    write_json(ctx.out("driving_track.json"), metrics)
    return StageResult(metrics=metrics)


def tracker_input(truth, points):
    """The tracker's input for the driving scenes, and the ego's track.

    Args:
        truth: data/driving/truth.parquet (one row per scene, frame and pedestrian: ``scene``,
            ``frame``, ``time_s``, ``ego_x_m``, ``ego_y_m``, ``ego_yaw_deg``).
        points: data/driving/points.parquet (``scene``, ``frame``, ``x_m``, ``y_m``,
            ``velocity_over_ground_mps``; world frame).

    Returns:
        ``(pts, ego)``: ``pts`` the :func:`blindspot.track.tracker.track_points` input, one row
        per point with ``group`` (the scene), ``frame``, ``time_s``, ``x_m``, ``y_m``,
        ``velocity_over_ground_mps``, ``sensor_x_m``, ``sensor_y_m`` (the ego's position, the
        Doppler's line of sight), ``sensor_heading_deg`` (the ego's yaw: the radar looks ahead,
        the axis of ``tracker.field_of_view_deg``), and one row with NaN coordinates for each frame without a
        point (so every frame is stepped and tracks coast through it); ``ego`` one row per
        (``group``, ``frame``) with ``ego_x_m``, ``ego_y_m``.
    """
    frames = truth[["scene", "frame", "time_s"]].drop_duplicates(["scene", "frame"])
    pose = (truth.groupby(["scene", "frame"], as_index=False)
            [["ego_x_m", "ego_y_m", "ego_yaw_deg"]].first().rename(columns={"scene": "group"}))
    pts = (frames.merge(points[["scene", "frame", "x_m", "y_m", "velocity_over_ground_mps"]],
                        on=["scene", "frame"], how="left").rename(columns={"scene": "group"})
           .merge(pose.rename(columns={"ego_x_m": "sensor_x_m", "ego_y_m": "sensor_y_m",
                                       "ego_yaw_deg": "sensor_heading_deg"}),
                  on=["group", "frame"], how="left"))
    return pts, pose.drop(columns="ego_yaw_deg")


def doppler_spread_by_label(objects):
    """The Doppler spread the moving test's ``warning.moving_doppler_spread_std_mps`` models,
    measured (truth labels score it): :func:`pooled_std` over the tracker's objects of the
    Monte-Carlo scenes (``objects``: :func:`monte_carlo_objects`) that are all static-world
    points or all one pedestrian's, per half of the replicates (even: tuning, odd: held out);
    no ``pooled_std_mps`` where there is no such object (a tiny profile)."""
    per = objects[objects.n_sources == 1]
    tuning = replicate_half(per.group.to_numpy())
    static = (per.source == "static").to_numpy()
    out = {}
    for half, sel in (("tuning", tuning), ("held_out", ~tuning)):
        for name, lab in (("static", static), ("pedestrian", ~static)):
            q = per[sel & lab]
            dof = int((q.n_points - 1).sum())
            out.setdefault(half, {})[name] = {"n_objects": int(len(q)),
                                              "degrees_of_freedom": dof}
            if dof:                                     # none without a multi-point object
                out[half][name]["pooled_std_mps"] = pooled_std(q.n_points,
                                                               q.doppler_spread_mps)
    return out


def monte_carlo_objects(points, tcfg):
    """:func:`object_doppler_spreads` of the Monte-Carlo scenes' points (points.parquet; the
    scene named ``group``) on their ego-compensated radial speeds."""
    mc = points[points.scene.str.startswith("mc_")].rename(columns={"scene": "group"})
    return object_doppler_spreads(mc.assign(time_s=mc.frame.astype(float)), tcfg,
                                  "velocity_over_ground_mps")


def object_doppler_spreads(points, tcfg, speed):
    """One row per object of two or more points (the tracker's DBSCAN objects,
    :func:`blindspot.track.tracker.label_objects`): ``n_points``, ``doppler_spread_mps`` (the
    sample standard deviation, ddof 1, of the column ``speed``, m/s), the object's first
    point's other columns, and with a ``source`` column ``n_sources`` (truth labels among its
    points), with a ``range_m`` column ``range_mean_m``."""
    pts = points.assign(obj=label_objects(points, tcfg).to_numpy())
    g = pts[pts.obj >= 0].groupby("obj")
    per = g.first().assign(n_points=g.size(), doppler_spread_mps=g[speed].std(ddof=1))
    if "source" in pts:
        per["n_sources"] = g.source.nunique()
    if "range_m" in pts:
        per["range_mean_m"] = g.range_m.mean()
    return per[per.n_points >= 2]


def pooled_std(n_points, spread):
    """sqrt(sum (n - 1) s^2 / sum (n - 1)) over objects of ``n_points`` points and sample
    standard deviations ``spread``: the pooled within-object standard deviation (m/s)."""
    dof = (np.asarray(n_points, float) - 1)
    return float(np.sqrt((dof * np.asarray(spread, float) ** 2).sum() / dof.sum()))


def own_points(points):
    """Each pedestrian's own points (truth label ``source``), one centroid per (scene,
    pedestrian, frame): columns scene, pedestrian, frame, time_s, x_m, y_m."""
    own = points[points.source != "static"]
    return (own.groupby(["scene", "source", "frame"], as_index=False)
            .agg(time_s=("time_s", "first"), x_m=("x_m", "mean"), y_m=("y_m", "mean"))
            .rename(columns={"source": "pedestrian"}))


def _counts(tracks):
    n = int(tracks.groupby(["group", "track_id"]).ngroups) if len(tracks) else 0
    out = {"n_tracks": n, "n_rows": int(len(tracks)),
           "n_confirmed_rows": int(tracks.confirmed.sum())}
    if "moving" in tracks.columns:
        out["n_moving_tracks"] = int(tracks[tracks.moving].groupby(["group", "track_id"]).ngroups)
        out["n_moving_rows"] = int(tracks.moving.sum())
    return out


def track_labels(tracks, points, eps):
    """Truth only scores the split: per confirmed track (group, track_id) the label of the
    points within the tracker's cluster radius of its positions over its life: ``static`` when
    all are static-world points, else the pedestrian giving most of them."""
    conf = tracks[tracks.confirmed]
    near = conf[["group", "frame", "track_id", "x_m", "y_m"]].merge(
        points[["scene", "frame", "x_m", "y_m", "source"]].rename(
            columns={"scene": "group", "x_m": "px", "y_m": "py"}), on=["group", "frame"])
    near = near[np.hypot(near.x_m - near.px, near.y_m - near.py) <= eps]
    ped = near[near.source != "static"]
    lab = pd.Series("static", index=pd.MultiIndex.from_frame(
        conf[["group", "track_id"]].drop_duplicates()), dtype=object)
    if len(ped):
        top = ped.groupby(["group", "track_id"]).source.agg(lambda s: s.value_counts().index[0])
        lab.loc[top.index] = top.to_numpy()
    return lab


def confusion(tracks, moving, labels, truth):
    """The classifier's confusion on the confirmed tracks (labels: :func:`track_labels`)."""
    t = tracks.assign(_m=moving)
    t = t[t.confirmed]
    per = t.groupby(["group", "track_id"])._m.any()
    lab = labels.reindex(per.index)
    st = lab.to_numpy() == "static"
    mc = truth[(truth.set == "monte_carlo") & (truth.pedestrian == "p0")]
    first = mc.groupby("scene").first()
    intr = first.index[((first.behaviour == "cross") & first.collision.astype(bool)).to_numpy()]
    p0 = (lab.to_numpy() == "p0") & per.index.get_level_values(0).isin(intr)
    t_first = t[t._m].groupby(["group", "track_id"]).time_s.min().reindex(per.index)
    scene_first = t_first[p0].groupby(level=0).min().reindex(intr)
    ttc = (first.collision_time_s.reindex(intr) - scene_first).to_numpy(float)
    ped = lab.to_numpy() != "static"
    return {"static_world_tracks": int(st.sum()),
            "static_world_moving": int(per[st].sum()),
            "pedestrian_tracks": int(ped.sum()),
            "pedestrian_static": int((~per[ped]).sum()),
            "intruding_scenes": int(len(intr)),
            "intruding_scenes_missed": int(np.isnan(ttc).sum()),
            "ttc_at_moving_s_median": (float(np.nanmedian(ttc)) if np.isfinite(ttc).any()
                                       else None),
            "ttc_at_moving_s_p10": (float(np.nanpercentile(ttc, 10)) if np.isfinite(ttc).any()
                                    else None)}


if __name__ == "__main__":
    main_stage(run, "driving_track")
