"""The crossing prior (issue 40, blindspot.track.crossing): its closed-form likelihood ratio and
posterior against the explicit Gaussian densities (scipy), its sign for a crosser and a static
object, its window, the prior swap of the decision's velocity, and the tracker's per-hit
Doppler (range-rate) update against the Kalman update written out."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest
from omegaconf import OmegaConf
from scipy.stats import multivariate_normal, norm

from blindspot.track import TrackerConfig, track_points
from blindspot.track.crossing import CrossingPrior, crossing_evidence, crossing_state, toward_path
from blindspot.track.moving import moving_tracks
from tests.conftest import REPO_ROOT

EGO = pd.DataFrame({"group": "g", "frame": np.arange(6), "ego_x_m": 0.0,
                    "ego_y_m": np.arange(6) * 1.0, "ego_yaw_deg": 0.0})


def _track(dopplers, n_points=(1, 2, 1, 3, 1, 2), x=2.0, y0=12.0):
    """One track beside the path (x = 2 m right of a +y-heading ego), one row per Doppler."""
    k = len(dopplers)
    return pd.DataFrame({"group": "g", "track_id": 7, "frame": np.arange(k),
                         "x_m": x - 0.14 * np.arange(k), "y_m": y0 + 0.0 * np.arange(k),
                         "n_points": list(n_points[:k]), "doppler_mps": dopplers,
                         "confirmed": [False] + [True] * (k - 1),
                         "vx_mps": 0.0, "vy_mps": 0.0, "cov_vxvx": 2.25, "cov_vxvy": 0.0,
                         "cov_vyvy": 2.25})


def _explicit(tr, prior):
    """The log likelihood ratio and posterior of the module docstring, by dense Gaussians."""
    c, _, _, u = toward_path(tr, EGO)
    b = (u * c).sum(axis=1)
    n, d = tr.n_points.to_numpy(float), tr.doppler_mps.to_numpy(float)
    cov1 = np.diag(prior.walker_std_mps ** 2 / n) + prior.speed_std_mps ** 2 * np.outer(b, b)
    l1 = multivariate_normal(prior.speed_mps * b, cov1).logpdf(d)
    l0 = norm(0.0, prior.static_std_mps / np.sqrt(n)).logpdf(d).sum()
    w = n / prior.walker_std_mps ** 2
    prec = 1 / prior.speed_std_mps ** 2 + (w * b * b).sum()
    return l1 - l0, (prior.speed_mps / prior.speed_std_mps ** 2 + (w * b * d).sum()) / prec


@pytest.mark.parametrize("k", [1, 2, 3])
def test_log_ratio_and_posterior_match_the_dense_gaussians(k):
    rng = np.random.default_rng(k)
    tr = _track(rng.normal(-0.2, 0.3, k))
    prior = CrossingPrior(window=3)
    llr, speed, sd = crossing_evidence(tr, EGO, prior)
    want_llr, want_speed = _explicit(tr, prior)
    assert llr[-1] == pytest.approx(want_llr, abs=1e-9)
    assert speed[-1] == pytest.approx(want_speed, abs=1e-9)
    assert 0 < sd[-1] < prior.speed_std_mps


def test_a_crosser_scores_positive_and_a_static_object_negative():
    prior = CrossingPrior()
    tr = _track([0.0] * 3)
    c, _, _, u = toward_path(tr, EGO)
    b = (u * c).sum(axis=1)
    assert (b < 0).all()                     # toward the path from the right: range rate < 0
    crosser, _, _ = crossing_evidence(tr.assign(doppler_mps=1.4 * b), EGO, prior)
    static, _, _ = crossing_evidence(tr, EGO, prior)
    assert crosser[-1] > 2.0 and static[-1] < -1.0


def test_rows_after_the_window_keep_the_window_value_and_any_order_works():
    tr = _track([-0.3, -0.25, -0.2, 0.9, 0.8, 0.7])
    llr, _, _ = crossing_evidence(tr, EGO, CrossingPrior(window=3))
    assert llr[3:] == pytest.approx([llr[2]] * 3)
    perm = np.random.default_rng(0).permutation(len(tr))
    again, _, _ = crossing_evidence(tr.iloc[perm], EGO, CrossingPrior(window=3))
    np.testing.assert_allclose(again, llr[perm])


def test_outside_the_corridor_or_behind_the_radar_adds_nothing():
    far, _, _ = crossing_evidence(_track([-0.3] * 3, x=8.0), EGO, CrossingPrior(corridor_m=5.0))
    behind, _, _ = crossing_evidence(_track([-0.3] * 3, y0=-4.0), EGO, CrossingPrior())
    assert (far == 0).all() and (behind == 0).all()


def test_the_prior_swap_is_the_product_of_gaussians_along_the_crossing_direction():
    """Velocity along c = (-1, 0) uncorrelated with the rest: the swapped posterior is the
    filter's likelihood (its posterior divided by the N(0, 1.5^2) prior) times N(1.4, 0.5^2)."""
    tr = _track([-0.2] * 2).assign(vx_mps=-0.3, vy_mps=0.05, cov_vxvx=0.5, cov_vxvy=0.0,
                                   cov_vyvy=0.3, cov_xx=0.02, cov_xy=0.0, cov_yy=0.02,
                                   cov_xvx=0.0, cov_xvy=0.0, cov_yvx=0.0, cov_yvy=0.01)
    out = crossing_state(tr, EGO, CrossingPrior(speed_mps=1.4, speed_std_mps=0.5),
                         np.array([False, True]), init_velocity_std_mps=1.5)
    pd.testing.assert_frame_equal(out.iloc[:1], tr.iloc[:1])
    m, p = 0.3, 0.5                                  # c.v and its variance from the tracker
    like_prec = 1 / p - 1 / 1.5 ** 2
    like_mean = (m / p) / like_prec                  # the N(0, s0^2) prior divided out
    p_new = 1 / (like_prec + 1 / 0.25)
    m_new = p_new * (like_prec * like_mean + 1.4 / 0.25)
    assert out.vx_mps.iloc[1] == pytest.approx(-m_new)
    assert out.cov_vxvx.iloc[1] == pytest.approx(p_new)
    assert out.vy_mps.iloc[1] == pytest.approx(0.05) and out.cov_vyvy.iloc[1] == pytest.approx(0.3)


