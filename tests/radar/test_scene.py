"""The paper scene (Fig. 5): geometry, walking kinematics, occlusion timing, configs."""

import dataclasses

import numpy as np
import pytest
from omegaconf import OmegaConf

from blindspot.radar.config import RadarConfig
from blindspot.typed_config import ConfigError
from blindspot.radar.occlusion import point_in_polygon
from blindspot.radar.scene import TRUTH_COLUMNS, Scene, load_scenes, scene_truth
from tests.conftest import REPO_ROOT

RADAR = RadarConfig.from_mapping(OmegaConf.load(REPO_ROOT / "conf/radar/mmwcas.yaml"))
GROUP = OmegaConf.load(REPO_ROOT / "conf/scene/paper.yaml")
SCENES = load_scenes(GROUP)
TURNS = {"straight": 0.0, "approach": 45.0, "recede": -45.0}


def test_six_paper_scenes_three_directions_with_and_without_car():
    assert len(SCENES) == 6
    combos = {(c.pedestrian.turn_deg, c.with_car) for c in SCENES.values()}
    assert combos == {(t, w) for t in (0.0, 45.0, -45.0) for w in (True, False)}
    assert all(c.n_frames == 100 for c in SCENES.values())
    assert len({c.seed for c in SCENES.values()}) == 6
    for name, c in SCENES.items():
        assert c.pedestrian.turn_deg == TURNS[name.split("_")[0]]
        assert c.with_car == name.endswith("_car")


@pytest.mark.parametrize("name", sorted(SCENES))
def test_truth_columns_speed_and_turn(name):
    cfg = SCENES[name]
    tr = scene_truth(cfg, RADAR)
    assert list(tr.columns) == list(TRUTH_COLUMNS) and len(tr) == 100
    np.testing.assert_allclose(np.diff(tr.time_s), RADAR.frame_period_s)
    # speed from the positions (finite differences), not from the velocity columns
    step = np.hypot(np.diff(tr.x_m), np.diff(tr.y_m)) / np.diff(tr.time_s)
    assert step.min() > 1.0 - 1e-6 and step.max() < 1.5
    np.testing.assert_allclose(np.hypot(tr.vx_mps, tr.vy_mps), cfg.pedestrian.speed_mps)
    # polar columns agree with x = R sin(theta), y = R cos(theta)
    th = np.radians(tr.angle_deg)
    np.testing.assert_allclose(tr.range_m * np.sin(th), tr.x_m, atol=1e-9)
    np.testing.assert_allclose(tr.range_m * np.cos(th), tr.y_m, atol=1e-9)
    # heading before and after the turn, counter-clockwise from the walking direction (-x)
    first = np.degrees(np.arctan2(tr.vy_mps.iloc[0], tr.vx_mps.iloc[0]))
    last = np.degrees(np.arctan2(tr.vy_mps.iloc[-1], tr.vx_mps.iloc[-1]))
    assert first == pytest.approx(180.0)
    assert (last - first + 180) % 360 - 180 == pytest.approx(cfg.pedestrian.turn_deg, abs=1e-6)
    # after the turn (the last 30 frames, t >= 7 s): approaching = range falls, receding = rises
    dr = np.diff(tr.range_m.to_numpy()[-30:])
    if cfg.pedestrian.turn_deg > 0:
        assert (dr < 0).all() and (tr.radial_velocity_mps.iloc[-30:] < -0.3).all()
    elif cfg.pedestrian.turn_deg < 0:
        assert (dr > 0).all() and (tr.radial_velocity_mps.iloc[-30:] > 0.3).all()
    else:  # straight on, across the boresight: range changes slowly
        assert np.abs(tr.radial_velocity_mps.iloc[-30:]).max() < 0.6
    # radial velocity column = d(range)/dt (on a 1 ms grid, through the turn)
    fine = Scene(cfg).truth(np.arange(0.0, 9.9, 1e-3))
    vr = fine.radial_velocity_mps.to_numpy()
    np.testing.assert_allclose(np.diff(fine.range_m) / 1e-3, 0.5 * (vr[1:] + vr[:-1]), atol=2e-3)


