"""The typed ``scenario`` group: the driving scenes past parked cars (issue 11).

The configs of :mod:`blindspot.radar.driving` (see there for the geometry, the sources and the
kinematics): ego car, parked cars, static clutter, pedestrians and their behaviour, the named
scenes, the Euro NCAP nominal set and the Monte-Carlo draw. Apart from the kinematics, so that
reading the config does not import them; apart from the paper's scene (:mod:`blindspot.radar.scene`),
whose body parts and group merging it shares.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from blindspot.radar.scene import BodyPart, _merged_scenes, _present
from blindspot.typed_config import ConfigError, TypedConfig, setting

BEHAVIOURS = ("cross", "stop_at_kerb", "along_kerb", "turn_back", "cross_after")
INTRUDING = ("cross",)
KMH = 1.0 / 3.6


@dataclass(frozen=True)
class BodyModel(TypedConfig):
    """A pedestrian target: box (length along the walking direction, width, height), the
    reference point's distance behind the box front [V], gait and radar body parts."""

    length_m: float = setting(gt=0.0, le=3.0)
    width_m: float = setting(gt=0.0, le=3.0)
    height_m: float = setting(gt=0.0, le=3.0)
    ref_from_front_m: float = setting(ge=0.0, le=3.0)
    stride_length_m: float = setting(ge=0.1, le=5.0)
    parts: tuple[BodyPart, ...] = setting(min_items=1, doc="at least one body part")
    name: str = setting("body")

    def validate(self) -> None:
        if self.ref_from_front_m > self.length_m:
            raise ConfigError("ref_from_front_m", self.ref_from_front_m,
                              f"at most the box length {self.length_m} m")

    @property
    def rcs_m2(self) -> np.ndarray:
        """(n_parts,) RCS of each body part, m^2."""
        return 10.0 ** (np.array([p.rcs_dbsm for p in self.parts]) / 10.0)


@dataclass(frozen=True)
class EgoConfig(TypedConfig):
    """The ego car [V]: footprint (the radar sits at the front-bumper centre), radar height."""

    width_m: float = setting(gt=0.5, le=5.0)
    length_m: float = setting(gt=0.5, le=20.0)
    radar_height_m: float = setting(ge=0.0, le=3.0)
    rear_axle_to_radar_m: float = setting(3.5, gt=0.0, le=20.0,
                                          doc="the bumper radar's distance ahead of the rear axle "
                                              "centre along the centre line (Kellner et al. 2013 "
                                              "ego-motion needs it for the yaw rate)")


@dataclass(frozen=True)
class ParkedCar(TypedConfig):
    """A car parked parallel to the road: lateral centre ``center_x_m`` (world x), its front
    (the end the ego meets last) at ``front_y_m``, footprint, RCS and scatterer layout."""

    center_x_m: float = setting(ge=-50.0, le=50.0)
    front_y_m: float = setting(ge=-500.0, le=500.0)
    length_m: float = setting(ge=0.5, le=30.0)
    width_m: float = setting(ge=0.5, le=10.0)
    rcs_dbsm: float = setting(ge=-30.0, le=60.0)
    name: str = setting("car")


@dataclass(frozen=True)
class StaticClutter(TypedConfig):
    """A line of static scatterers parallel to the road (kerb stones, poles, building fronts):
    at world x ``x_m`` from ``y_from_m`` to ``y_to_m`` every ``spacing_m``, each ``rcs_dbsm``."""

    x_m: float = setting(ge=-100.0, le=100.0)
    y_from_m: float = setting(ge=-1000.0, le=1000.0)
    y_to_m: float = setting(ge=-1000.0, le=1000.0)
    spacing_m: float = setting(gt=0.1, le=100.0)
    rcs_dbsm: float = setting(ge=-40.0, le=40.0)
    height_m: float = setting(0.5, ge=0.0, le=10.0)
    name: str = setting("clutter")

    def validate(self) -> None:
        if self.y_to_m <= self.y_from_m:
            raise ConfigError("y_to_m", self.y_to_m, f"more than y_from_m = {self.y_from_m}")


