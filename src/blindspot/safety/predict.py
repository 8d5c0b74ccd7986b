"""Per confirmed track and frame: each predictor's forecast of the track's future path and its
collision risk against the ego car (:mod:`blindspot.safety.risk`).

History of a track at frame f: its own tracked positions (``x_m``, ``y_m``; the tracker's
filtered states, coasted rows included) from its first frame up to f, at most ``max_len``
frames, right-aligned (older rows NaN). Every predictor sees the same histories.

The scene LSTM reads a ``window``-point history (50 points, 5 s at 0.1 s), longer than a child
who just stepped out has been seen (a few frames). :class:`BackfilledHistory` completes the
missing past before the LSTM sees it: ``cv_backfill`` back-extrapolates the track at its current
constant velocity (least squares over its last 5 points), so the network sees a steady walk at
the speed the track shows now, the kind of walk it was trained on; ``hold_first`` holds the
first tracked point (a pedestrian who stood still, then walked off). CV and Kalman read the
unpadded history.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from blindspot.arrays import check_count, check_number
from blindspot.radar.config import RadarConfig
from blindspot.safety.config import WarningConfig
from blindspot.safety.risk import EgoShape, collision_risk, mixture_collision_risk
from blindspot.tables import check_columns
from blindspot.track.moving import coast_frames, confirmed_moving
from blindspot.traj.baselines import ConstantVelocity, KalmanCV, prediction_methods
from blindspot.traj.config import CalibrationConfig, DatasetConfig, EvalConfig
from blindspot.traj.distribution import DistributionError
from blindspot.traj.lstm import LSTMPredictor
from blindspot.traj.mixture import MixtureForecast
from blindspot.traj.windows import interpolate_gaps

__all__ = ["calibrated_predictors", "stage_predictors", "BackfilledHistory", "TrackState", "with_backfill", "track_histories",
           "incremental_kalman", "track_state_forecast", "decision_rows", "risk_table"]


@dataclass(frozen=True, eq=False)
class BackfilledHistory:
    """A probabilistic predictor whose histories get their leading missing rows filled first
    (module docstring). base: the predictor; window: the length it needs; mode:
    ``cv_backfill`` | ``hold_first``; k: points of the CV velocity."""

    base: Any
    window: int
    mode: str = "cv_backfill"
    k: int = 5

    def __post_init__(self) -> None:
        if self.mode not in ("cv_backfill", "hold_first"):
            raise ValueError(f"BackfilledHistory.mode: expected 'cv_backfill' or 'hold_first', "
                             f"found {self.mode!r}")

    @property
    def name(self) -> str:
        return getattr(self.base, "name", "lstm")

    def fill(self, history: np.ndarray) -> np.ndarray:
        """(B, T, 2) with leading NaN rows (and NaN rows between observed ones, a frame the
        track skipped: interpolated linearly between its two observed neighbours, both in the
        past) -> (B, max(T, window), 2) without them."""
        h = interpolate_gaps(np.asarray(history, float))
        if h.shape[1] < self.window:
            pad = np.full((h.shape[0], self.window - h.shape[1], 2), np.nan)
            h = np.concatenate([pad, h], axis=1)
        valid = np.isfinite(h).all(-1)
        first = np.argmax(valid, axis=1)
        x0 = h[np.arange(len(h)), first]                                   # (B, 2)
        lead = np.arange(h.shape[1])[None, :] < first[:, None]
        if self.mode == "cv_backfill":
            v, _ = ConstantVelocity(k=self.k).velocity(h)                    # m per frame
        else:
            v = np.zeros_like(x0)
        back = x0[:, None, :] + (np.arange(h.shape[1])[None, :, None]
                                 - first[:, None, None]) * v[:, None, :]
        return np.where(lead[..., None], back, h)

    def predict(self, history: np.ndarray, horizon: int) -> np.ndarray:
        return np.asarray(self.base.predict(self.fill(history), horizon))

    def predict_distribution(self, history: np.ndarray, horizon: int):
        return self.base.predict_distribution(self.fill(history), horizon)


@dataclass(frozen=True, eq=False)
class TrackState:
    """The ``track_state`` predictor: each track row's own filtered state (the tracker's
    Kalman filter, ``x_m, y_m, vx_mps, vy_mps`` and the ``cov_*`` columns) forecast at constant
    velocity, so the prediction knows what the tracker knows (the velocity its Doppler gave a
    new track, issue 40) instead of re-deriving it from a few positions. ``kalman``: the
    calibrated Kalman predictor (:class:`blindspot.traj.calibration.ScaledPredictor` around a
    :class:`~blindspot.traj.baselines.KalmanCV`) whose transition (process noise) and
    calibration scale the forecast uses (:func:`track_state_forecast`); one Kalman recursion,
    the tracker's, no second filter."""

    kalman: Any
    name: str = "track_state"


