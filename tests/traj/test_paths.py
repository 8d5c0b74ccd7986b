"""Synthetic path kinematics checked against geometry: speed, constant-curvature arcs, motion
classes, field of view, and the test noise model's statistics."""

import numpy as np
import pytest

from blindspot.traj.config import DatasetConfig
from blindspot.typed_config import ConfigError
from blindspot.traj.paths import (
    MOTIONS,
    PathSpec,
    integrate_constant_turn,
    radar_like_noise,
    random_path_set,
    random_paths,
)


@pytest.fixture(scope="module")
def pathset():
    return random_path_set(600, PathSpec(), seed=3)


def test_shape_and_determinism():
    a = random_paths(20, seed=5)
    assert a.shape == (20, 200, 2) and a.dtype == np.float64
    assert a.tobytes() == random_paths(20, seed=5).tobytes()
    assert not np.array_equal(a, random_paths(20, seed=6))


def test_speed_is_the_drawn_one_and_in_range(pathset):
    step = np.linalg.norm(np.diff(pathset.xy, axis=1), axis=-1) / 0.1  # (P, 199) m/s
    # a chord of an arc is shorter than the arc by sinc(w dt / 2): < 1e-5 relative at 4 deg/s
    np.testing.assert_allclose(step, np.broadcast_to(pathset.speed_mps[:, None], step.shape), rtol=1e-5)
    assert pathset.speed_mps.min() >= 0.5 and pathset.speed_mps.max() <= 2.0
    # the speed range is actually covered
    assert pathset.speed_mps.min() < 0.6 and pathset.speed_mps.max() > 1.8


def test_constant_turn_is_a_circle_arc():
    v, w, dt = 1.5, np.deg2rad(4.0), 0.1
    xy = integrate_constant_turn(np.array([[2.0, 10.0]]), np.array([v]), np.array([0.3]), np.array([w]), 200, dt)[0]
    # heading 0.3 rad (from +y towards +x), turning clockwise: centre at start + R * (cos psi, -sin psi)
    r = v / w
    centre = np.array([2.0, 10.0]) + r * np.array([np.cos(0.3), -np.sin(0.3)])
    np.testing.assert_allclose(np.linalg.norm(xy - centre, axis=1), r, rtol=1e-12)
    # heading of each step advances by exactly w dt
    d = np.diff(xy, axis=0)
    heading = np.unwrap(np.arctan2(d[:, 0], d[:, 1]))
    np.testing.assert_allclose(np.diff(heading), w * dt, atol=1e-10)


def test_straight_when_no_turn():
    xy = integrate_constant_turn(np.zeros((1, 2)), np.array([1.0]), np.array([np.pi / 2]), np.array([0.0]), 11, 0.1)[0]
    np.testing.assert_allclose(xy, np.stack([np.arange(11) * 0.1, np.zeros(11)], axis=1), atol=1e-12)


def test_motion_classes_match_their_geometry(pathset):
    xy = pathset.xy
    r0 = np.linalg.norm(xy[:, 0], axis=-1)
    radial = (np.linalg.norm(xy[:, 1], axis=-1) - r0) / (0.1 * pathset.speed_mps)  # cos of angle to line of sight
    spread = np.cos(np.deg2rad(45.0))
    tol = 0.02  # one 0.1 s step turns heading and bearing by well under a degree
    appr, rec, perp = (pathset.motion == k for k in range(3))
    assert (radial[appr] < -spread + tol).all()
    assert (radial[rec] > spread - tol).all()
    assert (np.abs(radial[perp]) < np.sin(np.deg2rad(20.0)) + tol).all()
    # "various slopes": headings fill most of the allowed spread, not just radial lines
    assert radial[appr].max() > -0.8 and radial[rec].min() < 0.8
    counts = np.bincount(pathset.motion, minlength=3) / len(pathset.motion)
    np.testing.assert_allclose(counts, 1 / 3, atol=0.06)
    assert len(MOTIONS) == 3


