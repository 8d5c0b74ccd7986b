"""Gap filling: the paper's forward rollout, the Kalman smoother, and our two-sided blend."""

import numpy as np
import pytest

from blindspot.traj.baselines import ConstantVelocity, KalmanCV
from blindspot.traj.interpolation import find_gaps, interpolate


def test_find_gaps_only_interior_runs():
    obs = np.array([0, 1, 1, 0, 0, 1, 0, 1, 1, 0, 0], bool)
    np.testing.assert_array_equal(find_gaps(obs), [[3, 5], [6, 7]])
    assert find_gaps(np.ones(5, bool)).shape == (0, 2)
    assert find_gaps(np.zeros(5, bool)).shape == (0, 2)


def straight_track(n=60, v=(1.2, -0.4), dt=0.1):
    t = np.arange(n) * dt
    return np.stack([1.0 + v[0] * t, 6.0 + v[1] * t], axis=1)


@pytest.mark.parametrize("method", ["forward", "bidirectional", "kalman"])
def test_straight_walk_gap_is_recovered(method):
    truth = straight_track()
    track = truth.copy()
    track[20:35] = np.nan
    filled = interpolate(track, method, predictor=ConstantVelocity(),
                         smoother=KalmanCV(dt=0.1, meas_std=0.01).smooth)
    seen = ~np.isnan(track).any(axis=1)
    np.testing.assert_array_equal(filled[seen], truth[seen])  # observed rows untouched
    tol = 0.05 if method == "kalman" else 1e-9
    assert np.abs(filled[20:35] - truth[20:35]).max() < tol


def test_two_sided_fill_lands_where_the_track_resumes():
    # A walk that turns by 90 degrees while hidden: a forward-only rollout keeps going straight
    # and misses where the pedestrian reappears; the two-sided blend ends at the reappearance.
    n, dt, speed = 80, 0.1, 1.3
    heading = np.where(np.arange(n) < 40, 0.0, np.pi / 2)
    heading[30:50] = np.linspace(0, np.pi / 2, 20)
    step = speed * dt * np.stack([np.cos(heading), np.sin(heading)], axis=1)
    truth = np.cumsum(step, axis=0) + [0.0, 5.0]
    track = truth.copy()
    track[30:50] = np.nan
    cv = ConstantVelocity()
    fwd = interpolate(track, "forward", predictor=cv)
    two = interpolate(track, "bidirectional", predictor=cv)
    err = lambda f: np.linalg.norm(f[30:50] - truth[30:50], axis=1)
    assert err(two).mean() < 0.5 * err(fwd).mean()
    # the last filled point is next to the first point after the gap
    assert np.linalg.norm(two[49] - truth[50]) < 2 * speed * dt


def test_bad_inputs_are_named():
    with pytest.raises(ValueError, match="shape"):
        interpolate(np.zeros((5, 3)), "forward", predictor=ConstantVelocity())
    with pytest.raises(ValueError, match="unknown"):
        interpolate(np.zeros((5, 2)), "spline")
    with pytest.raises(ValueError, match="needs a predictor"):
        interpolate(np.zeros((5, 2)), "forward")


def test_short_history_is_padded_backwards_along_its_own_line():
    from blindspot.traj.interpolation import pad_history

    truth = straight_track(n=30)
    padded = pad_history(truth[10:], 30)
    np.testing.assert_allclose(padded, truth, atol=1e-9)
    assert pad_history(truth, 10) is not None and len(pad_history(truth, 10)) == 30


class _WindowedCV(ConstantVelocity):
    """A predictor that, like the LSTM, refuses histories shorter than its window."""

    window = 50

    def predict(self, history, horizon):
        assert history.shape[1] >= self.window
        return super().predict(history, horizon)


def test_fixed_window_predictors_get_a_long_enough_history():
    truth = straight_track(n=60)
    track = truth.copy()
    track[:5] = np.nan
    track[15:30] = np.nan  # only 10 points before the gap, the window is 50
    filled = interpolate(track, "forward", predictor=_WindowedCV())
    assert np.abs(filled[15:30] - truth[15:30]).max() < 1e-9


def test_a_batch_is_filled_as_each_track_alone():
    """fill_gaps on many tracks (different gaps, misses, lengths of history) gives each track
    what interpolate gives it alone; the batched Kalman smoother is pykalman's."""
    from blindspot.traj.interpolation import fill_gaps

    rng = np.random.default_rng(0)
    n, T = 12, 70
    truth = np.cumsum(rng.normal(0, 0.05, (n, T, 2)) + [0.12, 0.03], axis=1)
    tracks = truth + rng.normal(0, 0.02, truth.shape)
    tracks[rng.random((n, T)) < 0.15] = np.nan
    for i in range(n):
        a = rng.integers(3, 30)
        tracks[i, a: a + rng.integers(5, 25)] = np.nan
    tracks[:, :2] = truth[:, :2]
    kalman = KalmanCV(dt=0.1, meas_std=0.05)
    for method in ("forward", "bidirectional", "kalman"):
        batch = fill_gaps(tracks, method, predictor=ConstantVelocity(k=3),
                          smoother=kalman.smooth_batch)
        alone = np.stack([interpolate(t, method, predictor=ConstantVelocity(k=3),
                                      smoother=kalman.smooth) for t in tracks])
        np.testing.assert_allclose(batch, alone, atol=1e-9, equal_nan=True)
