"""Constant-velocity and Kalman baselines: exact on constant-velocity motion, pykalman agreement,
Kalman theory (maximum-likelihood recovers the simulated noise), gap filling and noise reduction."""

import numpy as np
import pytest
from pykalman import KalmanFilter

from blindspot.traj.baselines import ConstantVelocity, KalmanCV, cv_model, kalman_filter
from blindspot.traj.predictor import HistoryError, PathPredictor

DT = 0.4


def cv_tracks(rng, B, T, speed=1.5):
    """(B, T, 2) exact constant-velocity tracks at frame period DT, random start and heading."""
    start = rng.uniform(-10, 10, size=(B, 1, 2))
    heading = rng.uniform(0, 2 * np.pi, size=(B, 1))
    v = speed * np.stack([np.cos(heading), np.sin(heading)], axis=-1)       # (B, 1, 2) m/s
    return start + v * DT * np.arange(T)[None, :, None]


def simulate_cv_model(rng, B, T, q, r):
    """Tracks drawn from the Kalman model itself (white-noise acceleration q, noise r)."""
    F, Q, H, R = cv_model(DT, q, r)
    L = np.linalg.cholesky(Q)
    s = np.concatenate([rng.uniform(-5, 5, (B, 2)), rng.normal(0, 1.0, (B, 2))], axis=1)
    states = np.empty((B, T, 4))
    for t in range(T):
        if t:
            s = s @ F.T + rng.normal(size=(B, 4)) @ L.T
        states[:, t] = s
    return states[..., :2], states[..., :2] + rng.normal(0, r, (B, T, 2))


@pytest.mark.parametrize("model", [ConstantVelocity(), ConstantVelocity(k=5), KalmanCV()])
def test_both_predict_exact_constant_velocity_motion(model):
    rng = np.random.default_rng(0)
    track = cv_tracks(rng, 64, 20)
    pred = model.predict(track[:, :8], 12)
    assert isinstance(model, PathPredictor)
    assert pred.shape == (64, 12, 2)
    # CVM is exact; the Kalman filter's zero-velocity prior fades out over 8 frames
    tol = 1e-9 if isinstance(model, ConstantVelocity) else 2e-3
    assert np.abs(pred - track[:, 8:]).max() < tol


def test_kalman_with_a_diffuse_velocity_prior_is_exact():
    track = cv_tracks(np.random.default_rng(1), 16, 20)
    pred = KalmanCV(init_vel_std=1e4).predict(track[:, :8], 12)
    assert np.abs(pred - track[:, 8:]).max() < 1e-6


def test_missing_frames_do_not_break_constant_velocity_extrapolation():
    rng = np.random.default_rng(2)
    track = cv_tracks(rng, 32, 20)
    hist = track[:, :8].copy()
    hist[rng.random((32, 8)) < 0.3] = np.nan
    hist[:, 0] = track[:, 0]                           # keep two observations per track
    hist[:, 3] = track[:, 3]
    hist[::2, -2:] = np.nan                            # half the tracks miss the last two frames
    for model, tol in ((ConstantVelocity(), 1e-9), (ConstantVelocity(k=3), 1e-9),
                       (KalmanCV(init_vel_std=1e4), 1e-6)):
        assert np.abs(model.predict(hist, 12) - track[:, 8:]).max() < tol, model


def test_cvm_uses_the_last_two_positions_only():
    # straight along x, then a right-angle turn between the last two frames
    hist = np.array([[[0, 0], [1, 0], [2, 0], [3, 0], [3, 1]]], dtype=float)
    np.testing.assert_allclose(ConstantVelocity().predict(hist, 2)[0], [[3, 2], [3, 3]])
    # least squares over the last 3: x 2, 3, 3 -> slope 0.5; y 0, 0, 1 -> slope 0.5
    np.testing.assert_allclose(ConstantVelocity(k=3).predict(hist, 1)[0], [[3.5, 1.5]])