def test_the_prior_swap_keeps_the_covariance_positive_semi_definite():
    """After a tight Doppler update the velocity is correlated along the line of sight, which is
    not perpendicular to c; the swap must keep the state covariance a covariance."""
    u = np.array([2.0, 10.0]) / np.hypot(2.0, 10.0)
    pv = 2.25 * np.eye(2)
    g = pv @ u / (u @ pv @ u + 0.05 ** 2)
    pv = pv - np.outer(g, u @ pv)
    tr = _track([-0.2]).assign(x_m=2.0, y_m=10.0, cov_vxvx=pv[0, 0], cov_vxvy=pv[0, 1],
                               cov_vyvy=pv[1, 1], cov_xx=0.02, cov_xy=0.0, cov_yy=0.02,
                               cov_xvx=0.0, cov_xvy=0.0, cov_yvx=0.0, cov_yvy=0.0)
    out = crossing_state(tr, EGO, CrossingPrior(), np.array([True]), 1.5).iloc[0]
    v = np.array([[out.cov_vxvx, out.cov_vxvy], [out.cov_vxvy, out.cov_vyvy]])
    assert np.linalg.eigvalsh(v).min() >= -1e-12
    on_line = crossing_state(tr.assign(x_m=0.0), EGO, CrossingPrior(), np.array([True]), 1.5)
    assert np.isfinite(on_line[["vx_mps", "vy_mps"]].to_numpy()).all()


