"""Predicting the rest of a scene from the track seen so far (the paper's Fig. 9).

Only what was seen before the prediction start is used: the gaps inside it are filled by a gap
filler that sees that part alone (no look-ahead), the history ends at the last point seen before
the start, and the rollout runs from there to the end of the scene; the frames from the start on
are returned.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from blindspot.arrays import check_array, check_count
from blindspot.traj.interpolation import gather_histories, pad_histories
from blindspot.traj.predictor import PathPredictor


class ForecastError(ValueError):
    """A track or prediction start/end handed to :func:`forecast_track` is malformed."""


def forecast_track(track: np.ndarray, start: int, predictor: PathPredictor,
                   fill: Callable[[np.ndarray], np.ndarray] | None = None,
                   end: int | None = None) -> np.ndarray:
    """Predicted positions for frames ``start .. end-1`` (default: to the end of ``track``):
    :func:`forecast_tracks` on a batch of one.

    track : (T, 2) points with NaN rows where nothing was seen; only rows < ``start`` are read.
    fill  : gap filler applied to ``track[:start]`` (T', 2) (e.g. an interpolation method);
        None = none.
    Returns (end - start, 2).
    Raises ForecastError: ``track`` not a real (T, 2) array (NaN rows allowed, inf not), start
    or end not integers with 0 < start < end <= T, or no point seen before ``start``.
    """
    who = "forecast_track"
    t = check_array(track, "track", ("T", 2), error=ForecastError, who=who, allow_nan=True)
    start = check_count(start, "start", ge=1, error=ForecastError, who=who)
    end = len(t) if end is None else check_count(end, "end", ge=1, error=ForecastError, who=who)
    batch_fill = None if fill is None else (lambda b: np.asarray(fill(b[0].copy()))[None])
    return forecast_tracks(t[None], np.array([start]), predictor, fill=batch_fill,
                           end=np.array([end]))[0]


def forecast_tracks(tracks: np.ndarray, start: np.ndarray, predictor: PathPredictor,
                    fill: Callable[[np.ndarray], np.ndarray] | None = None,
                    end: np.ndarray | None = None) -> np.ndarray:
    """Predictions of B tracks at once, each from its own start frame.

    tracks : (B, T, 2) points, NaN rows where nothing was seen; only rows < ``start[b]`` of
        track b are read (the rest is set to NaN before anything else sees it).
    start, end : (B,) int, 0 < start < end <= T (end default T).
    fill : gap filler of a batch, (B, T', 2) -> (B, T', 2) (e.g. ``partial(fill_gaps,
        method=...)``), applied to the past ``tracks[:, :max(start)]``; None = none.
    Returns (B, max(end - start), 2): row b holds frames ``start[b] ..`` up to ``end[b] - 1``,
    NaN after. Each track's history runs from its first to its last point seen before the
    start; the histories are right-aligned at their last point (a predictor with a ``window``
    gets them padded by :func:`pad_histories`) and rolled out in one batched call through the
    frames between the last point seen and the start. A shorter history is led by missing
    rows, which CV and the LSTM ignore; the Kalman filter propagates its prior through them
    (the batch of one, :func:`forecast_track`, has none).
    Raises ForecastError: malformed arrays, start / end out of range, or no point seen before
    a track's start.
    """
    history, lead, n = _batched_histories(tracks, start, predictor, fill, end,
                                          "forecast_tracks")
    horizon = int((lead + n).max())
    pred = np.asarray(predictor.predict(history, horizon))              # (B, horizon, 2)
    idx, inside = _steps(lead, n, horizon)
    out = np.take_along_axis(pred, idx[..., None], axis=1)
    return np.where(inside[..., None], out, np.nan)


def forecast_distributions(tracks: np.ndarray, start: np.ndarray, predictor,
                           fill: Callable[[np.ndarray], np.ndarray] | None = None,
                           end: np.ndarray | None = None):
    """:func:`forecast_tracks` for a predictor's Gaussian forecast (``predict_distribution``,
    :class:`blindspot.traj.distribution.GaussianForecast`): the same histories, the same
    frames. Returns a GaussianForecast (B, max(end - start), ...); a step after a track's end
    repeats its last step (mask it with ``end - start``)."""
    from blindspot.traj.distribution import GaussianForecast

    history, lead, n = _batched_histories(tracks, start, predictor, fill, end,
                                          "forecast_distributions")
    horizon = int((lead + n).max())
    fc = predictor.predict_distribution(history, horizon)
    idx, inside = _steps(lead, n, horizon)
    idx = np.where(inside, idx, (lead + n - 1)[:, None])
    return GaussianForecast(np.take_along_axis(fc.mean, idx[..., None], axis=1),
                            np.take_along_axis(fc.cov, idx[..., None, None], axis=1))


def _steps(lead: np.ndarray, n: np.ndarray, horizon: int) -> tuple[np.ndarray, np.ndarray]:
    j = np.arange(int(n.max()))[None, :]
    return np.clip(lead[:, None] + j, 0, horizon - 1), j < n[:, None]


def _batched_histories(tracks, start, predictor, fill, end, who):
    """Right-aligned histories (B, L, 2), frames from the last point seen to the start (B,),
    frames to predict (B,); see :func:`forecast_tracks`."""
    t = check_array(tracks, "tracks", ("B", "T", 2), error=ForecastError, who=who,
                    allow_nan=True)
    B, T = t.shape[:2]
    start = check_array(start, "start", (B,), error=ForecastError, who=who).astype(np.int64)
    end = np.full(B, T) if end is None else \
        check_array(end, "end", (B,), error=ForecastError, who=who).astype(np.int64)
    bad = ~((0 < start) & (start < end) & (end <= T))
    if bad.any():
        b = int(np.flatnonzero(bad)[0])
        raise ForecastError(f"{who}: prediction start {start[b]} / end {end[b]} of track {b}: "
                            f"expected 0 < start < end <= {T}")
    T_past = int(start.max())
    future = np.arange(T_past)[None, :] >= start[:, None]
    past = t[:, :T_past].copy()
    past[future] = np.nan
    if fill is not None:
        past = np.asarray(fill(past))
        past[future] = np.nan
    seen = np.isfinite(past).all(axis=-1)
    if not seen.any(axis=1).all():
        b = int(np.flatnonzero(~seen.any(axis=1))[0])
        raise ForecastError(f"{who}: no point seen before the prediction start (frame "
                            f"{start[b]}) of track {b}")
    first = np.argmax(seen, axis=1)
    last = T_past - 1 - np.argmax(seen[:, ::-1], axis=1)
    window = getattr(predictor, "window", None)
    history = gather_histories(past, first, last + 1, window or 1)
    if window is not None:
        history = pad_histories(history, window)
    return history, start - (last + 1), end - start
