"""The experiment's objects built from the composed config, shared by the stages.

Stages (``stages/*.py``) stay thin: they call these to get the radar, its array, the scenes and the
artifact paths, then call the library and write their declared outputs.
"""

from __future__ import annotations

from pathlib import Path
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


def data_path(cfg: DictConfig, *parts: str) -> Path:
    """A path under ``cfg.paths.data_dir`` (relative to the repo root, the stages' cwd)."""
    return Path(cfg.paths.data_dir, *parts)


def reports_path(cfg: DictConfig, *parts: str) -> Path:
    return Path(cfg.paths.reports_dir, *parts)



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


def save_report_figure(cfg: DictConfig, fig, name: str, **savefig_kwargs) -> Path:
    """Write ``reports/figures/<name>.png`` atomically and log it to the stage's MLflow run."""
    from blindspot import tracking
    from blindspot.io import save_figure

    out = save_figure(fig, reports_path(cfg, "figures", f"{name}.png"), **savefig_kwargs)
    tracking.current().log_artifact(out)
    return out


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
