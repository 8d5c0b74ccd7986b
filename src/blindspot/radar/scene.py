"""The paper's Fig. 5 scene: a parked car and a pedestrian who steps out from behind it.

Geometry (all in the ground plane, m; radar at the origin, boresight +y, x to the right)
----------------------------------------------------------------------------------------
* **Car**: a 4.5 m x 1.8 m box parked with its long axis along y at x = 1.5..3.3, y = 4.8..9.3
  (the kerb-side lane to the radar's right). The radar sees its near end (y = 4.8, range
  5.0-5.9 m) and its left side (x = 1.5, range 5.0-9.4 m). Point scatterers are painted on every
  face the radar can see (found from the geometry, so any placement works) plus a few bright
  points (the near bumper corner and the two left wheels, at ranges 5.0, 5.9 and 8.5 m), so the
  strong zero-Doppler returns fall around 5-8 m as in the paper's Fig. 6b. Total visible RCS
  ``car.rcs_dbsm`` (15 dBsm by default).
* **Pedestrian**: starts at (7.9, 10.2), 0.9 m beyond the car's far end on the kerb side, and walks
  in -x at 1.0-1.5 m/s. The car's shadow seen from the radar spans azimuths 9.2..34.5 deg, which
  on the line y = 10.2 is x = 1.64..7.01: the pedestrian is visible for the first ~0.7 s (so the
  hidden stretch has points on both sides of it, which the paper's Fig. 8 interpolation needs),
  hidden for ~4.3 s, steps out past the car's far-left corner, walks on to x ~ 0.3 and then
  turns by ``turn_deg`` on a 0.6 m radius arc: +45 = towards the radar (range decreasing,
  approaching), -45 = away from it (receding), 0 = straight on.
  The turn is a counter-clockwise rotation (x right, y forward) of the walking direction.
* **Body**: torso, head, two arms and two legs (total about -3 dBsm). Arms and legs swing along
  the walking direction at the stride frequency speed / stride_length (arms in anti-phase with
  the leg on the same side), which gives the micro-Doppler spread of a walking person.
* **Occlusion**: a pedestrian scatterer whose line of sight from the radar crosses the car's
  footprint is attenuated by ``occlusion_db`` (50 dB in ``conf/scene/paper.yaml``: after the
  2-D FFT and the 192-channel power sum a hidden pedestrian stays within the noise, so almost no
  points appear while hidden, as in Fig. 7). Diffraction around the car's edges and propagation
  under the car are not modelled (a hard shadow).

Heights are used for the slant range and the elevation phase only; occlusion is 2-D (the car is
taken to be taller than the line of sight). Times are frame start times, ``i * frame_period_s``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import pandas as pd

from blindspot.radar.config import RadarConfig
from blindspot.typed_config import ConfigError, TypedConfig, setting
from blindspot.radar.occlusion import segment_crosses_polygon

TRUTH_COLUMNS = (
    "frame", "time_s", "x_m", "y_m", "vx_mps", "vy_mps", "range_m", "radial_velocity_mps",
    "angle_deg", "occluded", "visible_fraction",
)


class Scatterers(NamedTuple):
    """Point scatterers at one time (shapes without F) or at F times (with a leading F axis).

    position_m : (K, 3) or (F, K, 3) x, y, z relative to the radar phase centre, m.
    velocity_mps : same shape as ``position_m``, m/s.
    rcs_m2 : (K,) radar cross-section, m^2.
    attenuation_db : (K,) or (F, K) extra loss of the received power (occlusion), dB >= 0.
    """

    position_m: np.ndarray
    velocity_mps: np.ndarray
    rcs_m2: np.ndarray
    attenuation_db: np.ndarray


# ----------------------------------------------------------------------------- configuration
@dataclass(frozen=True)
class BodyPart(TypedConfig):
    """One pedestrian scatterer: RCS, height, lateral offset (+ = walker's left), swing."""

    name: str = setting()
    rcs_dbsm: float = setting(ge=-60.0, le=20.0)
    height_m: float = setting(ge=0.0, le=3.0)
    lateral_m: float = setting(0.0, ge=-2.0, le=2.0)
    swing_m: float = setting(0.0, ge=0.0, le=2.0)
    phase_deg: float = setting(0.0, ge=-360.0, le=360.0)


@dataclass(frozen=True)
class PedestrianConfig(TypedConfig):
    """The walker: start, walking direction, speed, one turn, stride and body parts (given in
    the config as a mapping ``{part name: {rcs_dbsm, height_m, ...}}``)."""

    start_xy_m: tuple[float, float] = setting(doc="two finite numbers [x, y]")
    direction_xy: tuple[float, float] = setting(nonzero=True, doc="two finite numbers [x, y] not both 0")
    speed_mps: float = setting(ge=0.0, le=10.0)
    turn_after_m: float = setting(ge=0.0, le=1e4)
    turn_deg: float = setting(ge=-180.0, le=180.0)
    stride_length_m: float = setting(ge=0.1, le=5.0)
    parts: tuple[BodyPart, ...] = setting(min_items=1, doc="at least one body part")
    turn_radius_m: float = setting(0.0, ge=0.0, le=100.0)


@dataclass(frozen=True)
class BrightPoint(TypedConfig):
    """A bright scatterer of the car, car-local (across +x, along +y at yaw 0) from the centre,
    with its share of the car's RCS."""

    across_m: float = setting(ge=-50.0, le=50.0)
    along_m: float = setting(ge=-50.0, le=50.0)
    share: float = setting(ge=0.0, le=1.0)


@dataclass(frozen=True)
class CarConfig(TypedConfig):
    """The parked car: footprint, scatterer height, RCS, face scatterer spacing, bright points."""

    center_xy_m: tuple[float, float] = setting(doc="two finite numbers [x, y]")
    length_m: float = setting(ge=0.5, le=30.0)
    width_m: float = setting(ge=0.5, le=10.0)
    height_m: float = setting(ge=0.0, le=5.0)
    rcs_dbsm: float = setting(ge=-30.0, le=60.0)
    face_spacing_m: float = setting(ge=0.05, le=10.0)
    yaw_deg: float = setting(0.0, ge=-360.0, le=360.0)
    bright_points: tuple[BrightPoint, ...] = setting(())

    def validate(self) -> None:
        shares = [b.share for b in self.bright_points]
        if sum(shares) > 1.0 + 1e-9:
            raise ConfigError("bright_points", shares, "shares summing to at most 1")


@dataclass(frozen=True)
class SceneConfig(TypedConfig):
    """One scene of the experiment (see the module docstring for the geometry)."""

    GROUP = "scene"

    n_frames: int = setting(ge=1, le=1_000_000)
    seed: int = setting(ge=0, le=2**63 - 1)
    with_car: bool = setting()
    occlusion_db: float = setting(ge=0.0, le=300.0)
    car: CarConfig = setting()
    pedestrian: PedestrianConfig = setting()
    radar_height_m: float = setting(0.0, ge=-10.0, le=10.0)
    start_time_s: float = setting(0.0, ge=-1e6, le=1e6)
    name: str = setting("scene")


@dataclass(frozen=True)
class SceneGroup(TypedConfig):
    """The Hydra group ``scene`` (``conf/scene/paper.yaml``): ``shared`` settings and the
    ``scenes``, each a partial scene deep-merged over ``shared``; a scene set to null is left
    out (:func:`_merged_scenes`)."""

    GROUP = "scene"

    scenes: dict = setting(doc="a mapping {scene name: settings over shared, or null to leave "
                               "it out}, at least one scene")
    shared: dict = setting(default_factory=dict)

    def validate(self) -> None:
        if not _present(self.scenes):
            raise ConfigError("scenes", self.scenes, "at least one scene that is not null")


def load_scenes(group: Any, where: str = "scene") -> dict[str, SceneConfig]:
    """The scenes of a scene group file (``conf/scene/paper.yaml``): each entry of ``scenes``
    deep-merged over ``shared``. Returns {name: SceneConfig} in file order.

    Raises:
        ConfigError: a missing or invalid key, named ``scene.scenes.<name>.<key>``.
    """
    g = SceneGroup.from_mapping(group, where)
    out = {name: SceneConfig.from_mapping(merged, where=key)
           for name, merged, key in _merged_scenes(g.scenes, g.shared, where)}
    if g.shared and out:
        # a bad value in ``shared`` is an error even where every scene overrides it (it would
        # otherwise sit unchecked until a new scene uses it): check the shared settings laid
        # over the first scene, errors named ``scene.shared.<key>``
        first = next(iter(out.values()))
        SceneConfig.from_mapping(_deep_merge(_as_mapping(first), g.shared), where=f"{where}.shared")
    return out


def car_twin(name: str, all_scenes: Mapping[str, Any]) -> str | None:
    """The scene with the same walk and no car (``approach_car`` -> ``approach_nocar``)."""
    if not name.endswith("_car"):
        return None
    twin = name[: -len("_car")] + "_nocar"
    return twin if twin in all_scenes else None


def _as_mapping(scene: SceneConfig) -> dict[str, Any]:
    """A built scene as the mapping it came from (body parts as a list of records)."""
    from dataclasses import asdict

    return asdict(scene)


# ----------------------------------------------------------------------------- kinematics
def _rot90(u: np.ndarray) -> np.ndarray:
    """Rotate (..., 2) vectors 90 deg counter-clockwise (to the walker's left)."""
    return np.stack([-u[..., 1], u[..., 0]], axis=-1)


def _rotate(u: np.ndarray, angle_rad: np.ndarray | float) -> np.ndarray:
    """Rotate (..., 2) vectors counter-clockwise by ``angle_rad`` (broadcast over leading axes)."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return np.stack([c * u[..., 0] - s * u[..., 1], s * u[..., 0] + c * u[..., 1]], axis=-1)


class WalkState(NamedTuple):
    """Pedestrian body-centre kinematics at F times."""

    position_m: np.ndarray    # (F, 2)
    velocity_mps: np.ndarray  # (F, 2)
    heading: np.ndarray       # (F, 2) unit walking direction
    turn_rate_rps: np.ndarray  # (F,) heading rate, rad/s (counter-clockwise positive)


def walk(ped: PedestrianConfig, t: np.ndarray) -> WalkState:
    """Body-centre path at times ``t`` (F,) s: straight, a constant-radius arc of ``turn_deg``,
    straight again, at constant speed. Closed form, continuous in position and heading.
    One walk of :func:`walks` (the same formula)."""
    t = np.asarray(t, dtype=float)
    w = walks(np.asarray(ped.start_xy_m, float)[None], np.asarray(ped.direction_xy, float)[None],
              np.array([ped.speed_mps]), np.array([ped.turn_after_m]),
              np.radians([ped.turn_deg]), np.array([ped.turn_radius_m]), t)
    return WalkState(*(a[0] for a in w))


def walks(start_xy_m: np.ndarray, direction_xy: np.ndarray, speed_mps: np.ndarray,
          turn_after_m: np.ndarray, turn_rad: np.ndarray, turn_radius_m: np.ndarray,
          t: np.ndarray) -> WalkState:
    """N walks of the scene's kind at once: straight for ``turn_after_m``, a constant-radius arc
    turning the heading counter-clockwise by ``turn_rad``, straight again, at constant speed.

    Args:
        start_xy_m: (N, 2) start positions, m. direction_xy: (N, 2) initial walking directions
            (any non-zero length). speed_mps, turn_after_m, turn_rad, turn_radius_m: (N,) speed
            (m/s), path length before the turn (m), turn angle (rad), arc radius (m; 0 = an
            instantaneous turn). t: (F,) times, s.

    Returns:
        :class:`WalkState` with a leading N axis: position (N, F, 2), velocity (N, F, 2),
        heading (N, F, 2), turn rate (N, F) rad/s. Closed form (arc of curvature
        ``turn_rad / (radius |turn_rad|)``), continuous in position and heading.
    """
    t = np.asarray(t, dtype=float)[None, :]                              # (1, F)
    u0 = np.asarray(direction_xy, dtype=float)
    u0 = (u0 / np.linalg.norm(u0, axis=-1, keepdims=True))[:, None, :]  # (N, 1, 2)
    n0 = _rot90(u0)
    speed = np.asarray(speed_mps, float)[:, None]
    s1 = np.asarray(turn_after_m, float)[:, None]
    delta = np.asarray(turn_rad, float)[:, None]
    radius = np.asarray(turn_radius_m, float)[:, None]
    s = speed * t                                                        # (N, F)
    arc_len = radius * np.abs(delta)
    before = np.minimum(s, s1)
    curved = arc_len > 0
    safe_len = np.where(curved, arc_len, 1.0)
    kappa = np.where(curved, delta / safe_len, 1.0)                     # 1/m (dummy if straight)
    on_arc = np.clip(s - s1, 0.0, arc_len)
    phi = np.where(curved, kappa * on_arc, np.where(s > s1, delta, 0.0))
    arc = np.where(curved[..., None],
                   (np.sin(phi) / kappa)[..., None] * u0
                   + ((1 - np.cos(phi)) / kappa)[..., None] * n0, 0.0)
    turning = curved & (s > s1) & (s < s1 + arc_len)
    rate = np.where(turning, speed * kappa, 0.0)
    after = np.maximum(s - s1 - arc_len, 0.0)
    u2 = _rotate(u0, delta)
    pos = (np.asarray(start_xy_m, float)[:, None, :] + before[..., None] * u0 + arc
           + after[..., None] * u2)
    heading = _rotate(u0, phi)
    return WalkState(pos, speed[..., None] * heading, heading, rate)


# ----------------------------------------------------------------------------- the scene
class Scene:
    """Scatterers and truth of one scene; vectorised over scatterers and times."""

    def __init__(self, cfg: SceneConfig):
        self.cfg = cfg
        self.car_polygon: np.ndarray | None = car_footprint(cfg.car) if cfg.with_car else None
        if self.car_polygon is not None:
            car_xy, car_rcs = car_scatterers(cfg.car, self.car_polygon)
        else:
            car_xy, car_rcs = np.zeros((0, 2)), np.zeros(0)
        self._car_xy = car_xy
        self._car_z = cfg.car.height_m - cfg.radar_height_m
        parts = cfg.pedestrian.parts
        self._part_rcs = 10.0 ** (np.array([p.rcs_dbsm for p in parts]) / 10.0)
        self.rcs_m2 = np.concatenate([car_rcs, self._part_rcs])
        self.names: tuple[str, ...] = ("car",) * len(car_rcs) + tuple(p.name for p in parts)
        self.is_pedestrian = np.array([n != "car" for n in self.names])
        self.torso_index = next((i for i, p in enumerate(parts) if p.name == "torso"), 0)

    @property
    def n_scatterers(self) -> int:
        return len(self.rcs_m2)

    def pedestrian_parts_at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, WalkState]:
        """Body-part positions (F, P, 3) and velocities (F, P, 3) at times (F,), and the walk."""
        ped = self.cfg.pedestrian
        t = np.atleast_1d(np.asarray(t, dtype=float))
        w = walk(ped, t)
        u, n, om = w.heading[:, None, :], _rot90(w.heading)[:, None, :], w.turn_rate_rps[:, None, None]
        lat = np.array([p.lateral_m for p in ped.parts])[:, None]
        amp = np.array([p.swing_m for p in ped.parts])
        phase = np.radians([p.phase_deg for p in ped.parts])
        f_stride = ped.speed_mps / ped.stride_length_m
        arg = 2 * np.pi * f_stride * t[:, None] + phase          # (F, P)
        d = (amp * np.sin(arg))[..., None]                        # swing along the heading
        d_dot = (amp * 2 * np.pi * f_stride * np.cos(arg))[..., None]
        xy = w.position_m[:, None, :] + d * u + lat * n
        # d/dt of heading u is om * n, of the normal n is -om * u
        vxy = w.velocity_mps[:, None, :] + d_dot * u + d * om * n - lat * om * u
        z = np.array([p.height_m for p in ped.parts]) - self.cfg.radar_height_m
        pos = np.concatenate([xy, np.broadcast_to(z, xy.shape[:2])[..., None]], axis=-1)
        vel = np.concatenate([vxy, np.zeros(vxy.shape[:2] + (1,))], axis=-1)
        return pos, vel, w

    def scatterers_at(self, t: float | np.ndarray) -> Scatterers:
        """All scatterers (car first, then the body parts) at time ``t``.

        Scalar t -> position_m (K, 3), velocity_mps (K, 3), rcs_m2 (K,), attenuation_db (K,);
        t of shape (F,) -> leading F axis on position, velocity and attenuation.
        """
        scalar = np.ndim(t) == 0
        t = np.atleast_1d(np.asarray(t, dtype=float))
        f = len(t)
        ped_pos, ped_vel, _ = self.pedestrian_parts_at(t)
        k_car = len(self._car_xy)
        car_pos = np.concatenate([self._car_xy, np.full((k_car, 1), self._car_z)], axis=1)
        pos = np.concatenate([np.broadcast_to(car_pos, (f, k_car, 3)), ped_pos], axis=1)
        vel = np.concatenate([np.zeros((f, k_car, 3)), ped_vel], axis=1)
        att = np.zeros((f, self.n_scatterers))
        if self.car_polygon is not None:
            hidden = segment_crosses_polygon(ped_pos[..., :2], self.car_polygon)
            att[:, k_car:] = np.where(hidden, self.cfg.occlusion_db, 0.0)
        rcs = self.rcs_m2
        if scalar:
            return Scatterers(pos[0], vel[0], rcs, att[0])
        return Scatterers(pos, vel, rcs, att)

    def frame_times(self, frame_period_s: float) -> np.ndarray:
        """(n_frames,) frame start times, s."""
        return self.cfg.start_time_s + np.arange(self.cfg.n_frames) * frame_period_s

    def truth(self, times_s: np.ndarray) -> pd.DataFrame:
        """Per-time pedestrian truth (torso), columns ``TRUTH_COLUMNS``."""
        times_s = np.asarray(times_s, dtype=float)
        pos, _, w = self.pedestrian_parts_at(times_s)
        x, y = w.position_m[:, 0], w.position_m[:, 1]
        vx, vy = w.velocity_mps[:, 0], w.velocity_mps[:, 1]
        rng = np.hypot(x, y)
        if self.car_polygon is not None:
            hidden = segment_crosses_polygon(pos[..., :2], self.car_polygon)  # (F, P)
            torso_hidden = segment_crosses_polygon(w.position_m, self.car_polygon)
        else:
            hidden = np.zeros(pos.shape[:2], dtype=bool)
            torso_hidden = np.zeros(len(times_s), dtype=bool)
        visible = (~hidden * self._part_rcs).sum(axis=1) / self._part_rcs.sum()
        return pd.DataFrame({
            "frame": np.arange(len(times_s), dtype=np.int64),
            "time_s": times_s,
            "x_m": x, "y_m": y, "vx_mps": vx, "vy_mps": vy,
            "range_m": rng,
            "radial_velocity_mps": (x * vx + y * vy) / rng,
            "angle_deg": np.degrees(np.arctan2(x, y)),
            "occluded": torso_hidden,
            "visible_fraction": visible,
        }, columns=list(TRUTH_COLUMNS))


def scene_truth(scene_cfg: SceneConfig | Mapping[str, Any], radar: RadarConfig) -> pd.DataFrame:
    """Pedestrian truth for every frame of a scene (frame start times from the radar's frame
    period). Columns: frame, time_s, x_m, y_m, vx_mps, vy_mps, range_m, radial_velocity_mps,
    angle_deg, occluded (torso line of sight blocked by the car), visible_fraction (share of the
    pedestrian's RCS whose line of sight is clear)."""
    cfg = scene_cfg if isinstance(scene_cfg, SceneConfig) else SceneConfig.from_mapping(scene_cfg)
    scene = Scene(cfg)
    return scene.truth(scene.frame_times(radar.frame_period_s))


# ----------------------------------------------------------------------------- the car
def car_footprint(car: CarConfig) -> np.ndarray:
    """(4, 2) corners of the car's footprint, counter-clockwise. yaw 0 = long axis along +y;
    positive yaw rotates the car counter-clockwise."""
    hw, hl = car.width_m / 2, car.length_m / 2
    local = np.array([[-hw, -hl], [hw, -hl], [hw, hl], [-hw, hl]])  # (across, along)
    return _rotate(local, math.radians(car.yaw_deg)) + np.asarray(car.center_xy_m)


def car_scatterers(car: CarConfig, polygon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Scatterers on the faces of the car the radar sees, plus the visible bright points.

    Returns xy (K, 2) m and rcs (K,) m^2 summing to ``car.rcs_dbsm``. Face points sit every
    ``face_spacing_m`` along each edge; a point is kept when its line of sight, stopped 1 mm short
    of it, does not cross the footprint (so only faces turned towards the radar remain)."""
    q0, q1 = polygon, np.roll(polygon, -1, axis=0)
    lengths = np.linalg.norm(q1 - q0, axis=1)
    counts = np.maximum(1, np.ceil(lengths / car.face_spacing_m).astype(int))
    edge = np.repeat(np.arange(len(polygon)), counts)
    frac = (np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts) + 0.5) / counts[edge]
    face_xy = q0[edge] + frac[:, None] * (q1 - q0)[edge]
    bright = np.array([(b.across_m, b.along_m, b.share) for b in car.bright_points],
                      dtype=float).reshape(-1, 3)
    bright_xy = _rotate(bright[:, :2], math.radians(car.yaw_deg)) + np.asarray(car.center_xy_m)
    xy = np.concatenate([face_xy, bright_xy])
    face_share = 1.0 - bright[:, 2].sum()
    weight = np.concatenate([np.full(len(face_xy), face_share / max(len(face_xy), 1)), bright[:, 2]])
    r = np.linalg.norm(xy, axis=1, keepdims=True)
    seen = ~segment_crosses_polygon(xy * (1 - 1e-3 / r), polygon)
    xy, weight = xy[seen], weight[seen]
    if weight.sum() <= 0:
        raise ConfigError("car.bright_points", car.bright_points, "shares leaving RCS on visible points")
    rcs = 10 ** (car.rcs_dbsm / 10) * weight / weight.sum()
    return xy, rcs


# ----------------------------------------------------------------------------- group merging
# Shared by this group and the driving scenarios (blindspot.radar.scenario).

def _present(scenes: Mapping[str, Any]) -> dict[str, Any]:
    """The entries of a group's ``scenes`` that are not null."""
    return {name: over for name, over in scenes.items() if over is not None}


def _merged_scenes(scenes: Mapping[str, Any], shared: Mapping[str, Any], where: str
                   ) -> list[tuple[str, dict[str, Any], str]]:
    """``(name, scene settings deep-merged over shared, config key)`` of each entry of a scene
    group's ``scenes``, in file order; ConfigError naming ``<where>.scenes.<name>`` for an entry
    that is not a mapping.

    An entry set to null is left out: a Hydra config merged over the group (a run-size profile,
    ``conf/profile/tiny.yaml``) can replace a key's value but cannot delete the key, so null is
    how it drops a scene (``~scene.scenes.<name>`` does the same on the command line)."""
    out = []
    for name, over in _present(scenes).items():
        key = f"{where}.scenes.{name}"
        if not isinstance(over, Mapping):
            raise ConfigError(key, over, "a mapping of scene settings")
        merged = _deep_merge(shared, over)
        merged.setdefault("name", str(name))
        out.append((str(name), merged, key))
    return out


def _deep_merge(base: Mapping[str, Any], over: Mapping[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for k, v in over.items():
        out[k] = _deep_merge(out[k], v) if isinstance(v, Mapping) and isinstance(out.get(k), Mapping) else v
    return out
