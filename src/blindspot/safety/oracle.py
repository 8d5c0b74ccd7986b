"""The "oracle association" reference tracks: each pedestrian's own measured points (associated by
their truth label, so no association errors and no clutter tracks), filtered by a constant-velocity
Kalman filter (:func:`blindspot.kalman.kalman_filter`, :func:`~blindspot.kalman.cv_model`).

An upper bound for a real tracker on the same points (it knows which point is whose), kept as a
reference row of the safety results, never as the headline. The output has the schema of
``blindspot.track.track_points`` (one row per live track and frame): ``group``, ``frame``,
``time_s``, ``track_id``, ``x_m``, ``y_m``, ``vx_mps``, ``vy_mps``, ``cov_xx``, ``cov_xy``,
``cov_yy``, ``cov_vxvx``, ``cov_vxvy``, ``cov_vyvy``, ``confirmed``, ``coasting`` (plus
``pedestrian``, the truth label).

Track management: a track starts at a pedestrian's first point (prior: that position, zero
velocity, ``init_vel_std_mps``), is confirmed from its ``confirm_points``-th point, coasts
(prediction only) through frames without a point and is deleted after ``max_coast_frames``
such frames in a row; a pedestrian seen again later starts a new track.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from blindspot.arrays import check_number
from blindspot.kalman import cv_model, kalman_filter
from blindspot.safety.config import OracleConfig
from blindspot.tables import check_columns

__all__ = ["TRACK_COLUMNS", "oracle_tracks", "noisy_position_points", "true_state_tracks"]

TRACK_COLUMNS = ("group", "frame", "time_s", "track_id", "x_m", "y_m", "vx_mps", "vy_mps",
                 "cov_xx", "cov_xy", "cov_yy", "cov_vxvx", "cov_vxvy", "cov_vyvy", "confirmed",
                 "coasting", "cov_xvx", "cov_xvy", "cov_yvx", "cov_yvy")


def oracle_tracks(points: pd.DataFrame, cfg: OracleConfig, frame_period_s: float,
                  last_frame: int | dict | None = None, where: str = "points") -> pd.DataFrame:
    """Tracks of the measured points of each (scene, pedestrian).

    points: columns scene, pedestrian, frame (int), x_m, y_m (world frame, m); one row per
    pedestrian and frame at most. last_frame: no track row after this frame (the scenes' end;
    an int, or a dict scene -> frame); None = no limit. Returns a DataFrame of :data:`TRACK_COLUMNS` + ``pedestrian`` sorted by
    group, track_id, frame. Raises ValueError naming ``where`` for missing columns or duplicate
    (scene, pedestrian, frame) rows.
    """
    check_number(frame_period_s, "frame_period_s", gt=0.0, unit="s", who="oracle_tracks")
    check_columns(points, {"scene", "pedestrian", "frame", "x_m", "y_m"}, where)
    p = points.sort_values(["scene", "pedestrian", "frame"]).reset_index(drop=True)
    if p.duplicated(["scene", "pedestrian", "frame"]).any():
        raise ValueError(f"{where}: more than one point per (scene, pedestrian, frame)")
    if p.empty:
        return pd.DataFrame(columns=[*TRACK_COLUMNS, "pedestrian"])
    # a new track where the pedestrian changes or after more than max_coast_frames misses
    key = p.scene + "\x00" + p.pedestrian
    gap = p.frame.diff().to_numpy()
    new = (key != key.shift()).to_numpy() | (gap - 1 > cfg.max_coast_frames)
    tid = np.cumsum(new) - 1                                             # global track index
    f0 = p.frame.groupby(tid).min().to_numpy()
    f1 = p.frame.groupby(tid).max().to_numpy()
    end = f1 + cfg.max_coast_frames
    if isinstance(last_frame, dict):           # per scene
        scene0 = p.scene.to_numpy()[np.flatnonzero(new)]
        end = np.minimum(end, np.array([last_frame[s] for s in scene0]))
    elif last_frame is not None:
        end = np.minimum(end, last_frame)
    n = end - f0 + 1                                                     # rows per track
    B, T = len(f0), int(n.max())
    obs = np.full((B, T, 2), np.nan)
    obs[tid, p.frame.to_numpy() - f0[tid]] = p[["x_m", "y_m"]].to_numpy()
    F, Q, H, R = cv_model(frame_period_s, cfg.process_psd, cfg.meas_std_m)
    m0 = np.hstack([obs[:, 0], np.zeros((B, 2))])
    P0 = np.diag([cfg.meas_std_m**2] * 2 + [cfg.init_vel_std_mps**2] * 2)
    res = kalman_filter(obs, F, Q, H, R, m0, P0)
    live = np.arange(T)[None, :] < n[:, None]                            # (B, T)
    b, t = np.nonzero(live)
    seen = np.isfinite(obs).all(-1)
    count = np.cumsum(seen, axis=1)
    m, P = res.means[b, t], res.covs[b, t]
    first = np.flatnonzero(new)
    scene = p.scene.to_numpy()[first][b]
    # track ids numbered 0.. within each scene, in order of appearance
    scene_first = pd.Series(p.scene.to_numpy()[first])
    local = scene_first.groupby(scene_first).cumcount().to_numpy()
    frame = f0[b] + t
    out = pd.DataFrame({
        "group": scene, "frame": frame, "time_s": frame * frame_period_s,
        "track_id": local[b], "x_m": m[:, 0], "y_m": m[:, 1], "vx_mps": m[:, 2],
        "vy_mps": m[:, 3], "cov_xx": P[:, 0, 0], "cov_xy": P[:, 0, 1], "cov_yy": P[:, 1, 1],
        "cov_vxvx": P[:, 2, 2], "cov_vxvy": P[:, 2, 3], "cov_vyvy": P[:, 3, 3],
        "confirmed": count[b, t] >= cfg.confirm_points, "coasting": ~seen[b, t],
        "cov_xvx": P[:, 0, 2], "cov_xvy": P[:, 0, 3], "cov_yvx": P[:, 1, 2],
        "cov_yvy": P[:, 1, 3],
        "pedestrian": p.pedestrian.to_numpy()[first][b],
    })
    return out.sort_values(["group", "track_id", "frame"]).reset_index(drop=True)


def noisy_position_points(truth: pd.DataFrame, meas_std_m: float, seed: int) -> pd.DataFrame:
    """The points an ideal detector would give: every pedestrian's true reference point at every
    frame its line of sight is clear (``occluded`` False), plus white Gaussian noise of
    ``meas_std_m`` per coordinate (one generator seeded by ``seed``). Columns scene, pedestrian,
    frame, time_s, x_m, y_m: the input of :func:`oracle_tracks` for the "noisy_position"
    reference (perception removed as a cause: what the warning logic does when the pedestrian
    is seen whenever visible)."""
    check_number(meas_std_m, "meas_std_m", ge=0.0, unit="m", who="noisy_position_points")
    v = truth.loc[~truth.occluded.astype(bool), ["scene", "pedestrian", "frame", "time_s",
                                                "x_m", "y_m"]].reset_index(drop=True)
    noise = np.random.default_rng(seed).normal(0.0, meas_std_m, (len(v), 2))
    return v.assign(x_m=v.x_m + noise[:, 0], y_m=v.y_m + noise[:, 1])


def true_state_tracks(truth: pd.DataFrame, pos_std_m: float = 0.1,
                      vel_std_mps: float = 0.2) -> pd.DataFrame:
    """The "true state in line of sight" reference input (issue 40): every pedestrian's true
    position and velocity (truth columns x_m, y_m, vx_mps, vy_mps) at every frame its line of
    sight is clear (``occluded`` False), one track per visible stretch (a pedestrian hidden, or
    missing from a frame, and seen again starts a new track, so a predictor that fits a track's
    history never spans the gap; ids 0.. within each scene), with an isotropic covariance of
    ``pos_std_m`` and ``vel_std_mps``: what a perfect sensor that knows a pedestrian's state
    whenever it is in sight hands the decision (the physical bound of the decision rule, scored
    with the ``track_state`` predictor). Every pedestrian counts, the ones that never cross the
    ego's path included, and every row is confirmed and ``moving`` (a standing pedestrian too:
    the sensor knows its velocity), so the row's false activations are the rule's own.
    Columns :data:`TRACK_COLUMNS` + moving, pedestrian; sorted by group, track_id, frame.
    Raises ValueError naming the missing truth columns, an ``occluded`` column that is not
    boolean, duplicate (scene, pedestrian, frame) rows or a non-positive spread."""
    check_number(pos_std_m, "pos_std_m", gt=0.0, unit="m", who="true_state_tracks")
    check_number(vel_std_mps, "vel_std_mps", gt=0.0, unit="m/s", who="true_state_tracks")
    if not isinstance(truth, pd.DataFrame):
        raise TypeError(f"true_state_tracks: truth: expected a pandas DataFrame, found "
                        f"{type(truth).__name__}")
    check_columns(truth, {"scene", "pedestrian", "frame", "time_s", "x_m", "y_m", "vx_mps",
                          "vy_mps", "occluded"}, "truth", who="true_state_tracks")
    if not pd.api.types.is_bool_dtype(truth.occluded):
        raise ValueError(f"true_state_tracks: truth.occluded: expected booleans, found dtype "
                         f"{truth.occluded.dtype}")
    if truth.duplicated(["scene", "pedestrian", "frame"]).any():
        raise ValueError("true_state_tracks: truth has more than one row per (scene, "
                         "pedestrian, frame)")
    t = truth.sort_values(["scene", "pedestrian", "frame"]).reset_index(drop=True)
    seen = ~t.occluded.to_numpy(bool)
    who = t.groupby(["scene", "pedestrian"], sort=False, observed=True).ngroup().to_numpy()
    new_who = np.r_[True, who[1:] != who[:-1]]
    gap = np.r_[True, np.diff(t.frame.to_numpy(np.int64)) != 1]
    # a stretch starts at a visible row whose predecessor is another pedestrian's, hidden or
    # not the previous frame
    start = seen & (new_who | gap | ~np.r_[False, seen[:-1]])
    stretch = np.cumsum(start)[seen] - 1
    v = t[seen]
    # numbered 0.. within each scene (rows are sorted by scene, so a scene's stretches follow)
    scene = v.scene.to_numpy()
    local = stretch - pd.Series(stretch).groupby(scene).transform("min").to_numpy(np.int64)
    n = len(v)
    out = pd.DataFrame({
        "group": scene, "frame": v.frame.to_numpy(np.int64), "time_s": v.time_s.to_numpy(float),
        "track_id": local.astype(np.int64), "x_m": v.x_m.to_numpy(float),
        "y_m": v.y_m.to_numpy(float), "vx_mps": v.vx_mps.to_numpy(float),
        "vy_mps": v.vy_mps.to_numpy(float), "cov_xx": np.full(n, pos_std_m ** 2),
        "cov_xy": np.zeros(n), "cov_yy": np.full(n, pos_std_m ** 2),
        "cov_vxvx": np.full(n, vel_std_mps ** 2), "cov_vxvy": np.zeros(n),
        "cov_vyvy": np.full(n, vel_std_mps ** 2), "confirmed": np.ones(n, bool),
        "coasting": np.zeros(n, bool), "cov_xvx": np.zeros(n), "cov_xvy": np.zeros(n),
        "cov_yvx": np.zeros(n), "cov_yvy": np.zeros(n), "moving": np.ones(n, bool),
        "pedestrian": v.pedestrian.to_numpy()})
    return out.sort_values(["group", "track_id", "frame"]).reset_index(drop=True)