def track_state_forecast(pred: TrackState, rows: pd.DataFrame, horizon: int):
    """The GaussianForecast (len(rows), horizon) of :class:`TrackState` for the track rows
    ``rows`` (columns x_m, y_m, vx_mps, vy_mps, cov_xx, cov_xy, cov_yy, cov_vxvx, cov_vxvy,
    cov_vyvy; the cross terms cov_xvx, cov_xvy, cov_yvx, cov_yvy taken as 0 where absent):
    :meth:`KalmanCV.forecast_from_state` of the rows' states, scaled by the Kalman's
    calibration. Raises DistributionError when ``horizon`` is longer than the calibration,
    ValueError naming a missing column."""
    k = pred.kalman
    if horizon > len(k.scale):
        raise DistributionError(f"track_state: the Kalman calibration covers {len(k.scale)} "
                                f"steps, asked for {horizon}")
    check_columns(rows, ["x_m", "y_m", "vx_mps", "vy_mps", "cov_xx", "cov_xy", "cov_yy",
                         "cov_vxvx", "cov_vxvy", "cov_vyvy"], "tracks",
                  note="the track_state predictor forecasts the filtered state")
    n = len(rows)
    m = rows[["x_m", "y_m", "vx_mps", "vy_mps"]].to_numpy(float)
    col = (lambda c: rows[c].to_numpy(float) if c in rows.columns else np.zeros(n))
    P = np.zeros((n, 4, 4))
    for (i, j), c in {(0, 0): "cov_xx", (0, 1): "cov_xy", (1, 1): "cov_yy",
                      (2, 2): "cov_vxvx", (2, 3): "cov_vxvy", (3, 3): "cov_vyvy",
                      (0, 2): "cov_xvx", (0, 3): "cov_xvy", (1, 2): "cov_yvx",
                      (1, 3): "cov_yvy"}.items():
        P[:, i, j] = P[:, j, i] = col(c)
    fc = k.base.forecast_from_state(m, P, horizon, **dict(k.options))
    return fc.scaled(k.scale[:horizon])


def with_backfill(predictor, base, mode: str):
    """``predictor`` (calibrated around the point model ``base``) wrapped in
    :class:`BackfilledHistory` when ``base`` reads a fixed window of ``base.window`` points (the
    scene LSTMs: 50 points for the next-point LSTM, ``obs_len`` for lstm_direct); unchanged for
    the others (none, constant velocity, Kalman read any history)."""
    window = getattr(base, "window", None)
    return predictor if window is None else BackfilledHistory(predictor, int(window), mode)


def track_histories(tracks: pd.DataFrame, max_len: int) -> np.ndarray:
    """(B, max_len, 2) right-aligned position histories, one per row of ``tracks`` (columns
    group, track_id, frame, x_m, y_m; sorted by group, track_id, frame, as the trackers return
    them): row b's last entry is its own position, earlier entries the same track's positions
    at the frames before (NaN where the track did not exist or skipped a frame).
    Raises ValueError when ``tracks`` is not sorted that way or ``max_len`` is not an integer
    >= 1."""
    check_count(max_len, "max_len", ge=1, who="track_histories")
    key = tracks.group.astype(str) + "\x00" + tracks.track_id.astype(str)
    frame = tracks.frame.to_numpy()
    same = (key.to_numpy()[1:] == key.to_numpy()[:-1])
    if np.any(same & (np.diff(frame) <= 0)):
        raise ValueError("tracks: rows must be sorted by group, track_id, frame (frames "
                         "increasing within a track)")
    B = len(tracks)
    start = np.maximum.accumulate(np.where(np.r_[True, ~same], np.arange(B), 0))
    xy = tracks[["x_m", "y_m"]].to_numpy(float)
    out = np.full((B, max_len, 2), np.nan)
    for d in range(max_len):                      # loop over the history length only
        r = np.arange(B) - d
        ok = r >= start
        off = frame - frame[np.maximum(r, 0)]                          # frames back
        ok &= off < max_len
        rows = np.flatnonzero(ok)
        out[rows, max_len - 1 - off[rows]] = xy[r[rows]]
    return out