def test_moving_tracks_takes_the_crossing_test_and_checks_its_pair():
    prior = CrossingPrior()
    tr = _track([0.0] * 3)
    c, _, _, u = toward_path(tr, EGO)
    crosser = tr.assign(doppler_mps=1.4 * (u * c).sum(axis=1))
    assert not moving_tracks(crosser, 0.5).any()            # zero velocity: kinematics say no
    m = moving_tracks(crosser, 0.5, ego=EGO, crossing_prior=prior, crossing_log_ratio=1.0)
    assert list(m) == [False, True, True]                   # from its first confirmed row
    assert not moving_tracks(tr, 0.5, ego=EGO, crossing_prior=prior,
                             crossing_log_ratio=1.0).any()
    with pytest.raises(ValueError, match="crossing_prior, crossing_log_ratio: expected both"):
        moving_tracks(crosser, 0.5, ego=EGO, crossing_prior=prior)
    with pytest.raises(ValueError, match="ego: missing columns .*ego_yaw_deg"):
        moving_tracks(crosser, 0.5, ego=EGO.drop(columns="ego_yaw_deg"), crossing_prior=prior,
                      crossing_log_ratio=2.0)


@pytest.mark.parametrize("bad", [dict(speed_mps=0.0), dict(static_std_mps=-1.0),
                                 dict(window=0), dict(window=1.5)])
def test_the_prior_refuses_bad_settings(bad):
    with pytest.raises(ValueError, match=next(iter(bad))):
        CrossingPrior(**bad)


def test_crossing_state_refuses_rows_of_another_length_and_a_wider_prior():
    with pytest.raises(ValueError, match="rows: expected a bool array of length 2"):
        crossing_state(_track([0.0] * 2), EGO, CrossingPrior(), np.array([True]), 1.5)
    with pytest.raises(ValueError, match="prior.speed_std_mps: expected less than"):
        crossing_state(_track([0.0]), EGO, CrossingPrior(speed_std_mps=2.0), np.array([True]),
                       1.5)


def test_the_window_is_the_first_measured_rows_from_birth():
    """A track whose first rows lie outside the corridor is not young when it enters it."""
    tr = _track([-0.3] * 6).assign(x_m=[9.0, 9.0, 9.0, 2.0, 2.0, 2.0])
    llr, _, _ = crossing_evidence(tr, EGO, CrossingPrior(window=3, corridor_m=5.0))
    assert (llr == 0).all()


def test_the_per_hit_doppler_update_is_the_scalar_kalman_update():
    """Two frames of one object: with doppler_update_std_mps the second row's state equals the
    position-only row updated by d = u.v + e written out by hand."""
    cfg = TrackerConfig.from_mapping(OmegaConf.load(REPO_ROOT / "conf" / "tracker" / "gnn_cv.yaml"))
    cfg = dataclasses.replace(cfg, init_doppler_std_mps=None, init_doppler_along_std_mps=None,
                              doppler_confirm_log_ratio=None, doppler_update_std_mps=None,
                              confirm_m=1, confirm_n=1)
    pts = pd.DataFrame({"frame": [0, 1], "time_s": [0.0, 0.1], "x_m": [3.0, 2.9],
                        "y_m": [10.0, 10.0], "velocity_over_ground_mps": [-0.4, -0.4],
                        "sensor_x_m": 0.0, "sensor_y_m": 0.0})
    plain = track_points(pts, cfg)
    upd = track_points(pts, dataclasses.replace(cfg, doppler_update_std_mps=0.5))
    row = plain.iloc[-1]
    x = np.array([row.x_m, row.vx_mps, row.y_m, row.vy_mps])
    p = np.array([[row.cov_xx, row.cov_xvx, row.cov_xy, row.cov_xvy],
                  [row.cov_xvx, row.cov_vxvx, row.cov_yvx, row.cov_vxvy],
                  [row.cov_xy, row.cov_yvx, row.cov_yy, row.cov_yvy],
                  [row.cov_xvy, row.cov_vxvy, row.cov_yvy, row.cov_vyvy]])
    u = np.array([row.x_m, row.y_m]) / np.hypot(row.x_m, row.y_m)
    h = np.array([0.0, u[0], 0.0, u[1]])
    k = p @ h / (h @ p @ h + 0.25)
    want = x + k * (-0.4 - h @ x)
    got = upd.iloc[-1]
    np.testing.assert_allclose([got.x_m, got.vx_mps, got.y_m, got.vy_mps], want, atol=1e-9)
    assert got.vx_mps * u[0] + got.vy_mps * u[1] < row.vx_mps * u[0] + row.vy_mps * u[1]
