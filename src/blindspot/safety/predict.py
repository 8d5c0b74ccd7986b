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

from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
from scipy.stats import chi2

from blindspot.safety.risk import EgoShape, collision_risk
from blindspot.traj.baselines import ConstantVelocity

__all__ = ["BackfilledHistory", "track_histories", "moving_tracks", "risk_table"]


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
        """(B, T, 2) with leading NaN rows -> (B, max(T, window), 2) without them."""
        h = np.asarray(history, float)
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


def track_histories(tracks: pd.DataFrame, max_len: int) -> np.ndarray:
    """(B, max_len, 2) right-aligned position histories, one per row of ``tracks`` (columns
    group, track_id, frame, x_m, y_m; sorted by group, track_id, frame, as the trackers return
    them): row b's last entry is its own position, earlier entries the same track's positions
    at the frames before (NaN where the track did not exist or skipped a frame).
    Raises ValueError when ``tracks`` is not sorted that way."""
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


def moving_tracks(tracks: pd.DataFrame, speed_mps: float, probability: float = 0.99
                  ) -> np.ndarray:
    """(N,) bool per row of ``tracks`` (columns group, track_id, frame, vx_mps, vy_mps,
    cov_vxvx, cov_vxvy, cov_vyvy, confirmed; the tracker's world-frame filtered state): True
    from the track's first confirmed row on whose velocity is both fast, sqrt(vx^2 + vy^2) >
    ``speed_mps``, and significantly non-zero, v^T P_v^-1 v > the chi-square quantile of 2
    degrees of freedom at ``probability`` (a static object's filtered velocity is zero-mean
    Gaussian with covariance P_v, so it passes with probability 1 - ``probability`` per frame;
    the test of Bar-Shalom, Li & Kirubarajan 2001, sec. 5.4, applied to the velocity).
    Causal (a car decides with the frames it has) and latched (a pedestrian stopping at the kerb
    stays a moving object). Static world (parked cars, kerb clutter), tracked like anything
    else, mostly never gets there: a new track's velocity is fast but uncertain, and a cluster
    sliding along a parked car as the ego passes is short-lived. Raises ValueError naming a
    missing column."""
    need = {"group", "track_id", "frame", "vx_mps", "vy_mps", "cov_vxvx", "cov_vxvy",
            "cov_vyvy", "confirmed"}
    missing = sorted(need - set(tracks.columns))
    if missing:
        raise ValueError(f"tracks: missing columns {missing} (the blindspot.track schema)")
    vx, vy = tracks.vx_mps.to_numpy(float), tracks.vy_mps.to_numpy(float)
    a, b, c = (tracks[k].to_numpy(float) for k in ("cov_vxvx", "cov_vxvy", "cov_vyvy"))
    with np.errstate(divide="ignore", invalid="ignore"):
        d2 = (c * vx**2 - 2 * b * vx * vy + a * vy**2) / (a * c - b**2)
    fast = (np.hypot(vx, vy) > speed_mps) & (d2 > chi2.ppf(probability, 2))
    fast &= tracks.confirmed.to_numpy(bool)
    order = np.lexsort((tracks.frame.to_numpy(), tracks.track_id.to_numpy(),
                        tracks.group.astype(str).to_numpy()))
    key = (tracks.group.astype(str) + "\x00" + tracks.track_id.astype(str)).to_numpy()[order]
    seen = pd.Series(fast[order]).groupby(key, sort=False).cummax().to_numpy(bool)
    out = np.empty(len(tracks), bool)
    out[order] = seen
    return out


def risk_table(tracks: pd.DataFrame, ego: pd.DataFrame, predictors: dict[str, Any], *,
               horizon: int, dt_s: float, shape: EgoShape, margin_m: float, method: str,
               max_len: int) -> pd.DataFrame:
    """P(collision) and TTC per confirmed track row and predictor.

    tracks: the tracker's output (``blindspot.track`` schema: group, frame, track_id, x_m, y_m,
    confirmed, ...; with a ``moving`` column (:func:`moving_tracks`) only rows confirmed and
    moving are scored, the static world's tracks are not); ego: columns group, frame, ego_x_m, ego_y_m, ego_yaw_deg, ego_speed_mps
    (one row per group and frame). predictors: name -> probabilistic predictor
    (``predict_distribution(history (B, T, 2), horizon)``). Returns columns predictor, group,
    frame, track_id, p_collision, ttc_s. Raises ValueError when a track row has no ego state.
    """
    tr = tracks.sort_values(["group", "track_id", "frame"]).reset_index(drop=True)
    hist = track_histories(tr, max_len)
    keep = tr.confirmed.to_numpy(bool)
    if "moving" in tr.columns:                       # the tracker on every point: moving only
        keep = keep & tr.moving.to_numpy(bool)
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
        fc = pred.predict_distribution(hist, horizon)
        r = collision_risk(fc, e[["ego_x_m", "ego_y_m"]].to_numpy(),
                           np.radians(e.ego_yaw_deg.to_numpy()), e.ego_speed_mps.to_numpy(),
                           dt_s, shape, margin_m=margin_m, method=method)
        out.append(pd.DataFrame({"predictor": name, "group": rows.group, "frame": rows.frame,
                                 "track_id": rows.track_id, "p_collision": r.p_collision,
                                 "ttc_s": r.ttc_s}))
    cols = ["predictor", "group", "frame", "track_id", "p_collision", "ttc_s"]
    return pd.concat(out, ignore_index=True) if out else pd.DataFrame(columns=cols)
