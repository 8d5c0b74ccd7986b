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


def test_a_batch_is_forecast_as_each_track_alone():
    from functools import partial

    from blindspot.traj.baselines import KalmanCV
    from blindspot.traj.forecast import forecast_tracks
    from blindspot.traj.interpolation import fill_gaps, interpolate

    rng = np.random.default_rng(1)
    tracks = np.stack([line(v=(rng.uniform(-1, 1), rng.uniform(-1, 1))) for _ in range(6)])
    tracks += rng.normal(0, 0.02, tracks.shape)
    tracks[rng.random(tracks.shape[:2]) < 0.2] = np.nan
    tracks[:, :3] = 0.0
    start = rng.integers(40, 70, 6)
    end = np.minimum(start + 12, 80)
    for predictor, tol in ((ConstantVelocity(k=4), 1e-9), (KalmanCV(dt=0.1), 1e-4)):  # Kalman: see forecast_tracks
        batch = forecast_tracks(tracks, start, predictor,
                                fill=partial(fill_gaps, method="forward", predictor=predictor),
                                end=end)
        for i in range(6):
            alone = forecast_track(tracks[i], int(start[i]), predictor,
                                   fill=partial(interpolate, method="forward",
                                                predictor=predictor), end=int(end[i]))
            np.testing.assert_allclose(batch[i, : len(alone)], alone, atol=tol)
            assert np.isnan(batch[i, len(alone):]).all()
