"""The one interface every path predictor offers (baselines, the LSTM, anything later).

A *history* is an array (B, T, 2) of (x, y) positions in metres at a fixed frame period, oldest
first; a NaN row means "no point in that frame" (missed detection, occlusion). A predictor
returns the next ``horizon`` positions of each of the B tracks, (B, horizon, 2), at the same
frame period.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

__all__ = ["PathPredictor", "HistoryError", "check_history"]


@runtime_checkable
class PathPredictor(Protocol):
    """A model that extrapolates pedestrian tracks."""

    name: str

    def predict(self, history: np.ndarray, horizon: int) -> np.ndarray:
        """Predict the next ``horizon`` positions.

        Args:
            history: (B, T, 2) observed positions in metres, NaN rows = missing frames.
            horizon: number of future frames to predict (>= 1).

        Returns:
            (B, horizon, 2) predicted positions in metres.
        """
        ...


class HistoryError(ValueError):
    """A history array or horizon handed to a predictor is malformed."""


def check_history(history: np.ndarray, horizon: int, *, who: str = "predict") -> np.ndarray:
    """Validate a predictor's input and return it as a float64 (B, T, 2) array.

    A single track (T, 2) is not silently promoted: batching is explicit in this interface.

    Raises:
        HistoryError: wrong rank/last axis, empty time axis, or ``horizon < 1``.
    """
    h = np.asarray(history, dtype=float)
    if h.ndim != 3 or h.shape[-1] != 2:
        raise HistoryError(f"{who}: history must be shaped (B, T, 2) (x, y in metres), "
                           f"found shape {h.shape}")
    if h.shape[1] < 1:
        raise HistoryError(f"{who}: history has no time steps (shape {h.shape})")
    if int(horizon) != horizon or horizon < 1:
        raise HistoryError(f"{who}: horizon must be a positive integer, found {horizon!r}")
    return h
