"""The approach test (issue 40, blindspot.track.crossing.approach_z and moving_frames'
``approach_probability``) and the decision's coasting limit (blindspot.track.moving.coast_frames,
blindspot.safety.predict.decision_rows): the one-sided test's false-alarm rate on static
objects against its nominal 1 - p (theory), its direction, and the rows a decision reads."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy.stats import chi2, norm

from blindspot.safety.predict import decision_rows
from blindspot.track.config import MovingConfig
from blindspot.track.crossing import approach_z
from blindspot.track.moving import (coast_frames, moving_frames, moving_test_settings,
                                     moving_tracks)
from blindspot.typed_config import ConfigError

EGO = pd.DataFrame({"group": "g", "frame": np.arange(6), "ego_x_m": 0.0,
                    "ego_y_m": 0.0, "ego_yaw_deg": 0.0})


def _rows(vx, vy, x=2.0, y=12.0, cov=((0.16, 0.0), (0.0, 0.16))):
    """Rows of one track at frame 0..k-1 beside a +y-heading ego's path (x > 0: right)."""
    vx, vy = np.atleast_1d(vx).astype(float), np.atleast_1d(vy).astype(float)
    k = len(vx)
    return pd.DataFrame({"group": "g", "track_id": 1, "frame": np.arange(k) % 6,
                         "x_m": x, "y_m": y, "vx_mps": vx, "vy_mps": vy,
                         "cov_vxvx": cov[0][0], "cov_vxvy": cov[0][1], "cov_vyvy": cov[1][1],
                         "confirmed": True, "n_points": 1, "doppler_mps": 0.0})


def test_approach_z_is_the_velocity_toward_the_path_in_its_own_sigmas():
    cov = ((0.25, 0.1), (0.1, 0.09))
    z = approach_z(_rows([-1.0, 1.0, 0.0], [0.3, 0.3, 2.0], cov=cov), EGO, 5.0)
    # right of the path: toward it is -x; sigma along -x is sqrt(0.25)
    assert z == pytest.approx([1.0 / 0.5, -1.0 / 0.5, 0.0])
    left = approach_z(_rows([1.0], [0.0], x=-2.0, cov=cov), EGO, 5.0)
    assert left == pytest.approx([2.0])                     # left of it: toward is +x
    # outside the corridor, behind the radar: 0
    assert approach_z(_rows([-1.0], [0.0], x=6.0), EGO, 5.0)[0] == 0.0
    assert approach_z(_rows([-1.0], [0.0], y=-3.0), EGO, 5.0)[0] == 0.0


@pytest.mark.parametrize("yaw_deg", [90.0, 45.0, -30.0])
def test_approach_z_follows_the_ego_heading(yaw_deg):
    # heading (-sin yaw, cos yaw), left (-cos yaw, -sin yaw) (yaw counter-clockwise from +y);
    # a track 10 m ahead and 2 m to the right moves toward the path along +left
    a = np.radians(yaw_deg)
    fwd, left = np.array([-np.sin(a), np.cos(a)]), np.array([-np.cos(a), -np.sin(a)])
    pos, v = 10 * fwd - 2 * left, 1.0 * left + 0.5 * fwd
    cov = np.array([[0.2, 0.05], [0.05, 0.1]])
    ego = EGO.assign(ego_yaw_deg=yaw_deg, ego_x_m=3.0, ego_y_m=-1.0)
    rows = _rows([v[0]], [v[1]], x=3.0 + pos[0], y=-1.0 + pos[1], cov=cov)
    want = 1.0 / np.sqrt(left @ cov @ left)        # written out: c = left, c.v = 1
    assert approach_z(rows, ego, 5.0)[0] == pytest.approx(want)
    away = rows.assign(vx_mps=-v[0], vy_mps=-v[1])
    assert approach_z(away, ego, 5.0)[0] == pytest.approx(-want)


def test_static_objects_pass_at_the_nominal_one_sided_rate():
    # a static object's filtered velocity is N(0, P_v): the test's false alarms per row are
    # 1 - p (theory), for any P_v; the chi-square test at p passes 1 - p too, on both axes
    rng = np.random.default_rng(4)
    cov = np.array([[0.3, 0.12], [0.12, 0.2]])
    v = rng.multivariate_normal([0, 0], cov, 40_000)
    rows = _rows(v[:, 0], v[:, 1], cov=cov)
    z = approach_z(rows, EGO, 5.0)
    for p in (0.9, 0.95):
        rate = np.mean(z > norm.ppf(p))
        assert rate == pytest.approx(1 - p, abs=3 * np.sqrt(p * (1 - p) / len(z)))


