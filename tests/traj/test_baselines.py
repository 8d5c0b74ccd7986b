"""Constant-velocity and Kalman baselines: exact on constant-velocity motion, pykalman agreement,
Kalman theory (maximum-likelihood recovers the simulated noise), gap filling and noise reduction."""

import numpy as np
import pytest
from pykalman import KalmanFilter

from blindspot.kalman import cv_model, kalman_filter
from blindspot.traj.baselines import ConstantVelocity, KalmanCV
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


# --------------------------------------------------------------------------------------------
# predictive distributions: nominal coverage when the truth follows the model (theory)
# --------------------------------------------------------------------------------------------

LEVELS = (0.5, 0.9, 0.95)


def simulate_cv_tracks(rng, B, T, q, r, *, q_scale=None):
    """Noisy tracks of the white-noise-acceleration CV process; ``q_scale`` (B,) multiplies
    each track's process noise density (a heteroscedastic population)."""
    F, Q, H, R = cv_model(DT, q, r)
    L = np.linalg.cholesky(Q)
    k = np.ones(B) if q_scale is None else np.sqrt(q_scale)
    s = np.concatenate([rng.uniform(-5, 5, (B, 2)), rng.normal(0, 1.0, (B, 2))], axis=1)
    states = np.empty((B, T, 4))
    for t in range(T):
        if t:
            s = s @ F.T + k[:, None] * (rng.normal(size=(B, 4)) @ L.T)
        states[:, t] = s
    return states[..., :2] + rng.normal(0, r, (B, T, 2))


def test_kalman_distribution_covers_truth_of_its_own_model_at_nominal_rate():
    from blindspot.traj.distribution import ellipse_coverage

    rng = np.random.default_rng(11)
    z = simulate_cv_tracks(rng, 4000, 20, q=0.5, r=0.05)
    kf = KalmanCV(process_psd=0.5, meas_std=0.05, init_vel_std=1.0)
    fc = kf.predict_distribution(z[:, :8], 12)
    assert np.allclose(fc.mean, kf.predict(z[:, :8], 12))
    cov = ellipse_coverage(fc, z[:, 8:])
    # 4000 independent tracks: the coverage's standard error is < 0.008 at every level
    assert np.allclose(cov, LEVELS, atol=0.025), cov
    # the spread grows with the horizon, as F P F^T + Q must
    tr = np.trace(fc.cov, axis1=-2, axis2=-1)
    assert np.all(np.diff(tr, axis=1) > 0)


def test_kalman_distribution_without_measurement_noise_is_narrower():
    rng = np.random.default_rng(12)
    z = simulate_cv_tracks(rng, 10, 10, q=0.5, r=0.1)
    kf = KalmanCV(process_psd=0.5, meas_std=0.1)
    a = kf.predict_distribution(z, 3).cov
    b = kf.predict_distribution(z, 3, measured=False).cov
    assert np.allclose(a - b, 0.01 * np.eye(2))


def test_cv_noise_model_fitted_on_one_set_covers_another_at_nominal_rate():
    from blindspot.traj.distribution import ellipse_coverage

    rng = np.random.default_rng(13)
    fit_set = simulate_cv_tracks(rng, 4000, 20, q=0.5, r=0.05)
    test_set = simulate_cv_tracks(rng, 4000, 20, q=0.5, r=0.05)
    cv = ConstantVelocity().fit(fit_set[:, :8], fit_set[:, 8:])
    fc = cv.predict_distribution(test_set[:, :8], 12)
    assert np.allclose(fc.mean, cv.predict(test_set[:, :8], 12))
    assert np.allclose(ellipse_coverage(fc, test_set[:, 8:]), LEVELS, atol=0.025)
    # homoscedastic truth: the fitted feature exponents stay near zero
    assert np.all(np.abs(cv.noise.beta) < 0.15), cv.noise.beta


def test_cv_noise_model_follows_a_heteroscedastic_population():
    """Process noise density q differing 100-fold between tracks. Theory: the CV error's
    covariance is proportional to q, and so is the expected squared second difference of the
    history (measurement noise kept small), so the fitted exponent of the acceleration feature
    is 1 and that of speed 0. One covariance per step is too wide for the steady tracks and too
    narrow for the erratic ones (50 % ellipse over-covers, 95 % under-covers); the fitted model
    is much closer to nominal and more likely. (Not exactly nominal: q is read off six second
    differences, a noisy estimate, which leaves a Student-t-like tail.)"""
    from blindspot.traj.distribution import ellipse_coverage, gaussian_nll

    rng = np.random.default_rng(14)

    def population(n):
        return simulate_cv_tracks(rng, n, 20, q=0.5, r=0.02,
                                  q_scale=10 ** rng.uniform(-1, 1, n))

    fit_set, test_set = population(4000), population(4000)
    hetero = ConstantVelocity().fit(fit_set[:, :8], fit_set[:, 8:])
    homo = ConstantVelocity().fit(fit_set[:, :8], fit_set[:, 8:], heteroscedastic=False)
    f_het = hetero.predict_distribution(test_set[:, :8], 12)
    f_hom = homo.predict_distribution(test_set[:, :8], 12)
    c_het = ellipse_coverage(f_het, test_set[:, 8:])
    c_hom = ellipse_coverage(f_hom, test_set[:, 8:])
    assert abs(hetero.noise.beta[1] - 1.0) < 0.15 and abs(hetero.noise.beta[0]) < 0.15
    assert c_hom[0] > 0.5 + 0.1 and c_hom[2] < 0.95 - 0.02, c_hom
    assert np.max(np.abs(c_het - LEVELS)) < 0.5 * np.max(np.abs(c_hom - LEVELS)), c_het
    assert gaussian_nll(f_het, test_set[:, 8:]) < gaussian_nll(f_hom, test_set[:, 8:]) - 0.3


def test_cv_distribution_refuses_an_unfitted_model_and_a_longer_horizon():
    rng = np.random.default_rng(15)
    z = simulate_cv_tracks(rng, 50, 14, q=0.5, r=0.05)
    with pytest.raises(HistoryError, match="fit it first"):
        ConstantVelocity().predict_distribution(z[:, :8], 6)
    cv = ConstantVelocity().fit(z[:, :8], z[:, 8:])
    with pytest.raises(HistoryError, match="fitted for 6 steps"):
        cv.predict_distribution(z[:, :8], 7)
    with pytest.raises(HistoryError, match="tracks"):
        cv.fit(z[:10, :8], z[:, 8:])
