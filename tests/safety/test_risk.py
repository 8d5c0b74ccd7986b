"""Collision probability against theory: the footprint mass of a Gaussian equals the bivariate
normal CDF's rectangle difference (scipy), a tight Gaussian inside the footprint gives ~1 and a
far one ~0, Boole's bounds order, TTC of a pedestrian standing in the ego's path."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.special import ndtr
from scipy.stats import multivariate_normal

from blindspot.safety.risk import (EgoShape, RiskError, collision_risk, footprints,
                                  rectangle_mass)
from blindspot.traj.distribution import GaussianForecast

EGO = EgoShape(1.815, 4.358)


def _scipy_rect(mean, cov, lo, hi):
    F = multivariate_normal(mean, cov).cdf
    return F(hi) - F([lo[0], hi[1]]) - F([hi[0], lo[1]]) + F(lo)


@settings(max_examples=25, deadline=None)
@given(mx=st.floats(-2, 2), my=st.floats(-2, 2), sx=st.floats(0.05, 2), sy=st.floats(0.05, 2),
       rho=st.floats(-0.9, 0.9), x0=st.floats(-3, 1), y0=st.floats(-3, 1),
       wx=st.floats(0.1, 4), wy=st.floats(0.1, 4))
def test_rectangle_mass_equals_bivariate_normal_cdf(mx, my, sx, sy, rho, x0, y0, wx, wy):
    cov = np.array([[sx**2, rho * sx * sy], [rho * sx * sy, sy**2]])
    lo, hi = np.array([x0, y0]), np.array([x0 + wx, y0 + wy])
    ref = _scipy_rect([mx, my], cov, lo, hi)
    assert rectangle_mass(np.array([mx, my]), cov, lo, hi) == pytest.approx(ref, abs=2e-5)


def _forecast(xy, std, H=10):
    B = len(xy)
    mean = np.broadcast_to(np.asarray(xy, float)[:, None, :], (B, H, 2)).copy()
    cov = np.broadcast_to(std**2 * np.eye(2), (B, H, 2, 2)).copy()
    return GaussianForecast(mean, cov)


def test_inside_wide_footprint_is_certain_and_far_away_is_impossible():
    # ego at the origin heading +y, at rest: footprint x in [-W/2 - r, W/2 + r], y in [-L - r, r]
    fc = _forecast([[0.0, -2.0], [15.0, 30.0]], 0.05)
    r = collision_risk(fc, np.zeros((2, 2)), np.zeros(2), np.zeros(2), 0.1, EGO, margin_m=0.3)
    assert r.p_collision[0] == pytest.approx(1.0, abs=1e-9)
    assert r.p_collision[1] == pytest.approx(0.0, abs=1e-12)


def test_world_to_vehicle_rotation_and_boole_bounds():
    # ego at (10, 5) heading -x (yaw +90 deg): a point 2 m ahead of it is (8, 5) in the world
    fc = _forecast([[8.0, 5.0]], 0.4)
    kw = dict(margin_m=0.3)
    lo = collision_risk(fc, np.array([[10.0, 5.0]]), np.radians([90.0]), np.array([5.0]), 0.1,
                        EGO, method="max_step", **kw)
    hi = collision_risk(fc, np.array([[10.0, 5.0]]), np.radians([90.0]), np.array([5.0]), 0.1,
                        EGO, method="union", **kw)
    assert 0.3 < lo.p_collision[0] <= hi.p_collision[0] <= 1.0
    assert lo.p_step.max() == pytest.approx(lo.p_collision[0])


def test_ttc_of_a_pedestrian_standing_ahead():
    # 10 m ahead, ego at 5 m/s, margin 0.3 m: the bumper reaches y = 9.7 m at 1.94 s -> step 20
    fc = _forecast([[0.0, 10.0]], 0.05, H=30)
    r = collision_risk(fc, np.zeros((1, 2)), np.zeros(1), np.array([5.0]), 0.1, EGO,
                       margin_m=0.3)
    assert r.ttc_s[0] == pytest.approx(2.0)
    # at 1.9 s the footprint's front edge is at 9.5 + 0.3 m: the mass beyond 4 sigma stays out
    assert r.p_step[0, 18] == pytest.approx(1 - ndtr(4.0), rel=1e-6)
    assert r.p_step[0, 19] > 0.999
    none = collision_risk(_forecast([[4.0, 10.0]], 0.05, H=30), np.zeros((1, 2)), np.zeros(1),
                          np.array([5.0]), 0.1, EGO, margin_m=0.3)
    assert np.isnan(none.ttc_s[0])


def test_bad_method_and_dt_are_refused():
    fc = _forecast([[0.0, 1.0]], 0.1)
    with pytest.raises(RiskError, match="method"):
        collision_risk(fc, np.zeros((1, 2)), np.zeros(1), np.ones(1), 0.1, EGO, margin_m=0.3,
                       method="mean")
    with pytest.raises(RiskError, match="dt_s"):
        collision_risk(fc, np.zeros((1, 2)), np.zeros(1), np.ones(1), 0.0, EGO, margin_m=0.3)


# --- every argument checked by the function itself (issue 45; case t3_c15) -------------------
_ARGS = (np.zeros((1, 2)), np.zeros(1))


def test_negative_margin_is_refused_by_collision_risk_itself():
    # t3_c15: margin_m=-0.5 shrank the footprint to 0.8 m and gave p = 0 for a pedestrian
    # standing in the ego's path (p = 0.977 with +0.3); the function's own error names it
    fc = _forecast([[1.0, 3.0]], 0.1, H=30)
    with pytest.raises(RiskError, match=r"collision_risk: margin_m: .*>= 0.*found -0\.5"):
        collision_risk(fc, *_ARGS, np.array([5.0]), 0.1, EgoShape(1.8, 4.5), margin_m=-0.5)


@settings(max_examples=30, deadline=None)
@given(margin=st.one_of(st.floats(max_value=-1e-9), st.just(float("nan")),
                        st.just(float("inf"))))
def test_every_bad_margin_is_named(margin):
    fc = _forecast([[1.0, 3.0]], 0.1)
    with pytest.raises(RiskError, match="margin_m"):
        collision_risk(fc, *_ARGS, np.array([5.0]), 0.1, EGO, margin_m=margin)
    with pytest.raises(RiskError, match="footprints: margin_m"):
        footprints(np.array([5.0]), 10, 0.1, EGO, margin)


@settings(max_examples=30, deadline=None)
@given(speed=st.one_of(st.floats(max_value=-1e-9), st.sampled_from([np.nan, np.inf, -np.inf])))
def test_every_bad_speed_is_named(speed):
    fc = _forecast([[1.0, 3.0]], 0.1)
    with pytest.raises(RiskError, match="collision_risk: speed_mps"):
        collision_risk(fc, *_ARGS, np.array([speed]), 0.1, EGO, margin_m=0.3)
    with pytest.raises(RiskError, match="footprints: speed_mps"):
        footprints(np.array([speed]), 10, 0.1, EGO, 0.3)


@pytest.mark.parametrize("dt", [0.0, -0.1, float("nan"), float("inf")])
def test_bad_period_and_horizon_are_named(dt):
    with pytest.raises(RiskError, match="footprints: dt_s"):
        footprints(np.ones(1), 10, dt, EGO, 0.3)
    with pytest.raises(RiskError, match="collision_risk: dt_s"):
        collision_risk(_forecast([[0.0, 1.0]], 0.1), *_ARGS, np.ones(1), dt, EGO, margin_m=0.3)
    for horizon in (0, -3, 2.5):
        with pytest.raises(RiskError, match=f"footprints: horizon: .*found {horizon}"):
            footprints(np.ones(1), horizon, 0.1, EGO, 0.3)


@pytest.mark.parametrize("w, l", [(0.0, 4.0), (1.8, -1.0), (float("nan"), 4.0), (1.8, np.inf)])
def test_ego_shape_is_finite_and_positive(w, l):
    with pytest.raises(RiskError, match="EgoShape: (width_m|length_m)"):
        EgoShape(w, l)


def test_zero_margin_and_zero_speed_are_valid():
    lo, hi = footprints(np.zeros(1), 3, 0.1, EGO, 0.0)
    assert lo.shape == hi.shape == (1, 3, 2)
    assert np.allclose(hi[0, :, 0], EGO.width_m / 2)


def test_a_mixture_collides_with_the_probability_of_its_colliding_hypotheses():
    """Issue 43: a child at the kerb stops (far from the car) with probability 0.7 or crosses
    into the footprint with 0.3: P(collision) is 0.3 x that of the crossing path alone (its
    mass is the weighted sum of its components'), where the moment-matched Gaussian would say
    something else; one hypothesis is collision_risk itself; a non-mixture is named."""
    from blindspot.safety.risk import mixture_collision_risk
    from blindspot.traj.mixture import MixtureForecast

    H = 10
    cross = np.tile([[0.0, -2.0]], (H, 1))               # inside the footprint at every step
    stop = np.tile([[15.0, 30.0]], (H, 1))               # far away
    means = np.stack([stop, cross])[None]                # (1, 2, H, 2)
    covs = np.broadcast_to(np.eye(2) * 0.05**2, (1, 2, H, 2, 2))
    mix = MixtureForecast(np.array([[0.7, 0.3]]), means, covs)
    args = (np.zeros((1, 2)), np.zeros(1), np.zeros(1), 0.1, EGO)
    r = mixture_collision_risk(mix, *args, margin_m=0.3)
    alone = collision_risk(mix.component(1), *args, margin_m=0.3)
    assert alone.p_collision[0] == pytest.approx(1.0, abs=1e-9)
    assert r.p_collision[0] == pytest.approx(0.3, abs=1e-9)
    assert np.allclose(r.p_step, 0.3 * alone.p_step)
    one = MixtureForecast(np.ones((1, 1)), means[:, 1:], covs[:, 1:])
    assert np.array_equal(mixture_collision_risk(one, *args, margin_m=0.3).p_step, alone.p_step)
    with pytest.raises(RiskError, match="mixture"):
        mixture_collision_risk(mix.component(0), *args, margin_m=0.3)


def test_risk_table_scores_a_predictor_with_a_mixture_by_its_mixture():
    """A predictor offering predict_mixture (issue 43) is scored by mixture_collision_risk in
    risk_table; one offering only predict_distribution as before."""
    import pandas as pd

    from blindspot.safety.predict import risk_table
    from blindspot.safety.risk import mixture_collision_risk
    from blindspot.traj.mixture import MixtureForecast

    class Forking:
        """Stops 15 m aside (0.6) or walks to the bumper (0.4), whatever the history."""
        name = "forking"

        def predict_mixture(self, history, horizon):
            b = history.shape[0]
            means = np.stack([np.tile([[15.0, 30.0]], (horizon, 1)),
                              np.tile([[0.0, -2.0]], (horizon, 1))])
            return MixtureForecast(np.tile([0.6, 0.4], (b, 1)),
                                   np.broadcast_to(means, (b, 2, horizon, 2)),
                                   np.broadcast_to(np.eye(2) * 0.01, (b, 2, horizon, 2, 2)))

        def predict_distribution(self, history, horizon):
            return self.predict_mixture(history, horizon).to_gaussian()

    tracks = pd.DataFrame({"group": "g", "frame": [0, 1], "track_id": 1, "x_m": [0.0, 0.0],
                           "y_m": [-2.0, -2.0], "confirmed": True})
    ego = pd.DataFrame({"group": "g", "frame": [0, 1], "ego_x_m": 0.0, "ego_y_m": 0.0,
                        "ego_yaw_deg": 0.0, "ego_speed_mps": 0.0})
    out = risk_table(tracks, ego, {"forking": Forking()}, horizon=5, dt_s=0.1, shape=EGO,
                     margin_m=0.3, method="max_step", max_len=10, max_coast_s=None)
    assert np.allclose(out.p_collision, 0.4)
    mix = Forking().predict_mixture(np.zeros((1, 2, 2)), 5)
    assert np.allclose(out.p_collision, mixture_collision_risk(
        mix, np.zeros((1, 2)), np.zeros(1), np.zeros(1), 0.1, EGO, margin_m=0.3).p_collision)