@dataclass(frozen=True)
class PedestrianSpec(TypedConfig):
    """One pedestrian: body, behaviour, side, the NCAP timing parameters [V] and the deviation
    of its behaviour."""

    body: str = setting(doc="a body model name of scenario.bodies")
    behaviour: str = setting(choices=BEHAVIOURS)
    side: str = setting("near", choices=("near", "far"))
    start_offset_m: float = setting(4.0, gt=0.0, le=50.0)     # E, from the impact point
    accel_distance_m: float = setting(1.0, gt=0.0, le=20.0)   # G
    speed_mps: float = setting(1.389, gt=0.0, le=10.0)
    impact_pct: float = setting(50.0, ge=-100.0, le=200.0)
    delay_s: float = setting(0.0, ge=-30.0, le=30.0)
    walk_y_m: float = setting(0.0, ge=-200.0, le=200.0)       # walking line (0 = the NCAP line)
    stop_margin_m: float = setting(0.0, ge=-1.0, le=5.0)      # box front beyond the kerb line
    along_sign: int = setting(1, choices=(-1, 1))
    after_gap_s: float = setting(2.0, ge=0.0, le=30.0)
    name: str = setting("pedestrian")


@dataclass(frozen=True)
class DrivingScene(TypedConfig):
    """One driving scene: ego speed, timing, parked cars, static clutter and pedestrians."""

    speed_kmh: float = setting(gt=0.0, le=200.0)
    lead_time_s: float = setting(gt=0.0, le=60.0)
    tail_time_s: float = setting(ge=0.0, le=60.0)
    pedestrians: tuple[PedestrianSpec, ...] = setting(min_items=1, doc="1 to 3 pedestrians")
    parked_cars: tuple[ParkedCar, ...] = setting(())
    clutter: tuple[StaticClutter, ...] = setting(())
    seed: int = setting(0, ge=0, le=2**63 - 1)
    name: str = setting("scene")
    yaw_rate_deg_s: float = setting(0.0, ge=-60.0, le=60.0,
                                    doc="constant yaw rate of the ego car (positive = turning "
                                        "left); 0 drives straight")

    def validate(self) -> None:
        if len(self.pedestrians) > 3:
            raise ConfigError("pedestrians", len(self.pedestrians), "1 to 3 pedestrians")

    @property
    def speed_mps(self) -> float:
        return self.speed_kmh * KMH


@dataclass(frozen=True)
class MonteCarloConfig(TypedConfig):
    """The seeded Monte-Carlo set (:func:`draw_scenarios`): a grid of ego speed x impact point x
    intruding / non-intruding, ``scenes_per_cell`` draws per cell of body, behaviour, gap
    position (where along the parked cars the pedestrian steps out), timing and bystanders;
    ``tuning_seed`` / ``tuning_scenes_per_cell`` and ``held_out_seed`` /
    ``held_out_scenes_per_cell`` draw the independent tuning and held-out sets of the same grid
    (:func:`blindspot.safety.draws.independent_scenes`, issue 40); the main draw (``seed``,
    ``scenes_per_cell``) is the one the driving stages keep per scene for figures and studies."""

    seed: int = setting(ge=0, le=2**63 - 1)
    speeds_kmh: tuple[float, ...] = setting(gt=0.0, le=200.0, min_items=1)
    impact_pct: tuple[float, ...] = setting(ge=0.0, le=100.0, min_items=1)
    scenes_per_cell: int = setting(ge=1, le=10_000)
    non_intruding: tuple[str, ...] = setting(choices=BEHAVIOURS[1:], min_items=1)
    bodies: tuple[str, ...] = setting(min_items=1)
    front_gap_m: tuple[float, float] = setting(ge=0.0, le=50.0, ordered=True)
    between_cars_share: float = setting(ge=0.0, le=1.0)
    delay_jitter_s: float = setting(ge=0.0, le=10.0)
    speed_jitter: float = setting(ge=0.0, le=0.5)
    max_bystanders: int = setting(ge=0, le=2)
    held_out_seed: int = setting(3, ge=0, le=2**63 - 1)
    held_out_scenes_per_cell: int = setting(17, ge=1, le=10_000)
    tuning_seed: int = setting(2, ge=0, le=2**63 - 1)
    tuning_scenes_per_cell: int = setting(17, ge=1, le=10_000)

    def validate(self) -> None:
        if self.held_out_seed == self.seed:
            raise ConfigError("held_out_seed", self.held_out_seed,
                              f"a seed other than monte_carlo.seed = {self.seed} (the held-out "
                              "draw must be independent of the main draw)")
        if self.tuning_seed in (self.seed, self.held_out_seed):
            raise ConfigError("tuning_seed", self.tuning_seed,
                              f"a seed other than monte_carlo.seed = {self.seed} and "
                              f"held_out_seed = {self.held_out_seed} (each draw has its own)")


