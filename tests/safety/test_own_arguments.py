"""Every public function of the safety room checks its own scalar arguments (issue 45): a
negative, NaN or infinite speed, a period of zero, a negative standard deviation are refused by
the function itself, naming the argument and the value, not passed on to give NaN or a wrong
number (risk and braking: tests/safety/test_risk.py, test_braking.py)."""

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from blindspot.safety.braking import BrakingModel
from blindspot.safety.evaluation import aeb_gate_s
from blindspot.safety.oracle import oracle_tracks, noisy_position_points
from blindspot.safety.outcome import OutcomeError, pedestrian_boxes
from blindspot.safety.predict import track_histories
from blindspot.track.moving import doppler_log_ratio, moving_tracks
from tests.track.test_moving import _tracks

BAD = st.sampled_from([np.nan, np.inf, -np.inf])
NEGATIVE = st.floats(max_value=-1e-9, allow_infinity=False)


@settings(max_examples=20, deadline=None)
@given(speed=st.one_of(NEGATIVE, BAD))
def test_moving_tracks_refuses_a_bad_speed(speed):
    with pytest.raises(ValueError, match=r"moving_tracks: speed_mps: expected a finite number "
                                         r">= 0 m/s"):
        moving_tracks(_tracks(), speed)


@pytest.mark.parametrize("kw, name", [(dict(probability=1.0), "probability"),
                                      (dict(probability=0.0), "probability"),
                                      (dict(probability=np.nan), "probability"),
                                      (dict(doppler_std_mps=0.0), "doppler_std_mps"),
                                      (dict(doppler_std_mps=-0.3), "doppler_std_mps")])
def test_moving_tracks_refuses_a_bad_probability_or_spread(kw, name):
    with pytest.raises(ValueError, match=f"moving_tracks: {name}: .*found"):
        moving_tracks(_tracks(), 1.0, **kw)


@pytest.mark.parametrize("std", [0.0, -1.0, np.nan, np.inf])
def test_doppler_log_ratio_refuses_a_bad_spread(std):
    with pytest.raises(ValueError, match="doppler_log_ratio: doppler_std_mps"):
        doppler_log_ratio(_tracks(), np.zeros((1, 2)), std)


@pytest.mark.parametrize("max_len", [0, -1, 2.5])
def test_track_histories_refuses_a_bad_length(max_len):
    with pytest.raises(ValueError, match=f"track_histories: max_len: .*found {max_len}"):
        track_histories(_tracks(), max_len)


@settings(max_examples=20, deadline=None)
@given(dt=st.one_of(st.floats(max_value=0.0), BAD), extend=st.floats(0, 5))
def test_pedestrian_boxes_refuses_a_bad_period(dt, extend):
    with pytest.raises(OutcomeError, match=r"pedestrian_boxes: dt_s: expected a finite number > 0"):
        pedestrian_boxes(None, dt, extend)


@pytest.mark.parametrize("extend", [-0.1, np.nan, np.inf])
def test_pedestrian_boxes_refuses_a_bad_extension(extend):
    with pytest.raises(OutcomeError, match="pedestrian_boxes: extend_s"):
        pedestrian_boxes(None, 0.01, extend)


@pytest.mark.parametrize("period", [0.0, -0.1, np.nan])
def test_oracle_tracks_refuses_a_zero_frame_period(period):
    with pytest.raises(ValueError, match=r"oracle_tracks: frame_period_s: .*found"):
        oracle_tracks(pd.DataFrame(), None, period)


def test_noisy_position_points_refuses_a_negative_noise():
    with pytest.raises(ValueError, match=r"noisy_position_points: meas_std_m: .*found -0.1"):
        noisy_position_points(pd.DataFrame(), -0.1, 0)


@pytest.mark.parametrize("kw, name", [(dict(speed_mps=np.array([5.0, np.nan])), "speed_mps"),
                                      (dict(decision_delay_s=-0.1), "decision_delay_s"),
                                      (dict(decision_delay_s=np.inf), "decision_delay_s"),
                                      (dict(margin_s=np.nan), "margin_s")])
def test_aeb_gate_refuses_a_non_finite_speed_delay_or_margin(kw, name):
    args = dict(speed_mps=np.array([5.0, 10.0]), decision_delay_s=0.1, margin_s=0.2) | kw
    with pytest.raises(ValueError, match=f"aeb_gate_s: {name}"):
        aeb_gate_s(args.pop("speed_mps"), BrakingModel(0.2, 30.0, 9.8), gate="stopping_time",
                   **args)