def incremental_kalman(pred, tracks: pd.DataFrame, keep: np.ndarray, horizon: int):
    """A calibrated Kalman predictor's forecast for the rows ``keep`` (N,) bool of ``tracks``
    (sorted by group, track_id, frame) without re-filtering each row's history: the filter
    runs once over each track's whole life (:meth:`KalmanCV.filter`, prior at its first
    position), and each row predicts from its own frame's filtered state
    (:meth:`KalmanCV.forecast_from_state`), scaled by the calibration (``pred.scale``; the
    ``options`` of :class:`blindspot.traj.calibration.ScaledPredictor`). The filter is
    recursive, as a car's would be: it keeps each track's whole life, where the window
    predictors see histories cut to ``warning.max_history_s``; equal to
    ``pred.predict_distribution`` on the rows' cut histories while a track is younger than the
    cut. Only tracks with a kept row are filtered. Returns a GaussianForecast (keep.sum(),
    horizon). Raises DistributionError when ``horizon`` is longer than the calibration
    (``len(pred.scale)``)."""
    if horizon > len(pred.scale):
        raise DistributionError(f"{getattr(pred, 'name', 'kalman')}: calibrated for "
                                f"{len(pred.scale)} steps, asked for {horizon}")
    key = tracks.group.astype(str) + "\x00" + tracks.track_id.astype(str)
    tid_all = pd.factorize(key)[0]
    kept_track = np.zeros(tid_all.max() + 1 if len(tid_all) else 0, bool)
    kept_track[tid_all[keep]] = True
    live = kept_track[tid_all]                       # rows of tracks with a kept row
    tid = pd.factorize(tid_all[live])[0]
    frame = tracks.frame.to_numpy()[live]
    f0 = pd.Series(frame).groupby(tid).transform("min").to_numpy()
    off = frame - f0
    obs = np.full((tid.max() + 1 if len(tid) else 0, off.max() + 1 if len(off) else 1, 2),
                  np.nan)
    obs[tid, off] = tracks[["x_m", "y_m"]].to_numpy(float)[live]
    base = pred.base
    res = base.filter(obs)
    k = keep[live]
    m, P = res.means[tid[k], off[k]], res.covs[tid[k], off[k]]
    fc = base.forecast_from_state(m, P, horizon, **dict(pred.options))
    return fc.scaled(pred.scale[:horizon])


def decision_rows(tracks: pd.DataFrame, dt_s: float, max_coast_s: float | None) -> np.ndarray:
    """(N,) bool per row of ``tracks``: the rows a decision may read. Confirmed; moving where
    the table has that column (the tracker on every point: the static world's tracks are not
    scored); and, unless ``max_coast_s`` is None, measured within the last ``max_coast_s`` s
    (:func:`blindspot.track.moving.coast_frames` of the ``coasting`` column, times ``dt_s``): a
    track coasting longer is the filter's extrapolation, not something the radar sees (issue 40:
    tracks coasting 4-12 frames requested 7 of the main draw's 15 false activations, most of
    them clutter off the parked cars). Raises ValueError naming a missing column (``coasting`` only with a
    limit), a ``dt_s`` not > 0 or a ``max_coast_s`` < 0."""
    check_number(dt_s, "dt_s", gt=0.0, unit="s", who="decision_rows")
    check_columns(tracks, {"confirmed"} | ({"group", "track_id", "frame", "coasting"}
                                           if max_coast_s is not None else set()),
                  "tracks", who="decision_rows",
                  note="the blindspot.track schema; coasting is needed for max_coast_s")
    keep = confirmed_moving(tracks)
    if max_coast_s is not None:
        check_number(max_coast_s, "max_coast_s", ge=0.0, unit="s", who="decision_rows")
        keep &= coast_frames(tracks) * dt_s <= max_coast_s + 1e-9
    return keep


