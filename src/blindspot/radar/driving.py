"""Driving scenes: a moving ego car with the radar at its front bumper, cars parked along the
kerb, and one to three pedestrians stepping out between them (Euro NCAP AEB pedestrian
scenarios CPNCO, CPNA-25/-75, CPFA, and non-intruding variants).

Sources (``../shared/scenarios/EURO_NCAP_PEDESTRIAN.md``, tagged there [V]: the Vector
OpenSCENARIO implementation of Euro NCAP AEB/LSS VRU v4.5.1): ego width W = 1.815 m and length
4.358 m; pedestrian start E from the impact point (4.0 m near side, 6.0 m far side), acceleration
distance G (1.0 / 1.5 m), constant speed (1.389 m/s = 5 km/h child and adult near side,
2.222 m/s = 8 km/h far side); impact point H = W p / 100 - W / 2 (p counted from the near-side
edge); pedestrian boxes (adult 0.60 x 0.50 x 1.80 m, reference point 0.36 m behind the box front;
child 0.711 x 0.298 x 1.154 m, reference 0.396 m behind); CPNCO parked cars (small car
4.316 x 1.79 m, large car 4.418 x 1.82 m, centre lines 2.818 m from the ego centre line, small
car front 1.149 m before the walking line, 1 m gap between the cars); the synchronisation: the
pedestrian reference point reaches the impact point exactly when the bumper reaches the box's
near face, so without braking the impact lands on the nominal point.

Frames (all SI; degrees only in ``*_deg`` names)
-------------------------------------------------
* **World frame**: the project's radar convention laid on the road: x to the right (the
  near/kerb side, traffic on the right), y along the ego's direction of travel, origin where the
  ego centre line crosses the pedestrian's walking line. It is the scenario file's frame turned
  by 90 deg: ``x = -y_NCAP``, ``y = x_NCAP``. So the near-side pedestrian starts at x > 0 and
  walks in -x, as in the paper's scene.
* **Vehicle (radar) frame**: the radar at the front-bumper centre, boresight +y along the ego's
  heading, x to its right (the frame of every detection; :mod:`blindspot.radar.scene`).
  The ego drives at constant speed (no braking), straight along x = 0 or, with
  ``yaw_rate_deg_s``, on a circle (:func:`ego_pose`); a static point has the radial velocity
  ``v_r = -v_ego cos(theta)`` driving straight, ``omega l sin(theta) - v cos(theta)`` turning
  (Kellner et al. 2013; l the radar's distance ahead of the rear axle; negative = approaching).

Pedestrian motion
-----------------
Each pedestrian follows a polyline of waypoints (turns are drawn as arcs of
``TURN_RADIUS_M``) with one speed profile along it: at rest until its start time, uniform
acceleration ``speed_mps^2 / (2 accel_distance_m)`` (reaching ``speed_mps`` after
``accel_distance_m`` [V]), constant speed, and for the behaviours that stop, uniform deceleration
at the same rate to rest at the route's end (a route shorter than two acceleration distances
peaks below ``speed_mps``). The
behaviours:

``cross``         the Euro NCAP path: across the ego's path, on to the other side.
``stop_at_kerb``  walks out and stops with the box front at the kerb line (the parked cars'
                  inner side, 1 m beyond the ego's side [V], J).
``along_kerb``    walks out to the kerb line, turns and walks along it (``along_sign`` +1 with
                  the traffic, -1 against it).
``turn_back``     walks out to the kerb line and turns back on a half circle.
``cross_after``   the ``cross`` path, started late enough that it reaches the impact point
                  ``after_gap_s`` after the ego's rear has passed its walking line.

Every pedestrian is timed as the NCAP synchronisation times the crossing one (its reference point
would reach the impact point when the bumper reaches its near face), plus ``delay_s``; the
non-intruding ones then deviate from that path, so they are near misses of the same test.

Truth per frame and pedestrian (:func:`scene_truth`): the ego pose (radar position and heading,
speed), the pedestrian's reference-point position and velocity in the world and vehicle frames,
whether the line of sight from the radar to it crosses a parked car (``occluded``), and the
collision without braking (``collision``, ``collision_time_s``, ``impact_point_pct``,
``ttc_s``): first contact of the ego's footprint with the pedestrian's box on a 1 ms grid,
by the separating-axis test of two rectangles. Vectorised over frames and pedestrians.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pandas as pd

from blindspot.arrays import check_count
from blindspot.radar.occlusion import segments_blocked
# the typed config of the ``scenario`` group (radar/scenario.py)
from blindspot.radar.scenario import (  # noqa: F401 - re-exported
    BEHAVIOURS, INTRUDING, KMH, BodyModel, DrivingScene, EgoConfig, MonteCarloConfig, ParkedCar,
    PedestrianSpec, ScenarioGroup, StaticClutter, load_scenarios,
)

__all__ = [
    "BEHAVIOURS", "INTRUDING", "BodyModel", "EgoConfig", "ParkedCar", "PedestrianSpec",
    "StaticClutter", "DrivingScene", "ScenarioGroup", "MonteCarloConfig",
    "load_scenarios", "draw_scenarios", "scene_truth", "ego_pose", "pedestrian_states",
    "collision_without_braking", "car_polygon", "vehicle_to_world", "world_to_vehicle",
    "TRUTH_COLUMNS", "static_scatterers", "body_parts", "scatterers_in_vehicle_frame",
    "frame_times", "car_polygons", "ego_velocity", "relative_velocity", "describe_scenes",
    "monte_carlo_metrics",
]

TRUTH_COLUMNS = (
    "scene", "frame", "time_s", "ego_x_m", "ego_y_m", "ego_yaw_deg", "ego_speed_mps",
    "pedestrian", "body", "behaviour", "x_m", "y_m", "vx_mps", "vy_mps", "x_vehicle_m",
    "y_vehicle_m", "range_m", "angle_deg", "radial_velocity_mps", "occluded", "collision",
    "collision_time_s", "impact_point_pct", "ttc_s",
)


# ----------------------------------------------------------------------------- Monte Carlo
def draw_scenarios(group: ScenarioGroup, base: DrivingScene, *, seed: int | None = None,
                   per_cell: int | None = None) -> list[DrivingScene]:
    """The seeded Monte-Carlo set around ``base`` (the CPNCO-like scene: its parked cars,
    clutter and timing).

    For every ego speed x impact point x {intruding, non-intruding} cell of
    ``group.monte_carlo``, ``scenes_per_cell`` scenes, each drawing: the body
    (``monte_carlo.bodies``), the behaviour (``cross`` when intruding, else one of
    ``non_intruding``), the gap position (the parked cars moved along the road so that the
    pedestrian steps out ``I ~ U(front_gap_m)`` in front of the first car, [V] I = 1 m, or, with
    probability ``between_cars_share``, out of the middle of the gap between the first two),
    the timing (``delay_s`` ~ U(+-delay_jitter_s)), the pedestrian's speed
    (x U(1 +- speed_jitter)) and 0..``max_bystanders`` non-intruding bystanders stepping out
    further up the road. One ``numpy`` generator seeded by ``monte_carlo.seed``: the same
    config gives the same scenes. Names ``mc_<speed>kmh_<p>pct_<int|non>_<k>``.

    ``seed`` and ``per_cell`` replace ``monte_carlo.seed`` and ``scenes_per_cell`` (another
    draw of the same grid: :func:`blindspot.safety.draws.independent_scenes`); ValueError for
    a seed that is not an integer >= 0 or a per_cell that is not an integer >= 1.
    """
    mc = group.monte_carlo
    seed = mc.seed if seed is None else seed
    per_cell = mc.scenes_per_cell if per_cell is None else per_cell
    check_count(seed, "seed", who="draw_scenarios")
    check_count(per_cell, "per_cell", ge=1, who="draw_scenarios")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 11]))
    lead = base.pedestrians[0]
    cells = [(v, p, intr) for v in mc.speeds_kmh for p in mc.impact_pct for intr in (True, False)]
    n = len(cells) * per_cell
    body = rng.choice(len(mc.bodies), n)
    behav = rng.choice(len(mc.non_intruding), n)
    front_gap = rng.uniform(*mc.front_gap_m, n)
    between = rng.random(n) < mc.between_cars_share
    delay = rng.uniform(-mc.delay_jitter_s, mc.delay_jitter_s, n)
    speed = rng.uniform(1 - mc.speed_jitter, 1 + mc.speed_jitter, n)
    n_by = rng.integers(0, mc.max_bystanders + 1, n)
    by_y = rng.uniform(1.0, 12.0, (n, 2))            # behind the last parked car, m
    by_beh = rng.choice(len(mc.non_intruding), (n, 2))
    by_body = rng.choice(len(mc.bodies), (n, 2))
    seeds = rng.integers(0, 2**62, n)
    cars0 = base.parked_cars
    out = []
    for i, (v, p, intr) in enumerate(c for c in cells for _ in range(per_cell)):
        k = i % per_cell
        bname = mc.bodies[body[i]]
        half_w = group.body(bname).width_m / 2
        if cars0 and between[i] and len(cars0) >= 2:
            centre = (cars0[0].front_y_m - cars0[0].length_m + cars0[1].front_y_m) / 2
            shift = lead.walk_y_m - centre
        elif cars0:
            shift = lead.walk_y_m - half_w - front_gap[i] - cars0[0].front_y_m
        else:
            shift = 0.0
        cars = tuple(replace(c, front_y_m=c.front_y_m + shift) for c in cars0)
        # bystanders step out behind the last parked car (never through a car)
        rear = min([c.front_y_m - c.length_m for c in cars], default=lead.walk_y_m - 2.0)
        main = replace(lead, body=bname, impact_pct=float(p),
                       behaviour="cross" if intr else mc.non_intruding[behav[i]],
                       delay_s=lead.delay_s + float(delay[i]),
                       speed_mps=lead.speed_mps * float(speed[i]), name="p0")
        peds = [main] + [
            replace(lead, body=mc.bodies[by_body[i, j]], behaviour=mc.non_intruding[by_beh[i, j]],
                    walk_y_m=float(rear - by_y[i, j]), impact_pct=50.0, delay_s=float(delay[i]),
                    name=f"p{j + 1}")
            for j in range(int(n_by[i]))]
        name = f"mc_{v:g}kmh_{p:g}pct_{'int' if intr else 'non'}_{k}"
        out.append(replace(base, speed_kmh=float(v), pedestrians=tuple(peds), parked_cars=cars,
                           seed=int(seeds[i]), name=name))
    return out


# ----------------------------------------------------------------------------- kinematics
def frame_times(scene: DrivingScene, frame_period_s: float) -> np.ndarray:
    """(F,) frame start times, s: 0 .. lead_time_s + tail_time_s; the nominal impact (bumper at
    the lead pedestrian's walking line) is at ``lead_time_s``."""
    n = int(math.floor((scene.lead_time_s + scene.tail_time_s) / frame_period_s + 1e-9)) + 1
    return np.arange(n) * frame_period_s


def ego_pose(scene: DrivingScene, group: ScenarioGroup, t: np.ndarray) -> np.ndarray:
    """(F, 3) radar (front-bumper centre) pose (x_m, y_m, yaw_rad) in the world frame at times
    ``t`` (F,). yaw 0 = heading +y, positive = turned counter-clockwise (left).

    Straight (``yaw_rate_deg_s`` 0): along x = 0 at ``speed_kmh``, the bumper reaching the lead
    pedestrian's box near face (y = walk_y - width / 2) at ``lead_time_s`` ([V]
    synchronisation). Turning: the same pose at ``lead_time_s``, and a constant yaw rate omega
    with the rear axle centre (``ego.rear_axle_to_radar_m`` behind the radar) moving at the
    speed along its heading (Ackermann, no side slip: Kellner et al. 2013), i.e. on a circle of
    radius v / omega; the radar is ``l`` ahead of it along the heading."""
    t = np.asarray(t, dtype=float)
    lead = scene.pedestrians[0]
    w = group.body(lead.body).width_m
    y_sync = lead.walk_y_m - w / 2
    v, om, el = scene.speed_mps, math.radians(scene.yaw_rate_deg_s), group.ego.rear_axle_to_radar_m
    tau = t - scene.lead_time_s
    psi = om * tau
    # rear-axle displacement along the circle from its place at lead_time_s (straight: psi = 0)
    small = np.abs(psi) < 1e-9
    psi_s = np.where(small, 1.0, psi)
    along = v * tau * np.where(small, 1.0 - psi**2 / 6, np.sin(psi_s) / psi_s)
    side = v * tau * np.where(small, psi / 2, (1.0 - np.cos(psi_s)) / psi_s)
    heading = np.stack([-np.sin(psi), np.cos(psi)], axis=-1)        # unit heading (world)
    rear = np.stack([-side, y_sync - el + along], axis=-1)
    radar = rear + el * heading
    return np.concatenate([radar, psi[:, None]], axis=-1)


def ego_velocity(scene: DrivingScene, group: ScenarioGroup, t: np.ndarray) -> np.ndarray:
    """(F, 2) world velocity of the radar at times ``t`` (F,), m/s: the rear axle's ``v`` along
    the heading plus ``omega x l`` (the radar ``l`` ahead of the rear axle: ``omega l`` towards
    the left of the heading when turning left). Its components in the radar frame are
    ``(v_x, v_y) = (-omega l, v)`` (Kellner et al. 2013 with the sensor on the centre line)."""
    psi = ego_pose(scene, group, t)[:, 2]
    v, om = scene.speed_mps, math.radians(scene.yaw_rate_deg_s)
    el = group.ego.rear_axle_to_radar_m
    heading = np.stack([-np.sin(psi), np.cos(psi)], axis=-1)
    left = np.stack([-np.cos(psi), -np.sin(psi)], axis=-1)
    return v * heading + om * el * left


def relative_velocity(velocity_world: np.ndarray, scene: DrivingScene, group: ScenarioGroup,
                      t: np.ndarray) -> np.ndarray:
    """World velocities (F, ..., 2) of scatterers at times ``t`` (F,) minus the radar's, in the
    radar's axes (x right, y boresight), m/s: their projection on a line of sight is the radial
    velocity the radar measures (its own rotation does not change ranges)."""
    pose = ego_pose(scene, group, t)
    ev = ego_velocity(scene, group, t)
    extra = (1,) * (np.ndim(velocity_world) - 2)
    dv = np.asarray(velocity_world, float) - ev.reshape(ev.shape[:1] + extra + (2,))
    c = np.cos(pose[:, 2]).reshape((-1,) + extra)
    s_ = np.sin(pose[:, 2]).reshape((-1,) + extra)
    return np.stack([c * dv[..., 0] + s_ * dv[..., 1], -s_ * dv[..., 0] + c * dv[..., 1]], -1)


def _arc(centre: np.ndarray, radius: float, a0: float, a1: float, n: int = 9) -> np.ndarray:
    a = np.linspace(a0, a1, n)
    return centre + radius * np.stack([np.cos(a), np.sin(a)], axis=-1)


TURN_RADIUS_M = 0.4   # radius of the drawn turns (along_kerb, turn_back)
MAX_WAYPOINTS = 24


def _route(p: PedestrianSpec, body: BodyModel, group: ScenarioGroup, scene: DrivingScene
           ) -> tuple[np.ndarray, float, bool]:
    """Waypoints (MAX_WAYPOINTS, 2) (the last repeated), the start time (s) and whether the
    pedestrian stops at the end of its route."""
    ego = group.ego
    s = 1.0 if p.side == "near" else -1.0           # near side: x > 0, walking in -x
    x_imp = ego.width_m / 2 - ego.width_m * p.impact_pct / 100.0   # H, world x = -y_NCAP
    x0 = x_imp + s * p.start_offset_m
    y = p.walk_y_m
    start = np.array([x0, y])
    # time to walk E to the impact point: acceleration over G, then constant speed [V]
    t_walk = 2 * p.accel_distance_m / p.speed_mps + (p.start_offset_m - p.accel_distance_m) / p.speed_mps
    lead_w = group.body(scene.pedestrians[0].body).width_m
    # the bumper reaches this pedestrian's near face (y - w/2) at:
    y0 = scene.pedestrians[0].walk_y_m - lead_w / 2 - scene.speed_mps * scene.lead_time_s
    t_face = (y - body.width_m / 2 - y0) / scene.speed_mps
    t0 = t_face - t_walk + p.delay_s
    if p.behaviour == "cross_after":
        t0 += (ego.length_m + body.width_m) / scene.speed_mps + p.after_gap_s
    stops = p.behaviour == "stop_at_kerb"
    # the kerb line on this pedestrian's side: the parked cars' inner side, or 1 m beyond the
    # ego's side (J) without cars on that side
    inner = [c.center_x_m - s * c.width_m / 2 for c in scene.parked_cars if c.center_x_m * s > 0]
    kerb = (min(inner, key=abs) if inner else s * (ego.width_m / 2 + 1.0))
    x_stop = kerb + s * (body.ref_from_front_m - p.stop_margin_m)
    far = x_imp - s * 30.0                               # walks on across the road
    if p.behaviour in ("cross", "cross_after"):
        pts = [start, np.array([far, y])]
    elif p.behaviour == "stop_at_kerb":
        pts = [start, np.array([x_stop, y])]
    elif p.behaviour == "along_kerb":
        r, d = TURN_RADIUS_M, float(p.along_sign)
        c = np.array([x_stop + s * r, y])
        a0 = math.pi if s > 0 else 0.0                  # at the kerb side of the centre
        a1 = a0 - s * d * math.pi / 2
        arc = _arc(c, r, a0, a1)
        pts = [start, *arc, arc[-1] + np.array([0.0, d * 60.0])]
    else:  # turn_back: a half circle at the kerb line, back the way it came
        r = TURN_RADIUS_M
        c = np.array([x_stop + s * r, y])
        a0 = math.pi if s > 0 else 0.0
        arc = _arc(c, r, a0, a0 + math.pi, 13)
        pts = [start, *arc, arc[-1] + np.array([s * 30.0, 0.0])]
    w = np.asarray(pts, dtype=float)
    w = np.concatenate([w, np.repeat(w[-1:], MAX_WAYPOINTS - len(w), axis=0)])
    return w, t0, stops


def pedestrian_states(scene: DrivingScene, group: ScenarioGroup, t: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reference-point positions (P, F, 2), velocities (P, F, 2) (world frame, m, m/s) and unit
    headings (P, F, 2) (the walking direction, kept while at rest) of every pedestrian at times
    ``t`` (F,). Vectorised over pedestrians and times."""
    pos, vel, heading, _ = _pedestrian_kinematics(scene, group, t)
    return pos, vel, heading


def _pedestrian_kinematics(scene: DrivingScene, group: ScenarioGroup, t: np.ndarray):
    """:func:`pedestrian_states` plus the distance walked (P, F), m."""
    t = np.asarray(t, dtype=float)
    routes = [_route(p, group.body(p.body), group, scene) for p in scene.pedestrians]
    wp = np.stack([r[0] for r in routes])                       # (P, K, 2)
    t0 = np.array([r[1] for r in routes])[:, None]               # (P, 1)
    stops = np.array([r[2] for r in routes])[:, None]
    seg = np.diff(wp, axis=1)                                   # (P, K-1, 2)
    seg_len = np.linalg.norm(seg, axis=-1)
    cum = np.concatenate([np.zeros((len(wp), 1)), np.cumsum(seg_len, axis=1)], axis=1)
    total = cum[:, -1:]                                          # (P, 1)
    v_set = np.array([p.speed_mps for p in scene.pedestrians])[:, None]
    g_set = np.array([p.accel_distance_m for p in scene.pedestrians])[:, None]
    acc = v_set**2 / (2 * g_set)                                # [V]: v over G from rest
    # a route that stops and is shorter than 2 G: accelerate over half, decelerate over half
    g = np.where(stops, np.minimum(g_set, total / 2), g_set)
    v = np.sqrt(2 * acc * g)                                    # = speed_mps unless cut short
    ta = v / acc                                                # acceleration time
    tau = np.maximum(t[None, :] - t0, 0.0)                      # (P, F) time since start
    s_acc = 0.5 * acc * tau**2
    s_cruise = g + v * (tau - ta)
    s = np.where(tau < ta, s_acc, s_cruise)
    sp = np.where(tau < ta, acc * tau, v)
    # stopping: uniform deceleration over g to rest at the end of the route
    t_dec = ta + (total - 2 * g) / np.maximum(v, 1e-12)         # start of deceleration
    td = tau - t_dec
    s_dec = total - g + v * td - 0.5 * acc * td**2
    decel = stops & (td > 0)
    s = np.where(decel, np.where(td < ta, s_dec, total), s)
    sp = np.where(decel, np.where(td < ta, v - acc * td, 0.0), sp)
    s = np.minimum(s, total)
    sp = np.where(s >= total, 0.0, sp)
    # position along the polyline
    idx = np.clip((cum[:, None, :] <= s[..., None]).sum(-1) - 1, 0, seg.shape[1] - 1)  # (P, F)
    pi = np.arange(len(wp))[:, None]
    lseg = seg_len[pi, idx]
    frac = np.divide(s - cum[pi, idx], lseg, out=np.zeros_like(s), where=lseg > 0)
    pos = wp[pi, idx] + frac[..., None] * seg[pi, idx]
    # heading: the current segment's direction (the last non-empty one at the route's end)
    unit = np.divide(seg, seg_len[..., None], out=np.zeros_like(seg), where=seg_len[..., None] > 0)
    last_nonempty = np.maximum.accumulate(np.where(seg_len > 0, np.arange(seg.shape[1]), 0), axis=1)
    heading = unit[pi, last_nonempty[pi, idx]]
    return pos, sp[..., None] * heading, heading, s


def car_polygon(car: ParkedCar) -> np.ndarray:
    """(4, 2) footprint corners of a parked car (world frame), counter-clockwise."""
    x0, x1 = car.center_x_m - car.width_m / 2, car.center_x_m + car.width_m / 2
    y0, y1 = car.front_y_m - car.length_m, car.front_y_m
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])


def car_polygons(scene: DrivingScene) -> np.ndarray:
    """(C, 4, 2) footprints of the parked cars (C may be 0)."""
    return (np.stack([car_polygon(c) for c in scene.parked_cars]) if scene.parked_cars
            else np.zeros((0, 4, 2)))


def world_to_vehicle(xy: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """World (..., 2) points -> the vehicle frame of ``pose`` (..., 3) = (x, y, yaw_rad) (radar
    at the origin, boresight +y). Rotation by -yaw about the radar."""
    d = np.asarray(xy, float) - pose[..., :2]
    c, s = np.cos(pose[..., 2]), np.sin(pose[..., 2])
    return np.stack([c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]], axis=-1)


def vehicle_to_world(xy: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """Vehicle-frame (..., 2) points (e.g. detections ``x = R sin theta, y = R cos theta``) ->
    world frame, for the ego pose (..., 3) = (x, y, yaw_rad); the inverse of
    :func:`world_to_vehicle`. yaw positive = turned counter-clockwise."""
    p = np.asarray(xy, float)
    c, s = np.cos(pose[..., 2]), np.sin(pose[..., 2])
    return np.stack([c * p[..., 0] - s * p[..., 1], s * p[..., 0] + c * p[..., 1]], axis=-1) + pose[..., :2]


# ----------------------------------------------------------------------------- collision
def _box_corners(ref: np.ndarray, heading: np.ndarray, body_len: np.ndarray, body_w: np.ndarray,
                 ref_front: np.ndarray) -> np.ndarray:
    """(..., 4, 2) corners of pedestrian boxes: reference point ``ref`` (..., 2) lies
    ``ref_front`` behind the box front along ``heading``; length along it, width across."""
    n = np.stack([-heading[..., 1], heading[..., 0]], axis=-1)
    front = ref + ref_front[..., None] * heading
    back = front - body_len[..., None] * heading
    hw = (body_w / 2)[..., None] * n
    return np.stack([front + hw, front - hw, back - hw, back + hw], axis=-2)


def _overlap_rect_box(ymin: np.ndarray, ymax: np.ndarray, half_w: float, corners: np.ndarray
                      ) -> np.ndarray:
    """Separating-axis test: the axis-aligned ego rectangle x in [-half_w, half_w], y in
    [ymin, ymax] (...) against convex quadrilaterals ``corners`` (..., 4, 2) -> bool (...)."""
    cx, cy = corners[..., 0], corners[..., 1]
    sep = (cx.min(-1) > half_w) | (cx.max(-1) < -half_w) | (cy.min(-1) > ymax) | (cy.max(-1) < ymin)
    # the box's own two axes
    e1 = corners[..., 1, :] - corners[..., 0, :]
    e2 = corners[..., 3, :] - corners[..., 0, :]
    rect = np.stack([np.stack([-half_w + 0 * ymin, ymin], -1), np.stack([half_w + 0 * ymin, ymin], -1),
                     np.stack([half_w + 0 * ymin, ymax], -1), np.stack([-half_w + 0 * ymin, ymax], -1)],
                    axis=-2)                                   # (..., 4, 2)
    for e in (e1, e2):
        a = e[..., None, :]
        pb = (corners * a).sum(-1)
        pr = (rect * a).sum(-1)
        sep |= (pb.min(-1) > pr.max(-1)) | (pb.max(-1) < pr.min(-1))
    return ~sep


def collision_without_braking(scene: DrivingScene, group: ScenarioGroup, *, dt_s: float = 1e-3
                              ) -> pd.DataFrame:
    """Whether and when each pedestrian would be hit if nobody brakes.

    The ego footprint (width x length behind the bumper) and each pedestrian's box [V] are
    stepped on a ``dt_s`` grid over the scene; the first time they overlap (separating-axis
    test) is the collision. The impact point is counted as Euro NCAP counts it [V]:
    ``p = 100 (W / 2 - x_ref) / W`` from the ego's near-side (right) edge, ``x_ref`` the
    pedestrian's reference point at contact (so 50 = the centre, and outside 0..100 a contact
    with the ego's side).

    Returns one row per pedestrian: pedestrian, collision (bool), collision_time_s (NaN without),
    impact_point_pct (NaN without).
    """
    t = np.arange(0.0, scene.lead_time_s + scene.tail_time_s + dt_s / 2, dt_s)
    pose = ego_pose(scene, group, t)
    pos, _, heading = pedestrian_states(scene, group, t)
    bodies = [group.body(p.body) for p in scene.pedestrians]
    bl = np.array([b.length_m for b in bodies])[:, None]
    bw = np.array([b.width_m for b in bodies])[:, None]
    rf = np.array([b.ref_from_front_m for b in bodies])[:, None]
    corners = _box_corners(pos, heading, np.broadcast_to(bl, pos.shape[:2]),
                           np.broadcast_to(bw, pos.shape[:2]), np.broadcast_to(rf, pos.shape[:2]))
    # in the ego's frame (radar at the origin, heading +y) the footprint is axis-aligned
    corners = world_to_vehicle(corners, pose[None, :, None, :])
    ref = world_to_vehicle(pos, pose[None])
    zero = np.zeros(pos.shape[:2])
    hit = _overlap_rect_box(zero - group.ego.length_m, zero, group.ego.width_m / 2, corners)
    anyhit = hit.any(axis=1)
    first = np.argmax(hit, axis=1)
    w = group.ego.width_m
    x_ref = ref[np.arange(len(pos)), first, 0]
    return pd.DataFrame({
        "pedestrian": [p.name for p in scene.pedestrians],
        "collision": anyhit,
        "collision_time_s": np.where(anyhit, t[first], np.nan),
        "impact_point_pct": np.where(anyhit, 100.0 * (w / 2 - x_ref) / w, np.nan),
    })


# ----------------------------------------------------------------------------- truth
def scene_truth(scene: DrivingScene, group: ScenarioGroup, frame_period_s: float) -> pd.DataFrame:
    """Per frame and pedestrian truth of a driving scene, columns :data:`TRUTH_COLUMNS`:

    scene, frame, time_s; the ego pose (``ego_x_m``, ``ego_y_m``: the radar at the bumper
    centre, world frame; ``ego_yaw_deg``; ``ego_speed_mps``); pedestrian (name), body,
    behaviour; the reference point in the world (``x_m``, ``y_m``, ``vx_mps``, ``vy_mps``) and
    vehicle frame (``x_vehicle_m``, ``y_vehicle_m``, ``range_m``, ``angle_deg``, and
    ``radial_velocity_mps`` relative to the moving radar: negative = approaching);
    ``occluded``: the radar's line of sight to the reference point crosses a parked car;
    ``collision``, ``collision_time_s``, ``impact_point_pct`` (per pedestrian, see
    :func:`collision_without_braking`) and ``ttc_s`` = collision time - time (NaN without a
    collision or after it). Rows ordered by frame, then pedestrian.
    """
    t = frame_times(scene, frame_period_s)
    pose = ego_pose(scene, group, t)                            # (F, 3)
    pos, vel, _ = pedestrian_states(scene, group, t)            # (P, F, 2)
    rel = world_to_vehicle(pos, pose[None])                     # (P, F, 2)
    rel_v = relative_velocity(np.swapaxes(vel, 0, 1), scene, group, t).swapaxes(0, 1)
    rng = np.linalg.norm(rel, axis=-1)
    vr = np.einsum("pfd,pfd->pf", rel, rel_v) / np.maximum(rng, 1e-9)
    polys = car_polygons(scene)
    occluded = segments_blocked(pos, pose[None, :, :2], polys)
    col = collision_without_braking(scene, group)
    n_p, n_f = pos.shape[:2]
    ct = col["collision_time_s"].to_numpy()[:, None]
    ttc = np.where(t[None] < ct, ct - t[None], np.nan)
    rows = lambda a: np.asarray(a).T.reshape(-1)  # (P, F) -> frame-major (F * P,)
    peds = scene.pedestrians
    return pd.DataFrame({
        "scene": scene.name,
        "frame": np.repeat(np.arange(n_f), n_p),
        "time_s": np.repeat(t, n_p),
        "ego_x_m": np.repeat(pose[:, 0], n_p), "ego_y_m": np.repeat(pose[:, 1], n_p),
        "ego_yaw_deg": np.repeat(np.degrees(pose[:, 2]), n_p),
        "ego_speed_mps": scene.speed_mps,
        "pedestrian": np.tile([p.name for p in peds], n_f),
        "body": np.tile([p.body for p in peds], n_f),
        "behaviour": np.tile([p.behaviour for p in peds], n_f),
        "x_m": rows(pos[..., 0]), "y_m": rows(pos[..., 1]),
        "vx_mps": rows(vel[..., 0]), "vy_mps": rows(vel[..., 1]),
        "x_vehicle_m": rows(rel[..., 0]), "y_vehicle_m": rows(rel[..., 1]),
        "range_m": rows(rng), "angle_deg": rows(np.degrees(np.arctan2(rel[..., 0], rel[..., 1]))),
        "radial_velocity_mps": rows(vr),
        "occluded": rows(occluded),
        "collision": np.tile(col["collision"].to_numpy(), n_f),
        "collision_time_s": np.tile(col["collision_time_s"].to_numpy(), n_f),
        "impact_point_pct": np.tile(col["impact_point_pct"].to_numpy(), n_f),
        "ttc_s": rows(ttc),
    }, columns=list(TRUTH_COLUMNS))


# ----------------------------------------------------------------------------- scatterers
FIELD_OF_VIEW_DEG = 75.0   # scatterers outside +-75 deg of boresight are not simulated (the
                           # MMWCAS patch antennas' beam; the isotropic model would fold them)


def static_scatterers(scene: DrivingScene, group: ScenarioGroup) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The static world in the world frame: points every ``car_face_spacing_m`` along every
    face of every parked car (the car's RCS shared equally) and the clutter lines.

    Returns xyz (K, 3) (z above the radar: height - radar height), rcs (K,) m^2, and the index
    (K,) of the car each point belongs to (-1 for clutter), for self-occlusion."""
    xy, rcs, owner, z = [], [], [], []
    for ci, car in enumerate(scene.parked_cars):
        poly = car_polygon(car)
        q0, q1 = poly, np.roll(poly, -1, axis=0)
        lengths = np.linalg.norm(q1 - q0, axis=1)
        counts = np.maximum(1, np.ceil(lengths / group.car_face_spacing_m).astype(int))
        edge = np.repeat(np.arange(4), counts)
        frac = (np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts) + 0.5) / counts[edge]
        pts = q0[edge] + frac[:, None] * (q1 - q0)[edge]
        xy.append(pts)
        rcs.append(np.full(len(pts), 10 ** (car.rcs_dbsm / 10) / len(pts)))
        owner.append(np.full(len(pts), ci))
        z.append(np.full(len(pts), 0.5 - group.ego.radar_height_m))   # bumper / wheel level
    for cl in scene.clutter:
        ys = np.arange(cl.y_from_m, cl.y_to_m + 1e-9, cl.spacing_m)
        xy.append(np.stack([np.full_like(ys, cl.x_m), ys], axis=1))
        rcs.append(np.full(len(ys), 10 ** (cl.rcs_dbsm / 10)))
        owner.append(np.full(len(ys), -1))
        z.append(np.full(len(ys), cl.height_m - group.ego.radar_height_m))
    if not xy:
        return np.zeros((0, 3)), np.zeros(0), np.zeros(0, dtype=int)
    xy = np.concatenate(xy)
    return (np.concatenate([xy, np.concatenate(z)[:, None]], axis=1), np.concatenate(rcs),
            np.concatenate(owner))


def body_parts(scene: DrivingScene, group: ScenarioGroup, t: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Body-part scatterers of every pedestrian at times ``t`` (F,), world frame.

    Each part sits ``lateral_m`` to the walker's left and swings ``swing_m sin(gait + phase)``
    along the heading, gait = 2 pi distance / stride (the scene model of
    :mod:`blindspot.radar.scene`, on the driving routes). Returns positions (F, Q, 3) (z above
    the radar), velocities (F, Q, 3), rcs (Q,) m^2, pedestrian index (Q,)."""
    t = np.asarray(t, dtype=float)
    pos, vel, heading, dist = _pedestrian_kinematics(scene, group, t)   # (P, F, ...)
    xyz, v3, rcs, who = [], [], [], []
    for i, p in enumerate(scene.pedestrians):
        b = group.body(p.body)
        u = heading[i][:, None, :]                                     # (F, 1, 2)
        n = np.stack([-u[..., 1], u[..., 0]], axis=-1)
        lat = np.array([q.lateral_m for q in b.parts])[None, :, None]
        amp = np.array([q.swing_m for q in b.parts])[None, :]
        ph = np.radians([q.phase_deg for q in b.parts])[None, :]
        arg = 2 * np.pi * dist[i][:, None] / b.stride_length_m + ph     # (F, parts)
        speed = np.linalg.norm(vel[i], axis=-1)[:, None]
        d = (amp * np.sin(arg))[..., None]
        d_dot = (amp * np.cos(arg) * 2 * np.pi * speed / b.stride_length_m)[..., None]
        pxy = pos[i][:, None, :] + d * u + lat * n
        vxy = vel[i][:, None, :] + d_dot * u
        z = np.broadcast_to(np.array([q.height_m for q in b.parts]) - group.ego.radar_height_m,
                            pxy.shape[:2])[..., None]
        xyz.append(np.concatenate([pxy, z], axis=-1))
        v3.append(np.concatenate([vxy, np.zeros_like(z)], axis=-1))
        rcs.append(b.rcs_m2)
        who.append(np.full(len(b.parts), i))
    return (np.concatenate(xyz, axis=1), np.concatenate(v3, axis=1), np.concatenate(rcs),
            np.concatenate(who))


def scatterers_in_vehicle_frame(scene: DrivingScene, group: ScenarioGroup, t: float
                                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every scatterer the radar sees at time ``t``, relative to the moving radar.

    Returns position (K, 3) and velocity (K, 3) in the vehicle frame (static points move at
    -v_ego), rcs (K,) m^2, attenuation (K,) dB (``occlusion_db`` where the line of sight crosses
    a parked car, including a car's own far faces) and a label (K,) int: -1 static world, p >= 0
    body part of pedestrian p. Scatterers outside the +-75 deg field of view or behind the
    radar are left out."""
    pose = ego_pose(scene, group, np.array([t]))[0]
    sxyz, srcs, _ = static_scatterers(scene, group)
    pxyz, pv, prcs, who = body_parts(scene, group, np.array([t]))
    xyz = np.concatenate([sxyz, pxyz[0]])
    vw = np.concatenate([np.zeros_like(sxyz), pv[0]])
    rcs = np.concatenate([srcs, prcs])
    label = np.concatenate([np.full(len(srcs), -1), who])
    rel_xy = world_to_vehicle(xyz[:, :2], pose)
    rel_v = relative_velocity(vw[None, :, :2], scene, group, np.array([t]))[0]  # minus the ego's
    az = np.degrees(np.arctan2(rel_xy[:, 0], rel_xy[:, 1]))
    keep = (rel_xy[:, 1] > 0.2) & (np.abs(az) <= FIELD_OF_VIEW_DEG)
    # line of sight, stopped 1 mm short of each point, against every parked car
    r = np.linalg.norm(rel_xy, axis=1, keepdims=True)
    short = xyz[:, :2] - (xyz[:, :2] - pose[:2]) * (1e-3 / np.maximum(r, 1e-9))
    hidden = segments_blocked(short, pose[None, :2], car_polygons(scene))
    att = np.where(hidden, group.occlusion_db, 0.0)
    pos = np.concatenate([rel_xy, xyz[:, 2:]], axis=1)
    vel = np.concatenate([rel_v, np.zeros((len(xyz), 1))], axis=1)
    return pos[keep], vel[keep], rcs[keep], att[keep], label[keep]


def _finite(x: float) -> float | None:
    """A float, or None (JSON null) for NaN: no collision."""
    return float(x) if np.isfinite(x) else None


def describe_scenes(sets: list[tuple[str, DrivingScene]], truth: pd.DataFrame) -> dict:
    """``scenes.json`` of the driving scenes: per scene (``sets``: (set name, scene) pairs; the
    ``truth`` of :func:`scene_truth` for all of them) its set, speed, seed, parked-car polygons
    and, per pedestrian, its body, behaviour, side, impact point and collision without braking."""
    first = truth.drop_duplicates(["scene", "pedestrian"]).set_index(["scene", "pedestrian"])

    def ped(s: DrivingScene, p: PedestrianSpec) -> dict:
        row = first.loc[(s.name, p.name)]
        return {"name": p.name, "body": p.body, "behaviour": p.behaviour, "side": p.side,
                "impact_pct": p.impact_pct, "collision": bool(row["collision"]),
                "collision_time_s": _finite(row["collision_time_s"]),
                "impact_point_pct": _finite(row["impact_point_pct"])}

    return {s.name: {"set": k, "speed_kmh": s.speed_kmh, "seed": s.seed,
                     "car_polygons_xy_m": car_polygons(s).tolist(),
                     "pedestrians": [ped(s, p) for p in s.pedestrians]}
            for k, s in sets}


def monte_carlo_metrics(truth: pd.DataFrame) -> dict:
    """The Monte-Carlo set's lead pedestrians (``p0``) without braking: collision rates of the
    intruding (``cross``) and the other scenes, the fraction of frames hidden, the spread of the
    impact point (%)."""
    lead = truth[(truth.set == "monte_carlo") & (truth.pedestrian == "p0")]
    per = lead.drop_duplicates("scene")
    intr = per.behaviour == "cross"
    return {"monte_carlo.collision_rate_intruding": float(per.collision[intr].mean()),
            "monte_carlo.collision_rate_non_intruding": float(per.collision[~intr].mean()),
            "monte_carlo.lead_hidden_fraction": float(lead.occluded.mean()),
            "monte_carlo.impact_point_pct_sd": float(np.nanstd(per.impact_point_pct[intr]))}
