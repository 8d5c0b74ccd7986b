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
