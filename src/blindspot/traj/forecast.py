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
from blindspot.traj.interpolation import pad_history
from blindspot.traj.predictor import PathPredictor


class ForecastError(ValueError):
    """A track or prediction start/end handed to :func:`forecast_track` is malformed."""


def forecast_track(track: np.ndarray, start: int, predictor: PathPredictor,
                   fill: Callable[[np.ndarray], np.ndarray] | None = None,
                   end: int | None = None) -> np.ndarray:
    """Predicted positions for frames ``start .. end-1`` (default: to the end of ``track``).

    track : (T, 2) points with NaN rows where nothing was seen; only rows < ``start`` are read.
    fill  : gap filler applied to ``track[:start]`` (e.g. an interpolation method); None = none.
    Returns (end - start, 2).
    Raises ForecastError: ``track`` not a real (T, 2) array (NaN rows allowed, inf not), start
    or end not integers with 0 < start < end <= T, or no point seen before ``start``.
    """
    who = "forecast_track"
    t = check_array(track, "track", ("T", 2), error=ForecastError, who=who, allow_nan=True)
    start = check_count(start, "start", ge=1, error=ForecastError, who=who)
    end = len(t) if end is None else check_count(end, "end", ge=1, error=ForecastError, who=who)
    if not 0 < start < end <= len(t):
        raise ForecastError(f"{who}: prediction start {start} / end {end}: expected "
                            f"0 < start < end <= {len(t)}")
    past = t[:start] if fill is None else fill(t[:start].copy())
    seen = np.flatnonzero(~np.isnan(past).any(axis=1))
    if len(seen) == 0:
        raise ForecastError(f"{who}: no point seen before the prediction start (frame {start})")
    history = past[seen[0]: seen[-1] + 1]
    window = getattr(predictor, "window", None)
    if window is not None and len(history) < window:
        history = pad_history(history, window)
    lead = start - (seen[-1] + 1)  # frames between the last point seen and the start
    pred = np.asarray(predictor.predict(history[None], lead + end - start))[0]
    return pred[lead:]