def test_a_slow_crosser_passes_the_approach_test_before_the_chi_square():
    # 0.6 m/s toward the path with 0.4 m/s of sigma: 1.5 sigma, under the 2-dof chi-square's
    # 3.03 sigma at 0.99, over the one-sided 1.28 sigma at 0.9
    rows = _rows([-0.6, 0.6], [0.0, 0.0])
    assert 0.6 ** 2 / 0.16 < chi2.ppf(0.99, 2)
    assert not moving_frames(rows, 0.5, 0.99).any()
    got = moving_frames(rows, 0.5, 0.99, ego=EGO, approach_probability=0.9)
    assert list(got) == [True, False]                       # walking away from it: not
    assert not moving_frames(rows, 0.5, 0.99, ego=EGO, approach_probability=0.9,
                             approach_corridor_m=1.0).any()  # 2 m beside it, corridor 1 m
    slow = _rows([-0.45], [0.0], cov=((0.01, 0.0), (0.0, 0.01)))
    assert not moving_frames(slow, 0.5, 0.99, ego=EGO, approach_probability=0.9).any()


def test_approach_test_checks_its_arguments():
    rows = _rows([-0.6], [0.0])
    with pytest.raises(ValueError, match="approach_probability: expected a number in"):
        moving_tracks(rows, 0.5, ego=EGO, approach_probability=1.0)
    with pytest.raises(ValueError, match="ego: expected the ego's poses .* approach test"):
        moving_tracks(rows, 0.5, approach_probability=0.9)
    with pytest.raises(ValueError, match="corridor_m"):
        approach_z(rows, EGO, 0.0)
    with pytest.raises(ValueError, match=r"missing columns \['cov_vyvy'\]"):
        approach_z(rows.drop(columns="cov_vyvy"), EGO, 5.0)
    base = dict(speed_mps=0.5, probability=0.99, doppler_std_mps=0.3,
                doppler_log_ratio_min=-2.3)
    with pytest.raises(ConfigError, match="tracker.moving.approach_probability"):
        MovingConfig.from_mapping({**base, "approach_probability": 1.5})
    with pytest.raises(ValueError, match="approach_corridor_m"):
        moving_tracks(rows, 0.5, ego=EGO, approach_probability=0.9, approach_corridor_m=0.0)
    settings = moving_test_settings(MovingConfig.from_mapping(
        {**base, "approach_probability": 0.8, "crossing_corridor_m": 3.0}))
    assert settings["approach_probability"] == 0.8 and settings["approach_corridor_m"] == 3.0


def test_coast_frames_counts_frames_since_the_last_measurement():
    t = pd.DataFrame({"group": "g", "track_id": [1] * 6 + [2] * 3,
                      "frame": [0, 1, 2, 3, 4, 5, 3, 4, 5],
                      "coasting": [True, False, True, True, False, True, True, True, False]})
    shuffled = t.sample(frac=1, random_state=0)
    assert list(coast_frames(t)) == [0, 0, 1, 2, 0, 1, 0, 1, 0]
    assert list(coast_frames(shuffled)) == list(coast_frames(t)[shuffled.index])
    # another group with the same track id keeps its own count
    both = pd.concat([t, t.assign(group="h", coasting=False)], ignore_index=True)
    assert list(coast_frames(both)) == [0, 0, 1, 2, 0, 1, 0, 1, 0] + [0] * 9
    with pytest.raises(ValueError, match=r"missing columns \['coasting'\]"):
        coast_frames(t.drop(columns="coasting"))


def test_decision_rows_drop_long_coasting_moving_rows_only_with_the_limit():
    t = pd.DataFrame({"group": "g", "track_id": 1, "frame": np.arange(7),
                      "confirmed": [False] + [True] * 6, "moving": [False, False] + [True] * 5,
                      "coasting": [False, False, False, True, True, True, True]})
    assert list(decision_rows(t, 0.1, None)) == [False, False] + [True] * 5
    assert list(decision_rows(t, 0.1, 0.3)) == [False, False, True, True, True, True, False]
    assert list(decision_rows(t, 0.1, 0.0)) == [False, False, True] + [False] * 4
    assert decision_rows(t.drop(columns="coasting"), 0.1, None).sum() == 5  # no limit
    with pytest.raises(ValueError, match=r"missing columns \['coasting'\]"):
        decision_rows(t.drop(columns="coasting"), 0.1, 0.3)
    with pytest.raises(ValueError, match="max_coast_s"):
        decision_rows(t, 0.1, -0.1)
    with pytest.raises(ValueError, match="dt_s"):
        decision_rows(t, 0.0, 0.3)
