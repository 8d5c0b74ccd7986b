import numpy as np
import pytest

from blindspot.traj.baselines import ConstantVelocity
from blindspot.traj.forecast import forecast_track


def line(n=80, dt=0.1, v=(1.0, -0.5)):
    t = np.arange(n) * dt
    return np.stack([v[0] * t, 8 + v[1] * t], axis=1)


def test_forecast_uses_only_the_past_and_covers_start_to_end():
    truth = line()
    track = truth.copy()
    track[60:] = [100.0, 100.0]  # the future is garbage: it must not be read
    pred = forecast_track(track, 60, ConstantVelocity())
    assert pred.shape == (20, 2)
    np.testing.assert_allclose(pred, truth[60:], atol=1e-9)


def test_trailing_misses_before_the_start_are_rolled_through():
    truth = line()
    track = truth.copy()
    track[52:60] = np.nan  # last point seen at frame 51
    pred = forecast_track(track, 60, ConstantVelocity(), end=70)
    assert pred.shape == (10, 2)
    np.testing.assert_allclose(pred, truth[60:70], atol=1e-9)


def test_no_point_before_start_is_an_error():
    track = np.full((10, 2), np.nan)
    with pytest.raises(ValueError, match="no point seen"):
        forecast_track(track, 5, ConstantVelocity())
