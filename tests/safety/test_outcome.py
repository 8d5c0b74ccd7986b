"""Scene outcomes of a committed AEB against the scenario geometry: without braking the outcome
model finds the collision the scene generator found (an independent 1 ms separating-axis test),
a pedestrian who stops at the kerb is never hit, and a late brake hits a pedestrian standing in
the path at the speed kinematics gives."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from omegaconf import OmegaConf

from blindspot.radar.driving import load_scenarios, scene_truth
from blindspot.safety.braking import BrakingModel
from blindspot.safety.outcome import (NEVER_S, OutcomeError, braked_impacts, pedestrian_boxes,
                                      scene_arrays)
from blindspot.safety.risk import EgoShape

CONF = Path(__file__).resolve().parents[2] / "conf" / "scenario" / "euro_ncap.yaml"
BRAKE = BrakingModel(0.2, 30.0, 9.8)


@pytest.fixture(scope="module")
def scenario():
    group, named = load_scenarios(OmegaConf.load(CONF))
    bodies = {b.name: (b.length_m, b.width_m, b.ref_from_front_m) for b in group.bodies}
    return group, named, bodies, EgoShape(group.ego.width_m, group.ego.length_m)


def _truth(group, scenes):
    return pd.concat([scene_truth(s, group, 0.1) for s in scenes], ignore_index=True)


def test_no_braking_reproduces_the_scene_generators_collision(scenario):
    group, named, bodies, ego = scenario
    scenes = [replace(named[n], speed_kmh=v, name=f"{n}_{v:g}")
              for n in ("cpnco", "cpna25", "cpna75", "cpfa") for v in (20.0, 60.0)]
    truth = _truth(group, scenes)
    sa = scene_arrays(truth, bodies)
    t, lo, hi = pedestrian_boxes(sa, 0.002, 3.0)
    it, iv = braked_impacts(sa, t, lo, hi, np.full((len(scenes), 1), NEVER_S), BRAKE, ego)
    expected = truth.groupby("scene").collision_time_s.min().reindex(sa.scenes).to_numpy()
    assert np.isfinite(expected).all()
    assert np.abs(it[:, 0] - expected).max() <= 0.003
    assert iv[:, 0] == pytest.approx(sa.speed_mps)


def test_pedestrian_stopping_at_the_kerb_is_never_hit(scenario):
    group, named, bodies, ego = scenario
    scenes = [replace(named["stop_at_kerb"], speed_kmh=v, name=f"kerb_{v:g}")
              for v in (10.0, 30.0, 60.0)]
    sa = scene_arrays(_truth(group, scenes), bodies)
    t, lo, hi = pedestrian_boxes(sa, 0.005, 4.0)
    trig = np.concatenate([np.broadcast_to(sa.time_s, (3, len(sa.time_s))),
                           np.full((3, 1), NEVER_S)], axis=1)
    it, _ = braked_impacts(sa, t, lo, hi, trig, BRAKE, ego)
    assert np.isnan(it).all()


def test_late_braking_hits_a_standing_pedestrian_at_the_kinematic_speed(scenario):
    group, named, bodies, ego = scenario
    v0, D = 13.89, 12.0                      # 50 km/h, bumper 12 m from the box's near face
    frames = np.arange(31)
    ped_y = D + 0.5 / 2 - 0.36 + 0.60 / 2    # adult box (heading +x): near face at y = D
    truth = pd.DataFrame({
        "scene": "stand", "frame": frames, "time_s": frames * 0.1, "ego_x_m": 0.0,
        "ego_y_m": v0 * frames * 0.1, "ego_yaw_deg": 0.0, "ego_speed_mps": v0,
        "pedestrian": "p0", "body": "adult", "x_m": 0.0, "y_m": ped_y, "vx_mps": 0.0,
        "vy_mps": 0.0})
    # heading of a pedestrian that never moves: +y; its box then spans y - 0.24 .. y + 0.36
    near_face = ped_y - (0.60 - 0.36)
    sa = scene_arrays(truth, bodies)
    t, lo, hi = pedestrian_boxes(sa, 1e-4, 1.0)
    _, iv = braked_impacts(sa, t, lo, hi, np.zeros((1, 1)), BRAKE, ego)
    a, j, T = 9.8, 30.0, 0.2
    tr = a / j
    rest = near_face - v0 * T - (v0 * tr - j * tr**3 / 6)
    v1 = v0 - a * tr / 2
    assert BRAKE.stopping_distance(v0) > near_face           # too late to stop
    assert iv[0, 0] == pytest.approx(np.sqrt(v1**2 - 2 * a * rest), abs=0.01)


def test_missing_body_is_named(scenario):
    group, named, bodies, _ = scenario
    truth = _truth(group, [named["cpnco"]])
    with pytest.raises(OutcomeError, match="child"):
        scene_arrays(truth, {"adult": bodies["adult"]})


def test_a_pedestrian_walking_into_the_flank_is_not_a_front_contact(scenario):
    """Issue 40: a crossing pedestrian hit by the bumper is a front contact; one who walks into
    the side of a car that has already passed its walking line is a flank contact."""
    group, named, bodies, ego = scenario
    v0 = 5.0
    frames = np.arange(41)

    def walker(name, x0, y):                 # crossing toward the ego's path (-x) at 1.4 m/s
        return pd.DataFrame({
            "scene": name, "frame": frames, "time_s": frames * 0.1, "ego_x_m": 0.0,
            "ego_y_m": v0 * frames * 0.1, "ego_yaw_deg": 0.0, "ego_speed_mps": v0,
            "pedestrian": "p0", "body": "adult", "x_m": x0 - 1.4 * frames * 0.1, "y_m": y,
            "vx_mps": -1.4, "vy_mps": 0.0})
    # ahead: the bumper reaches its line (y = 10 m at t = 2 s) as it enters the path
    # flank: its line is at y = 7.5 m, the bumper passes it at 1.5 s, it reaches the side at 2 s
    truth = pd.concat([walker("front", 0.9 + 2.8, 10.0), walker("flank", 0.9 + 0.3 + 2.8, 7.5)])
    sa = scene_arrays(truth, bodies)
    t, lo, hi = pedestrian_boxes(sa, 0.002, 1.0)
    it, iv, front = braked_impacts(sa, t, lo, hi, np.full((2, 1), NEVER_S), BRAKE, ego,
                                   with_front=True)
    assert np.isfinite(it).all()                          # both touch the car
    assert front[list(sa.scenes).index("front"), 0]
    assert not front[list(sa.scenes).index("flank"), 0]
