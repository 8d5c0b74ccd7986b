"""The AEB braking model against kinematics: stopping distance = v T + v^2 / (2 a) + the ramp's
term v t_r / 2 - a t_r^2 / 24, the motion against a numerical integration of the jerk-limited
deceleration profile, and the stop inside the ramp."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from blindspot.safety.braking import BrakingModel


@settings(max_examples=30, deadline=None)
@given(v=st.floats(3.0, 20.0), T=st.floats(0.0, 0.5), j=st.floats(10.0, 60.0),
       a=st.floats(4.0, 10.0))
def test_stopping_distance_is_analytic(v, T, j, a):
    b = BrakingModel(T, j, a)
    tr = a / j
    if v <= a * tr / 2:
        return
    expected = v**2 / (2 * a) + v * T + v * tr / 2 - a * tr**2 / 24
    assert b.stopping_distance(v) == pytest.approx(expected, rel=1e-12)


def test_motion_matches_numerical_integration_of_the_deceleration():
    b = BrakingModel(0.2, 30.0, 9.8)
    v0, dt = 16.67, 1e-5
    t = np.arange(0.0, 3.0, dt)
    decel = np.clip(30.0 * (t - 0.2), 0.0, 9.8)
    v = np.maximum(v0 - np.concatenate([[0.0], np.cumsum((decel[1:] + decel[:-1]) / 2 * dt)]), 0)
    s = np.concatenate([[0.0], np.cumsum((v[1:] + v[:-1]) / 2 * dt)])
    s_m, v_m = b.motion(v0, t)
    assert np.max(np.abs(v_m - v)) < 1e-3
    assert np.max(np.abs(s_m - s)) < 1e-3
    assert s_m[-1] == pytest.approx(b.stopping_distance(v0), abs=1e-9)


def test_stop_within_the_ramp():
    b = BrakingModel(0.1, 10.0, 9.8)          # ramp 0.98 s; 1 m/s stops inside it
    assert b.stop_time(1.0) == pytest.approx(0.1 + np.sqrt(2 * 1.0 / 10.0))
    assert b.stopping_distance(1.0) == pytest.approx(0.1 + 2 / 3 * np.sqrt(2 / 10.0))
    s, v = b.motion(1.0, np.array([-1.0, 5.0]))
    assert s[0] == pytest.approx(-1.0) and v[1] == 0.0


def test_bad_parameters_are_refused():
    with pytest.raises(ValueError, match="decel_mps2"):
        BrakingModel(0.1, 10.0, 0.0)


# --- every argument checked by the model itself (issue 45) ----------------------------------
@pytest.mark.parametrize("field, args", [("latency_s", (np.inf, 10.0, 8.0)),
                                         ("latency_s", (-0.1, 10.0, 8.0)),
                                         ("jerk_mps3", (0.1, np.nan, 8.0)),
                                         ("decel_mps2", (0.1, 10.0, np.inf))])
def test_non_finite_parameters_are_named(field, args):
    with pytest.raises(ValueError, match=f"BrakingModel: {field}: expected a finite number"):
        BrakingModel(*args)


@settings(max_examples=30, deadline=None)
@given(v=st.one_of(st.floats(max_value=-1e-9), st.sampled_from([np.nan, np.inf, -np.inf])))
def test_every_bad_speed_is_named_by_each_method(v):
    b = BrakingModel(0.2, 10.0, 8.0)
    for method, call in (("stop_time", lambda: b.stop_time(v)),
                         ("motion", lambda: b.motion(v, 1.0)),
                         ("stop_ttc", lambda: b.stop_ttc(v)),
                         ("stopping_distance", lambda: b.stopping_distance(v))):
        with pytest.raises(ValueError, match=f"BrakingModel.{method}: v0"):
            call()


def test_motion_refuses_a_nan_time():
    with pytest.raises(ValueError, match="BrakingModel.motion: t"):
        BrakingModel(0.2, 10.0, 8.0).motion(5.0, np.array([0.0, np.nan]))