def test_paths_stay_in_field_of_view(pathset):
    spec = PathSpec()
    r = np.hypot(pathset.xy[..., 0], pathset.xy[..., 1])
    ang = np.degrees(np.arctan2(pathset.xy[..., 0], pathset.xy[..., 1]))
    assert r.min() >= spec.min_range_m and r.max() <= spec.max_range_m
    assert np.abs(ang).max() <= spec.max_abs_angle_deg


def test_turn_rates_in_range(pathset):
    deg = np.degrees(pathset.turn_rate_rad_s)
    assert deg.min() >= -4.0 and deg.max() <= 4.0 and deg.std() > 1.5


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"speed_mps": (2.0, 0.5)}, "speed_mps"),
        ({"points_per_path": 1}, "points_per_path"),
        ({"motion_weights": (0, 0, 0)}, "motion_weights"),
        ({"start_range_m": (5.0, 60.0)}, "start_range_m"),
        ({"heading_spread_deg": 120.0}, "heading_spread_deg"),
    ],
)
def test_bad_spec_names_the_key(kwargs, key):
    with pytest.raises(ConfigError, match=key):
        PathSpec(**kwargs)


def test_from_mapping_prefixes_where_and_accepts_lists():
    spec = PathSpec.from_mapping({"speed_mps": [0.6, 1.2], "points_per_path": 100}, "dataset")
    assert spec.speed_mps == (0.6, 1.2) and spec.points_per_path == 100
    with pytest.raises(ConfigError, match=r"dataset\.turn_rate_deg_s"):
        PathSpec.from_mapping({"turn_rate_deg_s": [3.0]}, "dataset")
    with pytest.raises(ConfigError, match=r"dataset\.speed_mp"):
        DatasetConfig.from_mapping({"speed_mp": [0.5, 2.0]})


def test_impossible_field_of_view_raises():
    spec = PathSpec(start_range_m=(5.0, 6.0), max_range_m=6.0, speed_mps=(2.0, 2.0), motion_weights=(0, 1, 0),
                    heading_spread_deg=0.0)
    with pytest.raises(ValueError, match="receding"):
        random_path_set(5, spec, seed=0, max_rounds=3)


def test_noise_model_statistics():
    clean = random_paths(400, seed=11)
    r_true = np.hypot(clean[..., 0], clean[..., 1])
    th_true = np.arctan2(clean[..., 0], clean[..., 1])

    q = radar_like_noise(clean, seed=1, angle_std_deg=0.0, miss_prob=0.0)
    r_q = np.hypot(q[..., 0], q[..., 1])
    np.testing.assert_allclose(r_q / 0.5, np.round(r_q / 0.5), atol=1e-9)  # on the 0.5 m grid
    assert np.abs(r_q - r_true).max() <= 0.25 + 1e-9
    np.testing.assert_allclose(np.arctan2(q[..., 0], q[..., 1]), th_true, atol=1e-12)
    assert abs(np.std(r_q - r_true) - 0.5 / np.sqrt(12)) < 0.01  # uniform quantisation error

    n = radar_like_noise(clean, seed=2, range_step_m=0.0, angle_std_deg=1.0, miss_prob=0.05)
    miss = np.isnan(n).any(axis=-1)
    assert abs(miss.mean() - 0.05) < 0.005
    dth = np.degrees(np.arctan2(n[~miss, 0], n[~miss, 1]) - th_true[~miss])
    assert abs(dth.std() - 1.0) < 0.02
    np.testing.assert_allclose(np.hypot(n[~miss, 0], n[~miss, 1]), r_true[~miss], rtol=1e-12)

    with pytest.raises(ValueError, match="range_mode"):
        radar_like_noise(clean[:1], range_mode="gauss")
    with pytest.raises(ValueError, match=r"\(P, T, 2\)"):
        radar_like_noise(clean[0])


