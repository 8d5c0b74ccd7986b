"""The experiment's objects built from the composed config, shared by the stages.

Stages (``stages/*.py``) stay thin: they call these to get the radar, its array, the scenes and
the baselines, then call the library and write their declared outputs (paths from ``dvc.yaml``
through :class:`blindspot.stage.StageContext`).
"""

from __future__ import annotations

from typing import Any

from omegaconf import DictConfig

from blindspot.radar.array import VirtualArray, array_for
from blindspot.radar.config import RadarConfig
from blindspot.radar.scene import SceneConfig, load_scenes


def radar(cfg: DictConfig) -> RadarConfig:
    """The radar profile of ``cfg.radar``."""
    return RadarConfig.from_mapping(cfg.radar, where="radar")


def array(cfg: DictConfig) -> VirtualArray:
    return array_for(radar(cfg))


def scenes(cfg: DictConfig) -> dict[str, SceneConfig]:
    """{name: SceneConfig} of ``cfg.scene`` in file order."""
    return load_scenes(cfg.scene, where="scene")


def car_twin(name: str, all_scenes: dict[str, Any]) -> str | None:
    """The scene with the same walk and no car (``approach_car`` -> ``approach_nocar``)."""
    if not name.endswith("_car"):
        return None
    twin = name[: -len("_car")] + "_nocar"
    return twin if twin in all_scenes else None


def scene_track(points, scene: str, n_frames: int):
    """(n_frames, 2) x, y of a scene's points (``localise`` output), NaN where no point."""
    import numpy as np

    track = np.full((n_frames, 2), np.nan)
    p = points[points.scene == scene]
    track[p.frame.to_numpy()] = p[["x_m", "y_m"]].to_numpy()
    return track


def kalman(cfg: DictConfig):
    """The constant-velocity Kalman baseline of ``cfg.eval.kalman`` at the radar's frame period."""
    from blindspot.traj.baselines import KalmanCV

    return KalmanCV(dt=float(cfg.radar.frame_period_s), **cfg.eval.kalman)


def predictors(cfg: DictConfig, lstm=None) -> dict:
    """The prediction methods of ``cfg.eval.prediction_methods`` by name."""
    from blindspot.traj.baselines import ConstantVelocity

    made = {
        "lstm": lstm,
        "constant_velocity": ConstantVelocity(k=int(cfg.eval.cv_fit_points), name="constant_velocity"),
        "kalman": kalman(cfg),
    }
    out = {}
    for name in cfg.eval.prediction_methods:
        if name not in made or made[name] is None:
            raise ValueError(f"config key 'eval.prediction_methods' lists {name!r}: expected names "
                             f"from {sorted(k for k, v in made.items() if v is not None)}")
        out[name] = made[name]
    return out