def test_degenerate_histories():
    hist = np.full((2, 4, 2), np.nan)
    hist[0, 2] = [1.0, 2.0]                             # a single observation -> stands still
    pred = ConstantVelocity().predict(hist, 3)
    np.testing.assert_allclose(pred[0], [[1.0, 2.0]] * 3)
    assert np.isnan(pred[1]).all()                      # nothing observed -> NaN, not zeros
    assert np.isnan(KalmanCV().predict(hist, 3)[1]).all()
    with pytest.raises(HistoryError, match=r"\(B, T, 2\)"):
        ConstantVelocity().predict(np.zeros((4, 2)), 3)
    with pytest.raises(HistoryError, match="horizon"):
        KalmanCV().predict(np.zeros((1, 4, 2)), 0)
    with pytest.raises(ValueError, match="KalmanCV.meas_std"):
        KalmanCV(meas_std=0.0)


def test_batched_filter_matches_pykalman():
    rng = np.random.default_rng(3)
    _, obs = simulate_cv_model(rng, 12, 25, q=0.3, r=0.1)
    obs[rng.random((12, 25)) < 0.3] = np.nan
    obs[0, :5] = np.nan                                 # leading gap
    obs[1, -6:] = np.nan                                # trailing gap
    kcv = KalmanCV(process_psd=0.3, meas_std=0.1)
    F, Q, H, R = kcv.matrices()
    m0, P0 = kcv.prior(obs)
    ours = kalman_filter(obs, F, Q, H, R, m0, P0)
    for b in range(obs.shape[0]):
        seen = np.isfinite(obs[b]).all(axis=1)
        kf = KalmanFilter(transition_matrices=F, observation_matrices=H, transition_covariance=Q,
                          observation_covariance=R, initial_state_mean=m0[b],
                          initial_state_covariance=P0)
        z = np.ma.masked_array(np.nan_to_num(obs[b]), mask=np.repeat(~seen[:, None], 2, axis=1))
        means, covs = kf.filter(z)
        np.testing.assert_allclose(ours.means[b], means, atol=1e-6)
        np.testing.assert_allclose(ours.covs[b], covs, atol=1e-6)
        assert ours.loglik[b] == pytest.approx(kf.loglikelihood(z), abs=1e-6)


def test_maximum_likelihood_recovers_the_simulated_noise_levels():
    rng = np.random.default_rng(4)
    _, obs = simulate_cv_model(rng, 1500, 20, q=0.5, r=0.08)
    fitted = KalmanCV(process_psd=0.05, meas_std=0.3).fit(obs, max_tracks=None)
    assert fitted.process_psd == pytest.approx(0.5, rel=0.1)
    assert fitted.meas_std == pytest.approx(0.08, rel=0.05)


def test_forecast_fit_does_not_lose_to_its_starting_point():
    rng = np.random.default_rng(5)
    _, obs = simulate_cv_model(rng, 800, 20, q=0.2, r=0.05)
    start = KalmanCV(process_psd=50.0)
    fitted = start.fit(obs, objective="forecast", obs_len=8)

    def train_ade(m):
        return np.linalg.norm(m.predict(obs[:, :8], 12) - obs[:, 8:], axis=-1).mean()

    assert train_ade(fitted) < train_ade(start)
    assert fitted.meas_std == start.meas_std            # forecast fit moves q only


def test_smoother_fills_a_gap_on_a_straight_line():
    truth = cv_tracks(np.random.default_rng(6), 1, 40)[0]
    track = truth.copy()
    track[12:25] = np.nan                               # 13 hidden frames = 5.2 s
    filled = KalmanCV().smooth(track)
    assert filled.shape == truth.shape
    assert np.abs(filled - truth).max() < 0.01


def test_smoother_and_filter_reduce_measurement_noise():
    rng = np.random.default_rng(7)
    truth, obs = simulate_cv_model(rng, 40, 60, q=0.05, r=0.15)
    model = KalmanCV(process_psd=0.05, meas_std=0.15)
    raw = np.sqrt(np.mean((obs - truth) ** 2))
    smoothed = np.stack([model.smooth(o) for o in obs])
    filtered = model.filter(obs).means[..., :2]
    rmse_s = np.sqrt(np.mean((smoothed - truth) ** 2))
    rmse_f = np.sqrt(np.mean((filtered - truth) ** 2))
    assert rmse_s < 0.5 * raw                           # ~0.34 of raw for these settings
    assert rmse_s < rmse_f < raw


def test_smooth_refuses_a_track_without_points():
    with pytest.raises(HistoryError, match="no valid"):
        KalmanCV().smooth(np.full((5, 2), np.nan))
    with pytest.raises(HistoryError, match=r"\(T, 2\)"):
        KalmanCV().smooth(np.zeros((2, 5, 2)))