def test_repo_dataset_config_builds_and_covers_the_splits():
    from blindspot.config import compose
    from blindspot.traj.windows import paths_needed
    from tests.conftest import REPO_ROOT

    cfg = compose(config_dir=REPO_ROOT / "conf")  # the paper profile
    spec = DatasetConfig.from_mapping(cfg.dataset)
    assert spec.points_per_path == 200 and spec.speed_mps == (0.5, 2.0)
    assert spec.frame_period_s == cfg.radar.frame_period_s
    split = spec.split
    assert (split.train, split.val, split.test) == (20000, 4000, 500)
    need = paths_needed((split.train, split.val, split.test), spec.points_per_path, spec.window,
                        spec.stride)
    assert spec.n_paths >= need


def test_path_table_back_to_arrays_in_any_row_order():
    """table_to_arrays undoes the paths stage's long table, whatever the row order, and refuses
    rows that are not whole paths."""
    import pandas as pd

    from blindspot.traj.paths import table_to_arrays

    rng = np.random.default_rng(0)
    truth = rng.normal(size=(3, 4, 2))
    meas = truth + 0.1
    meas[1, 2] = np.nan
    table = pd.DataFrame({
        "path_id": np.repeat(np.arange(3), 4), "point": np.tile(np.arange(4), 3),
        "motion": np.repeat(["approaching", "receding", "perpendicular"], 4),
        "x_true_m": truth[..., 0].ravel(), "y_true_m": truth[..., 1].ravel(),
        "x_m": meas[..., 0].ravel(), "y_m": meas[..., 1].ravel()})
    t, m, motion = table_to_arrays(table.sample(frac=1.0, random_state=1))
    np.testing.assert_array_equal(t, truth)
    np.testing.assert_array_equal(m, meas)
    assert list(motion) == ["approaching", "receding", "perpendicular"]
    with pytest.raises(ValueError, match=r"1 of 3 paths are defective \(1 with points not 0..3\)"):
        table_to_arrays(table.iloc[:-1])


def test_path_table_defects_are_refused_or_dropped_with_one_warning():
    """Each kind of defective path is counted; "skip" drops them with one warning."""
    import pandas as pd

    from blindspot.traj.paths import PathDataError, PathSkipWarning, table_to_arrays

    rng = np.random.default_rng(0)
    truth = rng.normal(size=(6, 4, 2))
    table = pd.DataFrame({
        "path_id": np.repeat(np.arange(6), 4), "point": np.tile(np.arange(4), 6),
        "motion": "receding", "x_true_m": truth[..., 0].ravel(),
        "y_true_m": truth[..., 1].ravel(), "x_m": truth[..., 0].ravel(),
        "y_m": truth[..., 1].ravel()})
    table.loc[1, "x_true_m"] = np.nan               # path 0: non-finite truth
    table.loc[6, "y_m"] = np.inf                    # path 1: infinite measured point
    table.loc[9, "x_m"] = np.nan                    # path 2: a missed point (fine)
    table = table.drop(index=13)                    # path 3: a point missing
    table = pd.concat([table, table[table.path_id == 4].iloc[:1]])   # path 4: a repeated row
    with pytest.raises(PathDataError, match=r"paths.parquet: 4 of 6 paths are defective "
                       r"\(1 with repeated \(path_id, point\) rows, 1 with points not 0..3, "
                       r"1 with non-finite truth, 1 with infinite measured points\); the first "
                       r"is path_id 0"):
        table_to_arrays(table, source="paths.parquet")
    with pytest.warns(PathSkipWarning, match="dropped 4 of 6 paths") as caught:
        t, m, _ = table_to_arrays(table, source="paths.parquet", bad_paths="skip")
    assert len(caught) == 1
    np.testing.assert_array_equal(t, truth[[2, 5]])
    assert np.isnan(m[0, 1, 0]) and np.isfinite(m[1]).all()
    with pytest.raises(PathDataError, match="missing \\['motion'\\]"):
        table_to_arrays(table.drop(columns="motion"))
