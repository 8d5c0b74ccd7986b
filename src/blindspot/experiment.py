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

