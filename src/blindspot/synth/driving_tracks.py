"""The driving scenes' tracker input and how its tracks are scored against the truth labels.

:func:`tracker_input` lays the driving scenes' radar points (world frame) and the ego's pose into
the tracker's input; :func:`own_points` gives each pedestrian's own points (the oracle
association); :func:`track_labels` and :func:`confusion` score the moving-object test against the
points' truth labels (the truth only scores, it never feeds the test); :func:`doppler_spread_by_label`
measures the Doppler spread of the tracker's objects per truth label, per half of the
Monte-Carlo replicates.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from blindspot.safety.evaluation import replicate_half
from blindspot.safety.oracle import oracle_tracks, noisy_position_points
from blindspot.tables import check_columns
from blindspot.track.moving import moving_test_settings, moving_tracks
from blindspot.track.tracker import label_objects, track_points

__all__ = ["POINT_COLUMNS", "driving_tracks", "tracker_input", "doppler_spread_by_label", "monte_carlo_objects",
           "object_doppler_spreads", "pooled_std", "own_points", "track_counts", "track_labels",
           "confusion"]


#: Columns of data/driving/points.parquet that :func:`driving_tracks` reads.
POINT_COLUMNS = ("scene", "frame", "time_s", "x_m", "y_m", "velocity_over_ground_mps", "static",
                 "source")


def driving_tracks(truth, points, tcfg, oracle_cfg, *, seed, frame_period_s, jobs=1,
                   where="points"):
    """The driving_track stage's science: the tracker on every radar point of every scene with
    the moving-object test (``tcfg.moving``), and the two reference inputs.

    The headline input: :func:`blindspot.track.tracker.track_points` (settings ``tcfg``, a
    :class:`~blindspot.track.config.TrackerConfig`) on :func:`tracker_input` (the static
    world's points included, the points' ``source`` truth label not read), its rows' ``moving``
    column from :func:`blindspot.track.moving.moving_tracks` with the static-evidence grid of
    the points' ego-motion ``static`` flag. The truth labels only score that split
    (:func:`track_labels`, :func:`confusion`, for the kinematic test alone and for the whole
    test) and the objects' Doppler spread (:func:`doppler_spread_by_label`). The references
    (:func:`blindspot.safety.oracle.oracle_tracks`, settings ``oracle_cfg``): "oracle" (each
    pedestrian's own points, associated by their truth label) and "noisy_position" (the true
    positions at every frame in line of sight plus noise of ``oracle_cfg.meas_std_m``, drawn
    with ``seed``).

    Returns ``(tables, metrics)``: tables ``tracks``, ``tracks_oracle``,
    ``tracks_noisy_position`` (the ``blindspot.track`` schema) and the JSON-ready metrics of
    data/driving/track.json. Raises ValueError naming ``where`` and the missing columns of
    ``points`` (:data:`POINT_COLUMNS`), or as the functions it calls (``tcfg.moving`` null).
    """
    check_columns(points, POINT_COLUMNS, where)
    if tcfg.moving is None:
        raise ValueError("tracker.moving: the driving scenes need the moving-object test's "
                         "settings (conf/tracker/gnn_cv.yaml), found null")
    mv = tcfg.moving
    last = truth.groupby("scene").frame.max().to_dict()
    pts, ego = tracker_input(truth, points)
    tracks = track_points(pts, tcfg, jobs=jobs, source=where)
    kinematic = moving_tracks(tracks, mv.speed_mps, mv.probability)
    tracks["moving"] = moving_tracks(tracks, ego=ego, **moving_test_settings(mv),
                                     points=points[["scene", "frame", "x_m", "y_m", "static"]])
    labels = track_labels(tracks, points, tcfg.cluster_eps_m)
    metrics = {"tracker": {**track_counts(tracks), "classifier": {
        "kinematic": confusion(tracks, kinematic, labels, truth),
        "doppler": confusion(tracks, tracks.moving.to_numpy(), labels, truth),
        **{f"moving_{k}": v for k, v in moving_test_settings(mv).items()
           if isinstance(v, (int, float)) and not isinstance(v, bool)}}},
        "doppler_spread": doppler_spread_by_label(monte_carlo_objects(points, tcfg))}
    tables = {"tracks": tracks}
    refs = {"oracle": (own_points(points), f"{where} (own points by source)"),
            "noisy_position": (noisy_position_points(truth, oracle_cfg.meas_std_m, seed),
                              "noisy position points")}
    for name, (p, w) in refs.items():
        tables[f"tracks_{name}"] = oracle_tracks(p, oracle_cfg, frame_period_s, last_frame=last,
                                                 where=w)
        metrics[name] = track_counts(tables[f"tracks_{name}"])
    return tables, metrics


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
        (``group``, ``frame``) with ``ego_x_m``, ``ego_y_m``, ``ego_yaw_deg``.
    """
    frames = truth[["scene", "frame", "time_s"]].drop_duplicates(["scene", "frame"])
    pose = (truth.groupby(["scene", "frame"], as_index=False)
            [["ego_x_m", "ego_y_m", "ego_yaw_deg"]].first().rename(columns={"scene": "group"}))
    pts = (frames.merge(points[["scene", "frame", "x_m", "y_m", "velocity_over_ground_mps"]],
                        on=["scene", "frame"], how="left").rename(columns={"scene": "group"})
           .merge(pose.rename(columns={"ego_x_m": "sensor_x_m", "ego_y_m": "sensor_y_m",
                                       "ego_yaw_deg": "sensor_heading_deg"}),
                  on=["group", "frame"], how="left"))
    return pts, pose


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


def track_counts(tracks):
    """Tracks, rows, confirmed rows (and moving tracks and rows with a ``moving`` column)."""
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