@dataclass(frozen=True)
class ScenarioGroup(TypedConfig):
    """The Hydra group ``scenario`` (``conf/scenario/euro_ncap.yaml``): shared ego, bodies,
    parked cars, clutter and timing; named scenes (partial scene settings over ``shared``);
    the Monte-Carlo set; the scene of the figures."""

    GROUP = "scenario"

    ego: EgoConfig = setting()
    bodies: tuple[BodyModel, ...] = setting(min_items=1)
    occlusion_db: float = setting(ge=0.0, le=300.0)
    car_face_spacing_m: float = setting(ge=0.05, le=10.0)
    shared: dict = setting(doc="scene settings every scene starts from")
    scenes: dict = setting(doc="a mapping {scene name: settings over shared, or null to leave "
                               "it out}, at least one")
    monte_carlo: MonteCarloConfig = setting()
    figure_scene: str = setting(doc="a scene name of scenario.scenes")

    def validate(self) -> None:
        present = _present(self.scenes)
        if not present:
            raise ConfigError("scenes", self.scenes, "at least one scene that is not null")
        if self.figure_scene not in present:
            raise ConfigError("figure_scene", self.figure_scene,
                              f"one of the scene names {sorted(map(str, present))}")
        names = {b.name for b in self.bodies}
        for b in self.monte_carlo.bodies:
            if b not in names:
                raise ConfigError("monte_carlo.bodies", self.monte_carlo.bodies,
                                  f"body names of scenario.bodies {sorted(names)}")

    def body(self, name: str, key: str = "body") -> BodyModel:
        for b in self.bodies:
            if b.name == name:
                return b
        raise ConfigError(key, name, f"a body of scenario.bodies {sorted(b.name for b in self.bodies)}")


def load_scenarios(group: Any, where: str = "scenario") -> tuple[ScenarioGroup, dict[str, DrivingScene]]:
    """The typed group and its named scenes (each deep-merged over ``shared``), in file order.

    Raises:
        ConfigError: a missing or invalid key, named ``scenario.shared.<key>`` (``shared`` must
        be a complete scene) or ``scenario.scenes.<name>.<key>``, or a pedestrian's body not in
        ``scenario.bodies``.
    """
    g = ScenarioGroup.from_mapping(group, where)
    # shared alone is a complete scene: a bad value there is named scenario.shared.<key> even
    # where every scene overrides it
    DrivingScene.from_mapping(g.shared, where=f"{where}.shared")
    out = {}
    for name, merged, key in _merged_scenes(g.scenes, g.shared, where):
        sc = DrivingScene.from_mapping(merged, where=key)
        for i, p in enumerate(sc.pedestrians):
            g.body(p.body, f"{key}.pedestrians[{i}].body")
        out[name] = sc
    return g, out




# ----------------------------------------------------------------------------- parsing helpers