def test_occluded_goes_false_true_false_at_the_shadow_edges():
    """The shadow edges come from the car's corners: entering when the torso crosses the ray
    through the near-right corner (3.3, 4.8), leaving through the ray via the far-left corner
    (1.5, 9.3); the pedestrian walks along y = 10.2 from x = 7.9 at 1.25 m/s."""
    cfg = SCENES["straight_car"]
    ped = cfg.pedestrian
    y = ped.start_xy_m[1]
    x_in, x_out = y * 3.3 / 4.8, y * 1.5 / 9.3
    t_in = (ped.start_xy_m[0] - x_in) / ped.speed_mps
    t_out = (ped.start_xy_m[0] - x_out) / ped.speed_mps
    tr = scene_truth(cfg, RADAR)
    t = tr.time_s.to_numpy()
    np.testing.assert_array_equal(tr.occluded.to_numpy(), (t > t_in) & (t < t_out))
    assert 0.5 < t_in < 1.0 and 4.5 < t_out < 5.5  # visible first, ~4.3 s hidden, then out
    hidden = tr.occluded.to_numpy()
    assert np.all(tr.visible_fraction[hidden & (t > t_in + 0.5) & (t < t_out - 0.5)] == 0)
    assert np.all(tr.visible_fraction[t > t_out + 0.5] == 1)
    # without the car, the same walk is never hidden
    free = scene_truth(SCENES["straight_nocar"], RADAR)
    assert not free.occluded.any() and (free.visible_fraction == 1).all()
    np.testing.assert_allclose(free[["x_m", "y_m"]], tr[["x_m", "y_m"]])


def test_scatterer_attenuation_follows_occlusion():
    scene = Scene(SCENES["approach_car"])
    t = np.array([0.3, 3.0, 8.0])                         # visible, hidden, visible
    sc = scene.scatterers_at(t)
    ped = scene.is_pedestrian
    assert sc.attenuation_db.shape == (3, scene.n_scatterers)
    assert np.all(sc.attenuation_db[:, ~ped] == 0)       # the car never hides itself
    assert np.all(sc.attenuation_db[1, ped] == SCENES["approach_car"].occlusion_db)
    assert np.all(sc.attenuation_db[[0, 2]][:, ped] == 0)
    # scalar time gives the same as one row of the vectorised call
    one = scene.scatterers_at(3.0)
    np.testing.assert_allclose(one.position_m, sc.position_m[1])
    np.testing.assert_allclose(one.attenuation_db, sc.attenuation_db[1])


def test_pedestrian_never_walks_through_the_car():
    scene = Scene(SCENES["recede_car"])
    pos, _, _ = scene.pedestrian_parts_at(np.linspace(0, 10, 1001))
    assert not point_in_polygon(pos[..., :2], scene.car_polygon).any()


def test_car_scatterers_visible_faces_5_to_9_5_m_static():
    scene = Scene(SCENES["straight_car"])
    sc = scene.scatterers_at(0.0)
    car = ~scene.is_pedestrian
    r = np.linalg.norm(sc.position_m[car], axis=1)
    assert r.min() > 4.9 and r.max() < 9.5
    assert np.all(sc.velocity_mps[car] == 0)
    xy = sc.position_m[car, :2]
    # only the faces turned towards the radar: the left side (x = 1.5) and the near end (y = 4.8)
    on_left, on_near = np.isclose(xy[:, 0], 1.5), np.isclose(xy[:, 1], 4.8)
    assert np.all(on_left | on_near) and on_left.sum() > 10 and on_near.sum() > 4
    assert 10 * np.log10(sc.rcs_m2[car].sum()) == pytest.approx(15.0)
    # a strong part of the car's RCS sits at ~5 m and at ~8-8.5 m (paper Fig. 6b)
    rcs = sc.rcs_m2[car]
    assert rcs[(r > 4.9) & (r < 6.0)].sum() > 0.3 * rcs.sum()
    assert rcs[(r > 8.0) & (r < 8.8)].sum() > 0.1 * rcs.sum()


