"""The "no prediction" baseline: the pedestrian stays where it was last seen.

The reference a predictor must beat in a warning system (a risk computed from the current
position only). Its uncertainty comes, as the LSTM's does, from a Gaussian model of its own
errors fitted on validation pairs (:class:`blindspot.traj.calibration.ErrorModelPredictor`, via
:func:`blindspot.traj.calibration.calibrate`): a walker at speed v is about v t away after t.
"""

from __future__ import annotations

import numpy as np

from blindspot.traj.baselines import last_valid_index
from blindspot.traj.predictor import check_history

__all__ = ["Stationary"]


class Stationary:
    """PathPredictor: every future step at the last valid position of the history.

    predict(history (B, T, 2) m, NaN rows missing, horizon) -> (B, horizon, 2) m; a track with
    no valid row gives NaN. Raises HistoryError for malformed input."""

    name = "none"

    def predict(self, history: np.ndarray, horizon: int) -> np.ndarray:
        h = check_history(history, horizon, who=f"{self.name}.predict")
        last = last_valid_index(np.isfinite(h).all(axis=-1))
        x = h[np.arange(h.shape[0]), np.maximum(last, 0)]
        x = np.where((last >= 0)[:, None], x, np.nan)
        return np.repeat(x[:, None, :], horizon, axis=1)
