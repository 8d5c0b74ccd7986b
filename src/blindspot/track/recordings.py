"""The tracker on real point-cloud recordings: read, drop static clutter and what lies behind the
scene's walls, track (with the points' radial speeds and the sensor's Doppler notch), score.

For a recording with a reference tracker (TI's gtrack targets in a people-counting log) the
confirmed tracks are scored against it with CLEAR MOT (:mod:`blindspot.track.evaluation`). For
one without (RadHAR) the numbers that exist without a reference are given: how many tracks were
confirmed, how much of the walker's time the longest one covers, and whether any confirmed track
stands still (static clutter that got through).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from blindspot.radar.capture.radhar import read_radhar
from blindspot.radar.capture.ti_gtrack import read_ti_gtrack
from blindspot.tables import check_columns
from blindspot.track.config import TrackedRecording, TrackerConfig
from blindspot.track.evaluation import compare_tracks
from blindspot.track.tracker import DOPPLER_COLUMN, track_points

__all__ = ["STATIC_TRACK_EXTENT_M", "RecordingTracks", "load_points", "track_recording",
           "tracker_input"]

#: A confirmed track whose positions all stay within this distance of their mean stands still:
#: static clutter that got through (a person shifting on the spot moves about 0.3 m).
STATIC_TRACK_EXTENT_M = 0.3


@dataclass(frozen=True)
class RecordingTracks:
    """What :func:`track_recording` returns.

    Attributes:
        points: every point of the recording: ``frame``, ``time_s``, ``x_m``, ``y_m``,
            ``velocity_mps``, ``static`` (dropped before tracking).
        tracks: :func:`blindspot.track.track_points` output (all live tracks, tentative too).
        reference: reference tracks (``frame``, ``track_id``, ``x_m``, ``y_m``, ...) or None.
        metrics: the summary (see :func:`track_recording`).
    """

    points: pd.DataFrame
    tracks: pd.DataFrame
    reference: pd.DataFrame | None
    metrics: dict


def _resolve(path: str, shared_dir: Path) -> Path:
    p = Path(path)
    return p if p.is_absolute() else Path(shared_dir) / p


def load_points(rec: TrackedRecording, shared_dir: Path) -> tuple[pd.DataFrame, pd.DataFrame | None]:
    """The recording's points (one row per point, plus one NaN row per frame without any, so
    the tracker steps through it) and its reference tracks (None without a reference).

    Columns of the points: ``frame``, ``time_s``, ``x_m``, ``y_m`` (m, the recording's sensor
    frame), ``velocity_mps`` (radial, m/s), ``static`` (``|velocity| <= static_speed_mps``),
    ``outside`` (beyond the scene's ``boundary_box_m``: behind a wall).
    """
    path = _resolve(rec.path, shared_dir)
    reference = None
    if rec.kind == "ti_gtrack":
        log = read_ti_gtrack(path, rec.frame_period_s)
        pts = log.points.rename(columns={"doppler_mps": "velocity_mps"})
        frames = pd.DataFrame({"frame": log.frames,
                               "time_s": (log.frames - log.frames[0]) * rec.frame_period_s})
        reference = log.targets
    else:
        pts = read_radhar(path)
        frames = pts.drop_duplicates("frame")[["frame", "time_s"]]
        if rec.frame_period_s is not None:
            pts = pts.assign(time_s=(pts.frame - pts.frame.min()) * rec.frame_period_s)
            frames = frames.assign(time_s=(frames.frame - frames.frame.min()) * rec.frame_period_s)
    pts = pts[["frame", "time_s", "x_m", "y_m", "velocity_mps"]].copy()
    pts["static"] = (False if rec.static_speed_mps is None
                     else pts.velocity_mps.abs() <= rec.static_speed_mps)
    box = rec.boundary_box_m
    pts["outside"] = (False if box is None
                      else ~(pts.x_m.between(box[0], box[1]) & pts.y_m.between(box[2], box[3])))
    empty = frames[~frames.frame.isin(pts.frame)].assign(x_m=np.nan, y_m=np.nan,
                                                         velocity_mps=np.nan, static=False,
                                                         outside=False)
    pts = pd.concat([pts, empty], ignore_index=True).sort_values("frame", kind="stable")
    return pts.reset_index(drop=True), reference


def tracker_input(points: pd.DataFrame, *, doppler: bool = True) -> pd.DataFrame:
    """The tracker's input (:func:`blindspot.track.track_points`) from a recording's points:
    the points neither ``static`` nor ``outside`` (where those columns exist), with ``frame``,
    ``time_s``, ``x_m``, ``y_m``, the sensor's position columns where the points carry them,
    and with ``doppler`` their radial speed over ground (``velocity_over_ground_mps``, or a
    still sensor's own ``velocity_mps``: the range-rate updates and a new track's velocity);
    a frame left without a point is one NaN row, so tracks coast through it."""
    check_columns(points, ("frame", "time_s", "x_m", "y_m"), "points", who="tracker_input")
    if doppler and not {DOPPLER_COLUMN, "velocity_mps"} & set(points.columns):
        raise ValueError(f"tracker_input: points: with doppler, expected a radial speed column "
                         f"({DOPPLER_COLUMN!r} or 'velocity_mps'); found {list(points.columns)}")
    keep = np.ones(len(points), bool)
    for col in ("static", "outside"):
        if col in points.columns:
            keep &= ~points[col].fillna(False).astype(bool).to_numpy()
    pose = [c for c in ("sensor_x_m", "sensor_y_m") if c in points.columns]
    cols = ["frame", "time_s", "x_m", "y_m"] + pose
    moving = points[keep].dropna(subset=["x_m"])
    if doppler:
        if DOPPLER_COLUMN not in moving.columns:
            moving = moving.assign(**{DOPPLER_COLUMN: moving.velocity_mps})
        cols.append(DOPPLER_COLUMN)
    frames = points.drop_duplicates("frame")[["frame", "time_s"] + pose]
    bare = frames[~frames.frame.isin(moving.frame)].assign(x_m=np.nan, y_m=np.nan)
    return pd.concat([moving[cols], bare]).sort_values("frame", kind="stable")


def track_recording(rec: TrackedRecording, tracker: TrackerConfig, shared_dir: Path, *,
                    doppler: bool = True) -> RecordingTracks:
    """Track one recording and summarise it (``doppler``: the points' radial speeds reach the
    tracker, :func:`tracker_input`).

    Returns:
        :class:`RecordingTracks` whose ``metrics`` holds ``n_frames``, ``n_points``,
        ``static_points_dropped`` and ``outside_points_dropped`` (fractions: static clutter,
        beyond the walls), ``n_tracks`` (confirmed), ``static_tracks``
        (confirmed tracks within :data:`STATIC_TRACK_EXTENT_M` of their mean throughout),
        ``longest_track_coverage`` (frames the longest confirmed track is live over the frames
        from the first to the last moving point), ``longest_track_to_points_median_m`` (without
        a reference: median distance from the longest track to the centroid of each frame's
        moving points), and against a reference: ``mota``,
        ``motp`` (m), ``id_switches``, ``idf1``, ``misses``, ``false_positives``,
        ``n_reference``, ``median_distance_m``, ``gate_m``, ``same_people`` (each reference
        track matched by exactly one of ours, ours by one reference); None where no reference.
    """
    points, reference = load_points(rec, shared_dir)
    moving = tracker_input(points, doppler=doppler)
    tracks = track_points(moving, tracker, source=str(_resolve(rec.path, shared_dir)),
                          min_detectable_speed_mps=rec.min_detectable_speed_mps)
    conf = tracks[tracks.confirmed]
    seen = moving.dropna(subset=["x_m"])
    span = (seen.frame.min(), seen.frame.max()) if len(seen) else (0, -1)
    span_frames = points.frame[(points.frame >= span[0]) & (points.frame <= span[1])].nunique()
    extent = conf.groupby("track_id").apply(
        lambda t: float(np.hypot(t.x_m - t.x_m.mean(), t.y_m - t.y_m.mean()).max()),
        include_groups=False) if len(conf) else pd.Series(dtype=float)
    sizes = conf.groupby("track_id").size()
    metrics = {
        "n_frames": int(points.frame.nunique()),
        "n_points": int(points.x_m.notna().sum()),
        "static_points_dropped": float(points.static[points.x_m.notna()].mean()),
        "outside_points_dropped": float(points.outside[points.x_m.notna()].mean()),
        "n_tracks": int(conf.track_id.nunique()),
        "static_tracks": int((extent < STATIC_TRACK_EXTENT_M).sum()),
        "longest_track_coverage": (float(sizes.max() / span_frames)
                                   if len(sizes) and span_frames else 0.0),
    }
    # without a reference: how far the longest track is from the centroid of the frame's
    # moving points (a single walker: the track should sit on them)
    metrics["longest_track_to_points_median_m"] = None
    if reference is None and len(sizes):
        main = conf[conf.track_id == sizes.idxmax()].set_index("frame")[["x_m", "y_m"]]
        cen = seen.dropna(subset=["x_m"]).groupby("frame")[["x_m", "y_m"]].mean()
        both = cen.join(main, how="inner", lsuffix="_pts")
        metrics["longest_track_to_points_median_m"] = float(np.median(
            np.hypot(both.x_m_pts - both.x_m, both.y_m_pts - both.y_m)))
    for key in ("mota", "motp", "id_switches", "idf1", "misses", "false_positives",
                "n_reference", "median_distance_m", "gate_m", "same_people"):
        metrics[key] = None
    if reference is not None and rec.reference_gate_m is not None:
        mot = compare_tracks(conf, reference, gate_m=rec.reference_gate_m)
        matches = mot.pop("matches")
        for key in ("mota", "motp", "idf1", "median_distance_m"):
            metrics[key] = None if mot[key] is None else float(mot[key])
        for key in ("id_switches", "misses", "false_positives", "n_reference"):
            metrics[key] = int(mot[key])
        metrics["gate_m"] = rec.reference_gate_m
        per_ref = matches.groupby("ref_id").track_id.nunique()
        per_trk = matches.groupby("track_id").ref_id.nunique()
        metrics["same_people"] = bool(
            len(per_ref) == reference.track_id.nunique() == metrics["n_tracks"]
            and (per_ref == 1).all() and (per_trk == 1).all())
    return RecordingTracks(points, tracks, reference, metrics)
