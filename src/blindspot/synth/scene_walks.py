"""Many randomised walks of the paper's scene kind, measured by the radar (issue 10, section 3).

The paper's scene (``conf/scene/paper.yaml``, :mod:`blindspot.radar.scene`): a car parked with
its long axis along the radar's boresight to the right of it, a pedestrian who starts beyond the
car's far end on the kerb side, walks across (in -x) hidden behind the car, steps out past its
far-left corner and turns. A benchmark walk draws every free quantity of that scene at random
(:class:`WalksConfig`, ``conf/walks/``):

* the car: centre, length, width, yaw;
* the walk: start beyond the car's far end and to its right, initial heading around -x,
  speed (paper: 1.0-1.5 m/s), turn angle (-60..60 deg; + = counter-clockwise, towards the
  radar), arc radius, and *where* it turns (path walked after leaving the car's shadow);
* *when* the prediction starts (time after the turn begins) and every seed.

Each walk is then measured frame by frame through the validated reduced radar chain
(:func:`blindspot.synth.path_dataset.measure_path_set`, the ``paths`` stage's chain) with the
car's footprint as occluder (each body part whose line of sight crosses it loses the scene's
``occlusion_db``), so a walk carries the radar's points, its misses and the hidden stretch.

Seeds: every draw comes from ``SeedSequence([seed, BENCHMARK_STREAM])`` and the radar noise
from a child of it; the training paths (``paths`` stage) use ``SeedSequence(seed)`` and its
children, so no benchmark walk shares a random stream with a training path.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from blindspot.radar.occlusion import segment_crosses_polygons
from blindspot.radar.scene import walks
from blindspot.traj.config import WalksConfig

__all__ = ["BENCHMARK_STREAM", "WalksConfig", "SceneWalks", "car_scene_walks", "draw_scene_walks",
           "measure_scene_walks"]

# Spawn key of the benchmark's random stream ("bnch"); the training paths use the bare seed.
BENCHMARK_STREAM = 0x626E6368


@dataclass(frozen=True)
class SceneWalks:
    """N drawn walks; arrays over walks (N,) unless shaped otherwise.

    Attributes:
        truth: (N, T, 2) body-centre positions, m, at the radar's frame period (T frames from
            the walk's start, enough for every walk's prediction horizon).
        hidden: (N, T) True where the body centre's line of sight crosses the car.
        car: (N, 4, 2) car footprints (corners, counter-clockwise), m.
        start: (N,) frame the prediction starts at (the history is frames < start).
        speed_mps, turn_deg: (N,) the walk's speed and turn angle.
        turn_frame: (N,) frame at which the turn begins.
    """

    truth: np.ndarray
    hidden: np.ndarray
    car: np.ndarray
    start: np.ndarray
    speed_mps: np.ndarray
    turn_deg: np.ndarray
    turn_frame: np.ndarray

    def __len__(self) -> int:
        return int(self.truth.shape[0])


def _uniform(rng: np.random.Generator, bounds: tuple[float, float], n: int) -> np.ndarray:
    return rng.uniform(bounds[0], bounds[1], size=n)


def draw_scene_walks(cfg: WalksConfig, frame_period_s: float, seed: int) -> SceneWalks:
    """Draw ``cfg.n_walks`` walks of the paper's scene kind (vectorised over walks).

    The pedestrian starts ``start_beyond_far_end_m`` beyond the car's far end and
    ``visible_before_shadow_m`` before the car's shadow on that line (paper: 0.9 m, ~0.7 s in
    sight, so the hidden stretch has points on both sides), walks towards -x (heading within
    ``heading_deg``), is hidden while the car blocks the line of sight, and turns by
    ``turn_deg`` on an arc of ``turn_radius_m`` after walking ``turn_after_exit_m`` past the
    shadow's edge (where the ray from the radar through the car's corner of smallest azimuth
    crosses the walk's start line; the paper's scene: x = 1.64 m, turning 1.3 m later at x = 0.3 m). The
    prediction starts ``prediction_after_turn_s`` after the turn begins.

    Raises ValueError: frame_period_s not > 0.
    """
    if not frame_period_s > 0:
        raise ValueError(f"frame_period_s: expected > 0 s, found {frame_period_s!r}")
    n = cfg.n_walks
    rng = np.random.default_rng(np.random.SeedSequence([seed, BENCHMARK_STREAM]))
    cx, cy = _uniform(rng, cfg.car_center_x_m, n), _uniform(rng, cfg.car_center_y_m, n)
    length, width = _uniform(rng, cfg.car_length_m, n), _uniform(rng, cfg.car_width_m, n)
    yaw = np.radians(_uniform(rng, cfg.car_yaw_deg, n))
    # footprints as radar.scene.car_footprint, for N cars at once
    local = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)[None] * \
        np.stack([width / 2, length / 2], axis=-1)[:, None, :]
    c, s = np.cos(yaw)[:, None], np.sin(yaw)[:, None]           # counter-clockwise, as the scene
    car = np.stack([c * local[..., 0] - s * local[..., 1], s * local[..., 0] + c * local[..., 1]],
                   axis=-1) + np.stack([cx, cy], axis=-1)[:, None, :]
    far_y = car[..., 1].max(axis=1)
    # the shadow's edges: the rays from the radar through the corners of extreme azimuth
    left_slope = (car[..., 0] / car[..., 1]).min(axis=1)                # x / y = tan(azimuth)
    right_slope = (car[..., 0] / car[..., 1]).max(axis=1)
    y0 = far_y + _uniform(rng, cfg.start_beyond_far_end_m, n)
    head = np.radians(_uniform(rng, cfg.heading_deg, n))
    x0 = right_slope * y0 + _uniform(rng, cfg.visible_before_shadow_m, n) * np.cos(head)
    direction = np.stack([-np.cos(head), np.sin(head)], axis=-1)       # -x, rotated ccw by head
    speed = _uniform(rng, cfg.speed_mps, n)
    turn = _uniform(rng, cfg.turn_deg, n)
    radius = _uniform(rng, cfg.turn_radius_m, n)
    # the shadow's edge on the start line y = y0
    x_exit = left_slope * y0
    turn_after = (x0 - x_exit) / np.cos(head) + _uniform(rng, cfg.turn_after_exit_m, n)
    t_turn = turn_after / speed
    t_start = t_turn + _uniform(rng, cfg.prediction_after_turn_s, n)
    start = np.ceil(t_start / frame_period_s - 1e-9).astype(np.int64)
    T = int(start.max()) + cfg.horizon_frames
    t = np.arange(T) * frame_period_s
    w = walks(np.stack([x0, y0], axis=-1), direction, speed, turn_after, np.radians(turn),
              radius, t)
    hidden = segment_crosses_polygons(w.position_m, car)
    return SceneWalks(truth=w.position_m, hidden=hidden, car=car, start=start,
                      speed_mps=speed, turn_deg=turn,
                      turn_frame=np.floor(t_turn / frame_period_s).astype(np.int64))


def measure_scene_walks(walks_: SceneWalks, radar, cfar, doa, detect, *, pedestrian,
                        occlusion_db: float, seed: int, jobs: int = 1,
                        progress: bool = False) -> np.ndarray:
    """The radar's point of every frame before each walk's prediction start.

    Every frame before the walk's own prediction start goes through
    :func:`blindspot.synth.path_dataset.measure_path_set` (the ``paths`` stage's reduced chain)
    with the walk's car as occluder; frames at or after it are returned NaN (the future is not
    measured: the predictors never see it, and it costs nothing). The radar noise is drawn from a child of
    the benchmark stream, ``SeedSequence([seed, BENCHMARK_STREAM, 1])``.

    Returns (N, T, 2) measured points, m, NaN where the chain gave no point.
    """
    from blindspot.synth.path_dataset import measure_path_set

    T_meas = int(walks_.start.max())
    noise_seed = int(np.random.SeedSequence([seed, BENCHMARK_STREAM, 1])
                     .generate_state(1, dtype=np.uint32)[0])
    paths = SimpleNamespace(xy=walks_.truth[:, :T_meas])      # what measure_path_set reads
    past = np.arange(T_meas)[None, :] < walks_.start[:, None]
    measured = measure_path_set(paths, radar, cfar, doa, detect, pedestrian=pedestrian,
                                seed=noise_seed, jobs=jobs, progress=progress,
                                occluders=walks_.car, occlusion_db=occlusion_db, frames=past)
    xy = np.full(walks_.truth.shape, np.nan)
    xy[:, :T_meas] = measured.xy
    return xy


def car_scene_walks(bench: WalksConfig, radar, car, cfar, doa, detect, *, seed: int,
                    jobs: int = 1, progress: bool = False) -> tuple[SceneWalks, np.ndarray]:
    """(walks, measured): ``bench``'s occluded walks of the paper's car scene ``car`` (a
    :class:`~blindspot.radar.scene.SceneConfig` with the car: its pedestrian model and occlusion
    loss) drawn with ``seed`` and measured through the paper's chain on ``jobs`` worker
    processes; what the walks stage and the studies that score other models on its walks draw."""
    from blindspot.synth.path_measurement import PedestrianModel

    walks_ = draw_scene_walks(bench, radar.frame_period_s, seed=seed)
    measured = measure_scene_walks(
        walks_, radar, cfar, doa, detect, pedestrian=PedestrianModel.from_scene(car),
        occlusion_db=car.occlusion_db, seed=seed, jobs=jobs, progress=progress)
    return walks_, measured