def risk_table(tracks: pd.DataFrame, ego: pd.DataFrame, predictors: dict[str, Any], *,
               horizon: int, dt_s: float, shape: EgoShape, margin_m: float, method: str,
               max_len: int, max_coast_s: float | None) -> pd.DataFrame:
    """P(collision) and TTC per confirmed track row and predictor.

    tracks: the tracker's output (``blindspot.track`` schema: group, frame, track_id, x_m, y_m,
    confirmed, ...; with a ``moving`` column (:func:`moving_tracks`) only rows confirmed and
    moving are scored, the static world's tracks are not); ego: columns group, frame, ego_x_m, ego_y_m, ego_yaw_deg, ego_speed_mps
    (one row per group and frame). ``max_coast_s``: rows coasting longer are not scored
    (:func:`decision_rows`; None: no limit). predictors: name -> probabilistic predictor
    (``predict_distribution(history (B, T, 2), horizon)``; one offering ``predict_mixture``
    is scored by its mixture, :func:`~blindspot.safety.risk.mixture_collision_risk`). Returns columns predictor, group,
    frame, track_id, p_collision, ttc_s. Raises ValueError when a track row has no ego state.
    """
    tr = tracks.sort_values(["group", "track_id", "frame"]).reset_index(drop=True)
    hist = track_histories(tr, max_len)
    keep = decision_rows(tr, dt_s, max_coast_s)
    rows = tr[keep].reset_index(drop=True)
    hist = hist[keep]
    e = rows[["group", "frame"]].merge(ego, on=["group", "frame"], how="left")
    if e.ego_x_m.isna().any():
        bad = e[e.ego_x_m.isna()].iloc[0]
        raise ValueError(f"tracks: no ego state for group {bad.group!r} frame {bad.frame}")
    out = []
    for name, pred in predictors.items():          # loop over the four predictors only
        if not len(rows):
            break
        # a calibrated Kalman filter (ScaledPredictor: base, scale, options), not a wrapped one
        if isinstance(pred, TrackState):
            fc = track_state_forecast(pred, rows, horizon)
        elif (isinstance(getattr(pred, "base", None), KalmanCV)
                and getattr(pred, "scale", None) is not None and hasattr(pred, "options")):
            fc = incremental_kalman(pred, tr, keep, horizon)
        elif callable(getattr(pred, "predict_mixture", None)):   # multi-modal (issue 43)
            fc = pred.predict_mixture(hist, horizon)
        else:
            fc = pred.predict_distribution(hist, horizon)
        risk = mixture_collision_risk if isinstance(fc, MixtureForecast) else collision_risk
        r = risk(fc, e[["ego_x_m", "ego_y_m"]].to_numpy(),
                           np.radians(e.ego_yaw_deg.to_numpy()), e.ego_speed_mps.to_numpy(),
                           dt_s, shape, margin_m=margin_m, method=method)
        out.append(pd.DataFrame({"predictor": name, "group": rows.group, "frame": rows.frame,
                                 "track_id": rows.track_id, "p_collision": r.p_collision,
                                 "ttc_s": r.ttc_s}))
    cols = ["predictor", "group", "frame", "track_id", "p_collision", "ttc_s"]
    return pd.concat(out, ignore_index=True) if out else pd.DataFrame(columns=cols)


