"""Every predictor and rollout checks its own horizon and scalar arguments (issue 45): a
zero-length or fractional horizon, a bad speed floor or maximum horizon are the function's own
error naming the argument and the value."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from blindspot.traj.baselines import ConstantVelocity, KalmanCV
from blindspot.traj.config import LSTMConfig
from blindspot.traj.lstm import LSTMPredictor, LSTMRegressor, NormStats
from blindspot.traj.predictor import (ConstantVelocityTail, HeadingFrameRollout, HistoryError,
                                      NextPointRollout, heading_frame)
from blindspot.traj.stationary import Stationary

H = np.cumsum(np.full((2, 10, 2), 0.1), axis=1)
_LSTM = LSTMPredictor(LSTMRegressor(LSTMConfig(window=6, hidden_size=4, head_hidden=2)),
                      NormStats(True, "displacement"))
PREDICTORS = {"cv": ConstantVelocity(), "kalman": KalmanCV(), "stationary": Stationary(),
              "lstm": _LSTM, "rollout": NextPointRollout(_LSTM),
              "heading_frame": HeadingFrameRollout(_LSTM),
              "cv_tail": ConstantVelocityTail(ConstantVelocity(), 5)}


@pytest.mark.parametrize("name", sorted(PREDICTORS))
@settings(max_examples=10, deadline=None)
@given(horizon=st.one_of(st.integers(max_value=0), st.sampled_from([2.5, True, np.nan, "3"])))
def test_every_predictor_refuses_a_zero_length_or_non_integer_horizon(name, horizon):
    with pytest.raises(HistoryError, match=r"predict: horizon: expected an integer >= 1, found"):
        PREDICTORS[name].predict(H, horizon)


@pytest.mark.parametrize("floor", [0.0, -0.1, np.nan, np.inf])
def test_heading_frame_refuses_a_bad_speed_floor(floor):
    with pytest.raises(ValueError, match=r"heading_frame: speed_floor: .*found"):
        heading_frame(H, floor)
    with pytest.raises(ValueError, match=r"heading_frame: speed_floor"):
        HeadingFrameRollout(_LSTM, speed_floor=floor).predict(H, 3)


@pytest.mark.parametrize("max_horizon", [0, 1, 2.5, np.nan])
def test_constant_velocity_tail_refuses_a_bad_max_horizon(max_horizon):
    with pytest.raises(ValueError, match=r"ConstantVelocityTail: max_horizon: expected an "
                                         r"integer >= 2"):
        ConstantVelocityTail(ConstantVelocity(), max_horizon)
