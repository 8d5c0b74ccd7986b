"""Calibrated predictive distributions: pairs of paths, coverage at the nominal rate where the
errors are truly Gaussian (theory), and the stored fit giving back the same forecasts."""

from __future__ import annotations

import numpy as np
import pytest

from blindspot.traj.baselines import ConstantVelocity, KalmanCV
from blindspot.traj.distribution import GaussianForecast
from blindspot.traj.calibration import (CalibrationError, calibrate, calibration_scores,
                                        from_record, path_pairs, to_record)
from blindspot.traj.windows import interpolate_gaps


def cv_paths(n: int, T: int, seed: int, dt: float = 0.1, q: float = 0.3, r: float = 0.05):
    """Walks of the Kalman filter's own model (white acceleration of density q) measured with
    white noise of std r: linear-Gaussian, so every linear predictor's errors are Gaussian."""
    rng = np.random.default_rng(seed)
    acc = rng.normal(0, np.sqrt(q / dt), (n, T, 2))
    vel = np.cumsum(acc * dt, axis=1) + rng.normal(0, 1.0, (n, 1, 2))
    truth = np.cumsum(vel * dt, axis=1)
    return truth, truth + rng.normal(0, r, truth.shape)


def test_path_pairs_take_the_next_true_points_and_drop_unfillable_windows():
    truth, meas = cv_paths(3, 60, seed=0)
    meas[0, 0] = np.nan                         # a miss at a path's start cannot be interpolated
    meas[1, 20] = np.nan                        # an interior miss is
    h, f = path_pairs(meas, truth, 10, 5, 10)
    starts = np.arange(0, 60 - 15 + 1, 10)
    assert h.shape == (3 * len(starts) - 1, 10, 2) and f.shape == (len(h), 5, 2)
    np.testing.assert_array_equal(f[0], truth[0, 20:25])   # path 0 lost its first window
    assert np.isfinite(h).all()
    with pytest.raises(CalibrationError, match="must fit"):
        path_pairs(meas, truth, 50, 20, 1)
    # with_index: each pair's path and first frame, the dropped window left out
    h2, f2, path, start = path_pairs(meas, truth, 10, 5, 10, with_index=True)
    np.testing.assert_array_equal(h2, h)
    assert path.tolist() == [0] * (len(starts) - 1) + [1] * len(starts) + [2] * len(starts)
    assert start.tolist() == list(starts[1:]) + list(starts) * 2
    for i in range(len(h2)):
        np.testing.assert_array_equal(f2[i], truth[path[i], start[i] + 10:start[i] + 15])


def test_path_pairs_histories_hold_nothing_from_after_the_window():
    """Each pair's history equals the gaps filled from the path up to the window's end alone (a
    causal fill): a window ending in a miss, which the whole path's fill would take from the
    next measurement, in the pair's future, is dropped."""
    truth, meas = cv_paths(4, 80, seed=3)
    rng = np.random.default_rng(4)
    meas[rng.random(meas.shape[:2]) < 0.2] = np.nan
    meas[0, 29] = np.nan                        # the last point of path 0's window at start 20
    h, f, path, start = path_pairs(meas, truth, 10, 5, 2, with_index=True)
    assert not ((path == 0) & (start == 20)).any()
    for i in range(len(h)):
        end = start[i] + 10
        causal = interpolate_gaps(meas[path[i], :end])[start[i]:]
        np.testing.assert_array_equal(h[i], causal)
        assert np.isfinite(meas[path[i], end - 1]).all()
    # what was dropped: exactly the windows that end in a miss or keep one at their start
    starts = np.arange(0, 80 - 15 + 1, 2)
    filled = interpolate_gaps(meas)
    expect = sum(np.isfinite(meas[p, s + 9]).all() and np.isfinite(filled[p, s:s + 10]).all()
                 for p in range(4) for s in starts)
    assert len(h) == expect < 4 * len(starts)


class PointOnly:
    """A predictor with no distribution of its own (as the LSTM): CV with k = 4."""

    name = "point"

    def predict(self, history, horizon):
        return ConstantVelocity(k=4).predict(history, horizon)