def calibrated_predictors(w, base: dict, records: dict, *, direct_path, paths, val, window: int,
                          calibration, cv_fit_points: int, where: str = "models.json",
                          frame_periods_s: tuple[float, float] | None = None) -> dict:
    """name -> calibrated probabilistic predictor for every name of ``w.predictors``
    (:class:`~blindspot.safety.config.WarningConfig`): ``none`` calibrated here on the
    validation paths (``paths``: paths.parquet, ``val``: the validation windows, ``window``
    points, ``calibration`` settings); ``track_state`` (:class:`TrackState`) around the
    calibrated Kalman; the others from their calibration ``records`` (models.json, named
    ``where`` in errors) around their point models ``base`` (name -> model; the direct LSTM
    loaded from ``direct_path`` when asked), the LSTMs' short histories completed as
    ``w.lstm_history`` says. ``frame_periods_s``: (driving, calibration) frame periods, which
    must agree. Raises ValueError naming the key of a predictor without a calibration, or
    of two frame periods that differ."""
    import torch

    from blindspot.traj.calibration import calibrate, from_record, path_pairs
    from blindspot.traj.direct import NAME as DIRECT
    from blindspot.traj.paths import table_to_arrays
    from blindspot.traj.seq2seq import Seq2SeqEnsemble
    from blindspot.traj.stationary import Stationary
    from blindspot.traj.windows import WindowSet

    if frame_periods_s is not None and abs(frame_periods_s[0] - frame_periods_s[1]) > 1e-9:
        raise ValueError(f"config keys 'driving_radar.frame_period_s' = {frame_periods_s[0]} "
                         f"and 'radar.frame_period_s' = {frame_periods_s[1]}: the predictors "
                         "were calibrated at the paper radar's frame period; expected equal")
    torch.set_num_threads(1)
    base = dict(base)
    if DIRECT in w.predictors:
        base[DIRECT] = Seq2SeqEnsemble.load(direct_path)
    out = {}
    for name in w.predictors:
        if name == "track_state":                  # the tracker's own state, Kalman-calibrated
            name_k = "kalman"
        else:
            name_k = name
        if name == "none":
            truth, measured, _ = table_to_arrays(pd.read_parquet(paths))
            ids = np.unique(WindowSet.load(val).path_id)
            hist, fut = path_pairs(measured[ids], truth[ids], window, calibration.horizon_frames,
                                   calibration.stride)
            out[name] = calibrate({"none": Stationary()}, hist, fut,
                                  scale_method=calibration.scale_method,
                                  scale_level=calibration.scale_level,
                                  cv_fit_points=cv_fit_points)["none"]
            continue
        if name_k not in records or name_k not in base:
            raise ValueError(f"config key 'warning.predictors' lists {name!r}: no calibrated "
                             f"distribution of {name_k!r} in {where} ({sorted(records)})")
        p = from_record(records[name_k], base[name_k], name_k)
        out[name] = TrackState(p) if name == "track_state" else with_backfill(p, base[name_k],
                                                                              w.lstm_history)
    return out


def stage_predictors(cfg, dep, *, jobs: int = 1) -> dict:
    """The calibrated predictors the safety stages score (:func:`calibrated_predictors` of
    ``warning.predictors``), built from the composed config ``cfg`` (groups warning, eval,
    dataset, calibration, driving_radar, radar) and the stage's inputs by file name
    (``dep(name)`` -> Path: train/model.pt, train_direct/model.pt, models.json, paths.parquet,
    val.parquet); the LSTM's rollouts on ``jobs`` workers."""
    w, ev = WarningConfig.from_cfg(cfg), EvalConfig.from_cfg(cfg)
    dt, paper_dt = (float(RadarConfig.from_cfg(cfg, k).frame_period_s)
                    for k in ("driving_radar", "radar"))
    lstm = LSTMPredictor.load(dep("train/model.pt")).with_workers(jobs)
    return calibrated_predictors(
        w, prediction_methods(ev, paper_dt, lstm), json.loads(dep("models.json").read_text()),
        direct_path=dep("train_direct/model.pt"), paths=dep("paths.parquet"),
        val=dep("val.parquet"), window=DatasetConfig.from_cfg(cfg).window,
        calibration=CalibrationConfig.from_cfg(cfg), cv_fit_points=ev.cv_fit_points,
        where=str(dep("models.json")), frame_periods_s=(dt, paper_dt))
