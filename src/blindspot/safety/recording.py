"""A real recording from its capture to a decision (issue 44): the recordings stage's work.

Per recording (an entry of the Hydra group ``recordings``, :class:`RecordingEntry`):

1. **points**: a raw capture (TI cascade, DCA1000, OpenRadar ``.npy``) goes through the detection
   chain (:func:`blindspot.dsp.recording.detect_recording`) and each detection with an angle
   becomes a point, ``x = R sin(theta)``, ``y = R cos(theta)`` (radar at the origin, boresight
   +y); a point-cloud log (TI people-counting TLV, RadHAR text) is read as it is
   (:func:`blindspot.track.recordings.load_points`); a point table (``points_table``: Parquet
   or CSV with ``frame``, ``time_s``, ``x_m``, ``y_m``, ``velocity_mps`` and, for a car,
   ``ego_speed_mps``) likewise. Static clutter is flagged ``static`` and left out of tracking:
   from a still radar ``|v| <= static_speed_mps``; from a moving one (``moving: true``, the
   radar looking along the car's heading) the points on the static world's Doppler curve
   ``v = -v_ego cos(theta)`` within ``static_speed_mps``, with ``v_ego`` the recording's speed
   column or the radar's own estimate (:func:`blindspot.dsp.ego_motion.estimate_ego_speed`).
   A moving radar's points are put in a world frame by the ego's travelled distance.
2. **tracks**: the project's tracker (``tracker`` group, the entry's ``tracker`` keys over it;
   :func:`blindspot.track.tracker.track_points`; for the point-cloud logs exactly the
   real_tracking stage's :func:`~blindspot.track.recordings.track_recording`, with TI's tracks
   as its reference).
3. **predictions**: each confirmed track's predicted path at every frame (from a car: the
   rows its decision reads, none coasting past ``warning.max_coast_s``), with its Gaussian
   distribution per step (``warning.horizon_s`` ahead; the ``eval.kalman`` constant-velocity
   Kalman filter at the recording's frame period, :func:`blindspot.traj.baselines.
   kalman_baseline`, the project's calibrated Kalman settings).
4. **decisions** (a recording made from a car only): per frame the largest collision
   probability over the tracks against the ego's swept footprint
   (:func:`blindspot.safety.risk.collision_risk`) and the warning / AEB request where it
   reaches ``warning.warning_threshold`` / ``warning.aeb_threshold``.

Bad input raises :class:`RecordingError` naming the recording's file: time stamps that go
backwards, a log without any point, a recording shorter than the predictor's history (with the
``stop_at`` that would accept it); the readers' own errors (a profile that does not match the
capture's size) are re-raised with the recording's name. Frames without points are kept: tracks
coast through them, and the summary counts them.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from blindspot.dsp.ego_motion import EgoMotionError, estimate_ego_speed
from blindspot.dsp.recording import detect_recording
from blindspot.safety.predict import decision_rows, track_histories
from blindspot.safety.risk import EgoShape, collision_risk
from blindspot.tables import check_columns
from blindspot.track.config import TrackedRecording, TrackerConfig
from blindspot.track.recordings import load_points, track_recording, tracker_input
from blindspot.track.tracker import track_points
from blindspot.typed_config import ConfigError, TypedConfig, setting

__all__ = ["POINT_LOG_KINDS", "RAW_KINDS", "STEPS", "RecordingEntry", "RecordingError",
           "RecordingResult", "check_points", "decide", "detection_points", "predict_tracks",
           "run_recording"]

#: Raw ADC captures (blindspot.radar.capture.open_recording) and point-cloud logs.
RAW_KINDS = ("ti_cascade", "dca1000", "dca1000_packets", "openradar_npy")
POINT_LOG_KINDS = ("ti_gtrack", "radhar", "points_table")
#: How far a recording goes (``stop_at``): each step needs the ones before it.
STEPS = ("points", "tracks", "predictions", "decisions")
#: The 90 % region of a 2-D Gaussian: Mahalanobis radius^2 = chi-square(2) quantile 0.9.
CHI2_2DOF_90 = 4.605170185988092


class RecordingError(ValueError):
    """A recording is not what the chain expects (the message names the file)."""


@dataclass(frozen=True)
class RecordingEntry(TypedConfig):
    """One entry of the Hydra group ``recordings`` (``conf/recordings/``): see the yaml files.

    Fields: ``name``; ``kind`` (:data:`RAW_KINDS` or :data:`POINT_LOG_KINDS`); ``path``
    (relative to ``paths.shared_dir`` or absolute); ``frame_period_s`` (s; null: the file's
    stamps, or the radar profile's period for a raw capture); ``static_speed_mps`` (the static
    clutter tolerance, m/s; null keeps every point); ``min_detectable_speed_mps`` (a still
    radar's Doppler notch, :func:`blindspot.track.track_points`) and ``boundary_box_m`` (a
    point-cloud log's walls, as :class:`~blindspot.track.config.TrackedRecording`'s);
    ``moving`` (recorded from a car driving along the radar's boresight: the ego speed, a world
    frame and the decisions);
    ``speed_column`` (the point table's ego-speed column; null: estimated by the radar);
    ``stop_at`` (:data:`STEPS`); ``reference_gate_m`` (TI's tracks, CLEAR MOT gate, m);
    ``ego_width_m``, ``ego_length_m`` (the car, m); ``animate`` (the recordings stage draws
    ``animation.gif``, every ``animate_every``-th frame, at most 150). The raw kinds'
    ``radar``, ``options``, ``cfar``, ``doa``, ``detect`` and every entry's ``tracker`` mapping
    are read as they are.
    """

    IGNORED = ("radar", "options", "cfar", "doa", "detect", "tracker")

    name: str = setting()
    kind: str = setting(choices=RAW_KINDS + POINT_LOG_KINDS)
    path: str = setting()
    frame_period_s: float | None = setting(None, gt=0.0, le=60.0)
    static_speed_mps: float | None = setting(None, ge=0.0, le=100.0)
    min_detectable_speed_mps: float | None = setting(None, gt=0.0, le=100.0)
    boundary_box_m: tuple[float, float, float, float] | None = setting(None, ge=-1000.0,
                                                                         le=1000.0)
    moving: bool = setting(False)
    speed_column: str | None = setting(None)
    stop_at: str = setting("decisions", choices=STEPS)
    reference_gate_m: float | None = setting(None, gt=0.0, le=100.0)
    ego_width_m: float = setting(1.815, gt=0.0, le=5.0)
    ego_length_m: float = setting(4.358, gt=0.0, le=30.0)
    animate: bool = setting(False)
    animate_every: int = setting(4, ge=1, le=10_000)

    def validate(self) -> None:
        if not self.path:
            raise ConfigError("path", self.path, "a file or folder path")
        if self.kind == "ti_gtrack" and self.frame_period_s is None:
            raise ConfigError("frame_period_s", None, "a positive period (s): a ti_gtrack log "
                              "holds no time stamps")
        if self.min_detectable_speed_mps is not None and self.moving:
            raise ConfigError("min_detectable_speed_mps", self.min_detectable_speed_mps,
                              "null for a recording from a moving car (its static points are "
                              "kept for the ego-motion, so it has no Doppler notch)")
        box = self.boundary_box_m
        if box is not None and (self.kind not in ("ti_gtrack", "radhar") or self.moving):
            raise ConfigError("boundary_box_m", list(box), "null except for a ti_gtrack or "
                              f"radhar log from a still radar (kind {self.kind!r}, moving "
                              f"{self.moving})")


@dataclass
class RecordingResult:
    """points, tracks, predictions, decisions (None past ``stop_at``, decisions None for a still
    radar); detections and the first frame's maps of a raw capture (else None); TI's tracks
    (``reference``) or None; the summary (:func:`run_recording`)."""

    points: pd.DataFrame
    tracks: pd.DataFrame | None
    predictions: pd.DataFrame | None
    decisions: pd.DataFrame | None
    detections: pd.DataFrame | None
    first: Any
    reference: pd.DataFrame | None
    summary: dict


def _steps_to(entry: RecordingEntry, step: str) -> bool:
    return STEPS.index(entry.stop_at) >= STEPS.index(step)


def detection_points(det: pd.DataFrame, n_frames: int, frame_period_s: float) -> pd.DataFrame:
    """A raw capture's detections (frame, range_m, angle_deg, velocity_mps) -> points (frame,
    time_s, x_m, y_m, velocity_mps, azimuth_deg), one NaN row for a frame without any."""
    d = det.dropna(subset=["angle_deg"]) if "angle_deg" in det else det.iloc[:0]
    th = np.radians(d.angle_deg.to_numpy(float))
    r = d.range_m.to_numpy(float)
    pts = pd.DataFrame({"frame": d.frame.to_numpy(np.int64), "x_m": r * np.sin(th),
                        "y_m": r * np.cos(th), "velocity_mps": d.velocity_mps.to_numpy(float),
                        "azimuth_deg": d.angle_deg.to_numpy(float)})
    empty = np.setdiff1d(np.arange(n_frames), pts.frame.to_numpy())
    pts = pd.concat([pts, pd.DataFrame({"frame": empty})], ignore_index=True)
    pts = pts.sort_values("frame", kind="stable").reset_index(drop=True)
    return pts.assign(time_s=pts.frame * float(frame_period_s))


def _read_table(entry: RecordingEntry, path: Path) -> pd.DataFrame:
    if not path.is_file():
        raise RecordingError(f"recording {entry.name!r}: {path.name}: file not found "
                             "(expected a .parquet or .csv point table)")
    pts = pd.read_parquet(path) if path.suffix == ".parquet" else pd.read_csv(path)
    need = ["frame", "time_s", "x_m", "y_m", "velocity_mps"] + (
        [entry.speed_column] if entry.speed_column else [])
    check_columns(pts, need, f"recording {entry.name!r}: {path.name}", error=RecordingError,
                  note=f"expected {need}, found {list(pts.columns)}")
    return pts


def check_points(points: pd.DataFrame, where: str, min_frames: int) -> dict:
    """Check a recording's points (one row per point, NaN rows for frames without any) and
    return ``{"n_frames", "frames_without_points"}``. Raises RecordingError naming ``where``:
    time stamps not increasing with the frame, no point at all, fewer than ``min_frames``
    frames."""
    frames = points.drop_duplicates("frame").sort_values("frame")
    dt = np.diff(frames.time_s.to_numpy(float))
    if (~(dt > 0)).any():
        i = int(np.flatnonzero(~(dt > 0))[0])
        a, b = frames.iloc[i], frames.iloc[i + 1]
        raise RecordingError(f"{where}: time stamps go backwards: frame {int(b.frame)} at "
                             f"{b.time_s:.6g} s after frame {int(a.frame)} at {a.time_s:.6g} s; "
                             "expected time increasing with the frame")
    seen = points.dropna(subset=["x_m"])
    if seen.empty:
        raise RecordingError(f"{where}: no point in any of its {len(frames)} frames; expected "
                             "a point cloud (is it the right file, or all static clutter?)")
    if len(frames) < min_frames:
        raise RecordingError(f"{where}: {len(frames)} frames, fewer than the {min_frames} "
                             "frames the tracker needs to confirm a track (tracker.confirm_m at "
                             "this frame rate); record longer, or stop the recording at "
                             "'points' (stop_at: points)")
    empty = int(len(frames) - seen.frame.nunique())
    if empty:
        warnings.warn(f"{where}: {empty} of {len(frames)} frames hold no point; tracks coast "
                      "through them", stacklevel=2)
    return {"n_frames": int(len(frames)), "frames_without_points": empty}


def _ego_motion(entry: RecordingEntry, pts: pd.DataFrame, where: str) -> pd.DataFrame:
    """A moving radar: per frame ego speed (column or the radar's own estimate), the static
    flag on the ego-motion Doppler curve and the world frame (ego travelled along +y)."""
    az = (pts.azimuth_deg if "azimuth_deg" in pts
          else np.degrees(np.arctan2(pts.x_m, pts.y_m)))
    pts = pts.assign(azimuth_deg=az)
    if entry.speed_column:
        speed = pts.groupby("frame")[entry.speed_column].first()
    else:
        speed = {}
        for f, g in pts.dropna(subset=["x_m"]).groupby("frame"):
            try:
                speed[f] = estimate_ego_speed(g.velocity_mps.to_numpy(float),
                                              g.azimuth_deg.to_numpy(float))[0]
            except EgoMotionError:
                speed[f] = np.nan
        speed = pd.Series(speed, dtype=float)
    frames = pts.drop_duplicates("frame").set_index("frame").time_s.sort_index()
    v = speed.reindex(frames.index).interpolate(limit_direction="both").fillna(0.0)
    travelled = np.r_[0.0, np.cumsum(v.to_numpy()[:-1] * np.diff(frames.to_numpy()))]
    ego = pd.DataFrame({"frame": frames.index, "time_s": frames.to_numpy(),
                        "ego_speed_mps": v.to_numpy(), "ego_y_m": travelled})
    pts = pts.drop(columns=["ego_speed_mps", "ego_y_m"], errors="ignore").merge(
        ego[["frame", "ego_speed_mps", "ego_y_m"]], on="frame", how="left")
    tol = entry.static_speed_mps if entry.static_speed_mps is not None else 0.0
    curve = -pts.ego_speed_mps * np.cos(np.radians(pts.azimuth_deg))
    pts["static"] = (pts.velocity_mps - curve).abs() <= tol
    # the radial speed over ground (the tracker's Doppler) seen from the sensor's world position
    pts["velocity_over_ground_mps"] = pts.velocity_mps - curve
    pts["sensor_x_m"], pts["sensor_y_m"] = 0.0, pts.ego_y_m
    pts["y_m"] = pts.y_m + pts.ego_y_m            # sensor frame -> world frame
    return pts


def _track(points: pd.DataFrame, tracker: TrackerConfig, source: str,
           min_detectable_speed_mps: float | None) -> pd.DataFrame:
    """The tracker on a recording's moving points with their radial speed over ground (a still
    radar's own radial speed, or the ego-motion-compensated one from the sensor's position),
    behind the recording's Doppler notch if it has one."""
    return track_points(tracker_input(points), tracker, source=source,
                        min_detectable_speed_mps=min_detectable_speed_mps)


def predict_tracks(tracks: pd.DataFrame, predictor: Any, horizon: int, dt_s: float,
                   max_len: int, max_coast_s: float | None) -> tuple[pd.DataFrame, Any]:
    """Each track row a decision reads (:func:`blindspot.safety.predict.decision_rows`:
    confirmed, moving with that column, measured within ``max_coast_s``): its predicted path
    (long table frame, time_s, track_id, step, t_ahead_s, x_m, y_m, cov_xx, cov_xy, cov_yy, the
    forecast (B, H) of the rows in that order, and those rows)."""
    tr = tracks.assign(group=0).sort_values(["track_id", "frame"]).reset_index(drop=True)
    keep = decision_rows(tr, dt_s, max_coast_s)
    rows = tr[keep].reset_index(drop=True)
    cols = ["frame", "time_s", "track_id", "step", "t_ahead_s", "x_m", "y_m", "cov_xx",
            "cov_xy", "cov_yy"]
    if rows.empty:
        return pd.DataFrame({c: pd.Series(dtype=float) for c in cols}), None, rows
    fc = predictor.predict_distribution(track_histories(tr, max_len)[keep], horizon)
    B, H = fc.mean.shape[:2]
    step = np.tile(np.arange(1, H + 1), B)
    out = pd.DataFrame({
        "frame": np.repeat(rows.frame.to_numpy(), H), "time_s": np.repeat(rows.time_s, H),
        "track_id": np.repeat(rows.track_id.to_numpy(), H), "step": step,
        "t_ahead_s": step * dt_s, "x_m": fc.mean[..., 0].ravel(), "y_m": fc.mean[..., 1].ravel(),
        "cov_xx": fc.cov[..., 0, 0].ravel(), "cov_xy": fc.cov[..., 0, 1].ravel(),
        "cov_yy": fc.cov[..., 1, 1].ravel()})
    return out, fc, rows


def decide(forecast: Any, rows: pd.DataFrame, ego: pd.DataFrame, dt_s: float, shape: EgoShape,
           warning: Any) -> pd.DataFrame:
    """Per frame of ``ego`` (frame, time_s, ego_speed_mps, ego_y_m): the largest collision
    probability over the predicted tracks (``track_id`` of it, -1 none), ``warning`` and
    ``aeb`` (the request) where it reaches the ``warning`` group's thresholds."""
    out = ego[["frame", "time_s", "ego_speed_mps", "ego_y_m"]].copy()
    out["p_collision"], out["track_id"] = 0.0, -1
    if forecast is not None and len(rows):
        e = rows[["frame"]].merge(ego, on="frame", how="left")
        xy = np.stack([np.zeros(len(e)), e.ego_y_m.to_numpy(float)], axis=1)
        r = collision_risk(forecast, xy, np.zeros(len(e)), e.ego_speed_mps.to_numpy(float),
                           dt_s, shape, margin_m=warning.pedestrian_radius_m,
                           method=warning.probability)
        best = (pd.DataFrame({"frame": rows.frame, "track_id": rows.track_id,
                              "p": r.p_collision}).sort_values("p", ascending=False)
                .drop_duplicates("frame").set_index("frame"))
        out["p_collision"] = best.p.reindex(out.frame).fillna(0.0).to_numpy()
        out["track_id"] = best.track_id.reindex(out.frame).fillna(-1).astype(int).to_numpy()
    out["warning"] = out.p_collision >= warning.warning_threshold
    out["aeb"] = out.p_collision >= warning.aeb_threshold
    return out.reset_index(drop=True)


def _first(dec: pd.DataFrame, col: str) -> float | None:
    hit = dec[dec[col]]
    return float(hit.time_s.iloc[0]) if len(hit) else None


def run_recording(entry: RecordingEntry, rec_cfg: Any, path: Path, groups: Any,
                  tracker: TrackerConfig, predictor_for, warning: Any, *,
                  progress: bool = False) -> RecordingResult:
    """One recording through the chain (module docstring) up to ``entry.stop_at``.

    rec_cfg: the raw entry (its ``radar``, ``options``, chain overrides); path: the file or
    folder; groups: the composed config (for the detection chain); predictor_for: frame period
    (s) -> probabilistic predictor; warning: the ``warning`` group (horizon, thresholds, risk).
    """
    where = f"recording {entry.name!r} ({path.name})"
    det = first = reference = None
    summary: dict = {"file": entry.path if not Path(entry.path).is_absolute() else path.name,
                     "kind": entry.kind, "moving": entry.moving, "stop_at": entry.stop_at,
                     "n_tracks": None}
    try:
        if entry.kind in RAW_KINDS:
            det, first, s = detect_recording(entry.name, rec_cfg, path, groups, progress=progress)
            summary.update({k: s[k] for k in ("detections_per_frame", "noise_floor_db")})
            dt = float(entry.frame_period_s or rec_cfg.radar.frame_period_s)
            pts = detection_points(det, s["n_frames"], dt)
        elif entry.kind == "points_table":
            pts = _read_table(entry, path)
            if entry.frame_period_s is not None:
                pts = pts.assign(time_s=(pts.frame - pts.frame.min()) * entry.frame_period_s)
        else:
            tr_rec = TrackedRecording(name=entry.name, kind=entry.kind, path=str(path),
                                      frame_period_s=entry.frame_period_s,
                                      static_speed_mps=entry.static_speed_mps,
                                      min_detectable_speed_mps=entry.min_detectable_speed_mps,
                                      boundary_box_m=entry.boundary_box_m,
                                      reference_gate_m=entry.reference_gate_m)
            pts, reference = load_points(tr_rec, path.parent)
    except (OSError, ValueError) as exc:
        if isinstance(exc, RecordingError):
            raise
        raise RecordingError(f"{where}: {exc}") from exc
    if entry.moving:
        pts = _ego_motion(entry, pts, where)
    elif "static" not in pts or entry.kind in RAW_KINDS + ("points_table",):
        tol = entry.static_speed_mps
        pts["static"] = (pts.velocity_mps.abs() <= tol).to_numpy() if tol is not None else False
    pts["static"] = pts.static.fillna(False).astype(bool)
    dts = np.diff(np.sort(pts.time_s.dropna().unique()))
    dt = float(np.median(dts)) if len(dts) else float(entry.frame_period_s or 0.1)
    # the fewest frames that can confirm a track at this frame period (tracker.count_period_s)
    need = tracker.counts_at(dt)[0] if _steps_to(entry, "tracks") else 1
    horizon = max(1, int(round(warning.horizon_s / dt)))
    summary.update(check_points(pts, where, need), frame_period_s=dt,
                   n_points=int(pts.x_m.notna().sum()),
                   static_points=int((pts.static & pts.x_m.notna()).sum()))
    result = RecordingResult(pts, None, None, None, det, first, reference, summary)
    if not _steps_to(entry, "tracks"):
        return result
    if entry.kind in ("ti_gtrack", "radhar") and not entry.moving:
        res = track_recording(tr_rec, tracker, path.parent)     # real_tracking's own function
        result.tracks = res.tracks
        summary.update({k: v for k, v in res.metrics.items()
                        if k not in ("n_frames", "n_points")})
    else:
        result.tracks = _track(pts, tracker, str(path.name), entry.min_detectable_speed_mps)
        summary["n_tracks"] = int(result.tracks[result.tracks.confirmed].track_id.nunique())
    if not _steps_to(entry, "predictions"):
        return result
    max_len = int(round(warning.max_history_s / dt))
    decides = _steps_to(entry, "decisions") and entry.moving
    # a recording that decides predicts the rows its decision reads (no coasting past
    # warning.max_coast_s); a still radar's predictions follow every confirmed track
    result.predictions, fc, rows = predict_tracks(
        result.tracks, predictor_for(dt), horizon, dt, max_len,
        max_coast_s=warning.max_coast_s if decides else None)
    summary.update(horizon_s=horizon * dt, n_predicted_rows=int(len(rows)))
    if decides:
        ego = pts.drop_duplicates("frame")[["frame", "time_s", "ego_speed_mps", "ego_y_m"]]
        result.decisions = decide(fc, rows, ego.sort_values("frame"), dt,
                                  EgoShape(entry.ego_width_m, entry.ego_length_m), warning)
        summary.update(first_warning_s=_first(result.decisions, "warning"),
                       first_aeb_s=_first(result.decisions, "aeb"),
                       max_p_collision=float(result.decisions.p_collision.max()))
    print(f"recordings {entry.name}: {summary['n_frames']} frames, {summary['n_tracks']} tracks"
          + (f", first AEB request at {summary['first_aeb_s']} s" if entry.moving else ""))
    return result