def test_calibrated_on_validation_covers_at_the_nominal_rate_on_test():
    """Fitted on one set, scored on an independent one of the same linear-Gaussian walks: the
    50/90/95 % ellipses hold 50/90/95 % of the true positions within sampling error."""
    tv, mv = cv_paths(300, 45, seed=1)
    tt, mt = cv_paths(300, 45, seed=2)
    hv, fv = path_pairs(mv, tv, 20, 10, 25)
    ht, ft = path_pairs(mt, tt, 20, 10, 25)
    preds = {"kalman": KalmanCV(dt=0.1, process_psd=0.3, meas_std=0.05),
             "constant_velocity": ConstantVelocity(k=4), "point": PointOnly()}
    cal = calibrate(preds, hv, fv, scale_method="quantile", scale_level=0.9, cv_fit_points=4)
    for name, p in cal.items():
        s = calibration_scores(p, ht, ft)
        for level in (50, 90, 95):
            assert s[f"coverage_{level}"] == pytest.approx(level / 100, abs=0.04), (name, level)
        # a forecast the caller made already gives the same scores; one of another shape is named
        fc = p.predict_distribution(ht, ft.shape[1])
        assert calibration_scores(p, ht, ft, forecast=fc) == s
        wide = GaussianForecast(fc.mean, fc.cov * 4.0)       # used as given, not made again
        assert calibration_scores(p, ht, ft, forecast=wide)["coverage_50"] > s["coverage_50"] + 0.1
        with pytest.raises(CalibrationError, match=r"forecast: expected .* mean shape"):
            calibration_scores(p, ht, ft[:, :5], forecast=fc)
        with pytest.raises(CalibrationError, match="found ndarray"):
            calibration_scores(p, ht, ft, forecast=fc.mean)
    # the Kalman filter's own covariance is right already: its scales stay near 1
    np.testing.assert_allclose(cal["kalman"].scale, 1.0, atol=0.25)


def test_a_stored_calibration_gives_the_same_forecasts():
    tv, mv = cv_paths(80, 40, seed=3)
    hv, fv = path_pairs(mv, tv, 20, 8, 20)
    preds = {"kalman": KalmanCV(dt=0.1), "constant_velocity": ConstantVelocity(k=4),
             "point": PointOnly()}
    cal = calibrate(preds, hv, fv)
    for name, p in cal.items():
        back = from_record(to_record(p), preds[name], name)
        a, b = p.predict_distribution(hv, 8), back.predict_distribution(hv, 8)
        np.testing.assert_allclose(b.mean, a.mean)
        np.testing.assert_allclose(b.cov, a.cov)
    with pytest.raises(CalibrationError, match="point"):
        from_record({"scale": [1.0]}, PointOnly(), "point")


def test_a_mixture_calibration_covers_heavy_tailed_errors_where_one_scale_cannot():
    """A point predictor whose error is 0.1 m (85 % of the tracks) or 1 m (15 %; a turn it did
    not see coming), with no covariance of its own: a per-step scale covers either the 50 %
    or the 95 % ellipse, the scale mixture covers both on independent paths; its record gives
    back the same ellipses."""
    tv, mv = cv_paths(300, 45, seed=4)
    tt, mt = cv_paths(300, 45, seed=5)
    hv, fv = path_pairs(mv, tv, 20, 10, 5)
    ht, ft = path_pairs(mt, tt, 20, 10, 5)
    rng = np.random.default_rng(6)

    def heavy(f):
        big = rng.random((len(f), 1, 1)) < 0.15
        return f + rng.normal(0, 1, f.shape) * np.where(big, 1.0, 0.1)

    class Oracle:
        name = "oracle"

        def predict(self, history, horizon):
            return self.truth[:len(history), :horizon]

    preds = {"oracle": Oracle()}
    preds["oracle"].truth = fv
    fv_noisy = heavy(fv)
    one = calibrate(preds, hv, fv_noisy, scale_method="quantile", scale_level=0.9)["oracle"]
    mix = calibrate(preds, hv, fv_noisy, scale_method="mixture")["oracle"]
    preds["oracle"].truth = ft
    ft_noisy = heavy(ft)
    s1, sm = calibration_scores(one, ht, ft_noisy), calibration_scores(mix, ht, ft_noisy)
    assert abs(s1["coverage_50"] - 0.5) > 0.1, s1
    for level in (50, 90, 95):
        assert sm[f"coverage_{level}"] == pytest.approx(level / 100, abs=0.025), (level, sm)
    back = from_record(to_record(mix), preds["oracle"], "oracle")
    np.testing.assert_allclose(back.radius_sq((0.5, 0.9), 10), mix.radius_sq((0.5, 0.9), 10))
    assert calibration_scores(back, ht, ft_noisy) == sm