def test_pedestrian_rcs_and_micro_doppler():
    scene = Scene(SCENES["approach_nocar"])
    ped = scene.is_pedestrian
    total_dbsm = 10 * np.log10(scene.rcs_m2[ped].sum())
    assert -8 <= total_dbsm <= -1
    # after the turn, over ~3 gait cycles (0.9 Hz), the legs swing +-2 pi f A = +-1.4 m/s about
    # the torso along the walking direction, and their radial velocity spreads accordingly
    t = np.linspace(6.6, 9.9, 331)
    pos, vel, walk = scene.pedestrian_parts_at(t)
    names = [n for n, p in zip(scene.names, ped) if p]
    legs = [names.index("leg_left"), names.index("leg_right")]
    torso, arm = names.index("torso"), names.index("arm_left")
    rel = vel[..., :2] - vel[:, [torso], :2]
    along = (rel * walk.heading[:, None, :]).sum(-1)           # (F, P)
    assert along[:, legs].max() == pytest.approx(1.4, abs=0.05)
    assert along[:, legs].min() == pytest.approx(-1.4, abs=0.05)
    u = pos / np.linalg.norm(pos, axis=-1, keepdims=True)
    vr = (vel * u).sum(-1)
    assert np.ptp(vr[:, legs] - vr[:, [torso]]) > 1.0
    # the left leg and left arm swing in anti-phase
    assert np.corrcoef(along[:, legs[0]], along[:, arm])[0, 1] < -0.99


@pytest.mark.parametrize("name", ["approach_car", "recede_nocar"])
def test_velocities_are_the_derivative_of_positions(name):
    """Every scatterer's velocity (analytic, incl. swing and the turn) matches d(position)/dt."""
    scene = Scene(SCENES[name])
    t = np.linspace(0.05, 9.95, 400)      # covers the turn (t ~ 6.1-6.5 s)
    h = 1e-5
    a, b = scene.scatterers_at(t - h), scene.scatterers_at(t + h)
    numeric = (b.position_m - a.position_m) / (2 * h)
    np.testing.assert_allclose(scene.scatterers_at(t).velocity_mps, numeric, atol=2e-4)


@pytest.mark.parametrize("path,value,fragment", [
    (("pedestrian", "speed_mps"), -1.0, "scene.pedestrian.speed_mps"),
    (("pedestrian", "direction_xy"), [0, 0], "scene.pedestrian.direction_xy"),
    (("car", "length_m"), float("nan"), "scene.car.length_m"),
    (("n_frames",), 0, "scene.n_frames"),
    (("with_car",), "yes", "scene.with_car"),
])
def test_bad_scene_values_name_the_key(path, value, fragment):
    from blindspot.radar.scene import SceneConfig

    m = OmegaConf.to_container(GROUP.shared)
    m.update(n_frames=10, seed=1, with_car=True)
    node = m
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    with pytest.raises(ConfigError, match=fragment.replace(".", r"\.")):
        SceneConfig.from_mapping(m, where="scene")


def test_missing_scenes_and_bright_share_errors():
    with pytest.raises(ConfigError, match="scene.scenes"):
        load_scenes({"shared": {}})
    bad = OmegaConf.to_container(GROUP)
    bad["shared"]["car"]["bright_points"][0]["share"] = 0.9
    with pytest.raises(ConfigError, match="bright_points"):
        load_scenes(bad)


def test_a_null_scene_is_left_out_and_the_others_are_unchanged():
    """What conf/profile/tiny.yaml does: the scenes it sets to null are gone, the rest are
    built exactly as from the full group; nulling every scene is an error naming the key."""
    group = OmegaConf.to_container(GROUP)
    dropped = ["straight_nocar", "recede_car"]
    for name in dropped:
        group["scenes"][name] = None
    kept = load_scenes(group)
    assert list(kept) == [n for n in SCENES if n not in dropped]
    assert all(kept[n] == SCENES[n] for n in kept)
    tiny = OmegaConf.merge(GROUP, OmegaConf.load(REPO_ROOT / "conf/profile/tiny.yaml").scene)
    assert list(load_scenes(tiny)) == ["approach_nocar", "approach_car"]
    group["scenes"] = {n: None for n in SCENES}
    with pytest.raises(ConfigError, match="scene.scenes") as err:
        load_scenes(group)
    assert "not null" in str(err.value)


def test_yaw_rotates_the_car_and_its_visible_faces():
    cfg = SCENES["straight_car"]
    turned = dataclasses.replace(cfg, car=dataclasses.replace(cfg.car, yaw_deg=90.0))
    poly = Scene(turned).car_polygon
    # long axis now along x: 4.5 m wide in x, 1.8 m deep in y, same centre
    assert np.ptp(poly[:, 0]) == pytest.approx(4.5) and np.ptp(poly[:, 1]) == pytest.approx(1.8)
    np.testing.assert_allclose(poly.mean(axis=0), cfg.car.center_xy_m)
