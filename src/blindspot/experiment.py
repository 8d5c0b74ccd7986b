"""The experiment's objects built from the composed config, shared by the stages.

Stages (``stages/*.py``) stay thin: they call these to get the radar, its array, the scenes and
the baselines, then call the library and write their declared outputs (paths from ``dvc.yaml``
through :class:`blindspot.stage.StageContext`).
"""

from __future__ import annotations

from typing import Any

from omegaconf import DictConfig

from blindspot.dsp.config import (
    BridgeConfig, CfarConfig, DetectConfig, DoaConfig, EgoMotionConfig,
)
from blindspot.radar.array import VirtualArray, array_for
from blindspot.radar.config import RadarConfig, SimConfig
from blindspot.radar.scene import (
    DrivingScene, ScenarioGroup, SceneConfig, load_scenarios, load_scenes,
)
from blindspot.typed_config import ConfigError
from blindspot.traj.config import (WalksConfig, CalibrationConfig, DatasetConfig,
                                   DirectConfig, EthUcyConfig, EvalConfig, LSTMConfig, TrainConfig)


# One builder per config group: stages hand these typed objects to the library, never raw groups.
def jobs(cfg: DictConfig) -> int:
    """The top-level ``jobs``: worker processes (detect, paths, the driving set, the tracker,
    ETH/UCY) or LSTM inference threads (the stages that roll the scene LSTM out); 1 = in this
    process. Raises ConfigError naming the key for anything but an integer >= 1."""
    value = cfg.jobs
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ConfigError("jobs", value, "an integer >= 1 (worker processes or threads)")
    return value


def radar(cfg: DictConfig) -> RadarConfig:
    """The radar profile of ``cfg.radar``."""
    return RadarConfig.from_mapping(cfg.radar)


def sim(cfg: DictConfig) -> SimConfig:
    """The simulator settings of ``cfg.sim``."""
    return SimConfig.from_mapping(cfg.sim)


def cfar(cfg: DictConfig) -> CfarConfig:
    """The CFAR settings of ``cfg.cfar``."""
    return CfarConfig.from_mapping(cfg.cfar)


def driving_cfar(cfg: DictConfig) -> CfarConfig:
    """The driving chain's CFAR settings, ``cfg.driving_cfar`` (a ``cfar`` group option placed
    under its own key, so the paper's stages keep ``cfar``)."""
    return CfarConfig.from_mapping(cfg.driving_cfar, "driving_cfar")


def doa(cfg: DictConfig) -> DoaConfig:
    """The angle-estimation settings of ``cfg.doa``."""
    return DoaConfig.from_mapping(cfg.doa)


def detect(cfg: DictConfig) -> DetectConfig:
    """The detection-chain settings of ``cfg.detect``."""
    return DetectConfig.from_mapping(cfg.detect)


def bridge(cfg: DictConfig) -> BridgeConfig:
    """The ``bridge`` group (zero-Doppler points of a target crossing the line of sight)."""
    return BridgeConfig.from_mapping(cfg.bridge)


def dataset(cfg: DictConfig) -> DatasetConfig:
    """The path data set and window settings of ``cfg.dataset``."""
    return DatasetConfig.from_mapping(cfg.dataset)


def model(cfg: DictConfig) -> LSTMConfig:
    """The LSTM settings of ``cfg.model``."""
    return LSTMConfig.from_mapping(cfg.model)


def training(cfg: DictConfig) -> TrainConfig:
    """The optimisation settings of ``cfg.train``."""
    return TrainConfig.from_mapping(cfg.train)


def ethucy(cfg: DictConfig) -> EthUcyConfig:
    """The ETH/UCY benchmark settings of ``cfg.ethucy``."""
    return EthUcyConfig.from_mapping(cfg.ethucy)


def evaluation(cfg: DictConfig) -> EvalConfig:
    """The interpolation / prediction / evaluation settings of ``cfg.eval``."""
    return EvalConfig.from_mapping(cfg.eval)


def walks(cfg: DictConfig):
    """The many-walk benchmark settings of ``cfg.walks``."""
    return WalksConfig.from_mapping(cfg.walks)


def direct(cfg: DictConfig) -> DirectConfig:
    """The scenes' direct multi-step predictor and its training, ``cfg.direct`` (whether it
    fits the calibration pairs: :func:`blindspot.traj.direct.check_fits`)."""
    return DirectConfig.from_mapping(cfg.direct)


def calibration(cfg: DictConfig):
    """The predictive-distribution calibration settings of ``cfg.calibration``."""
    return CalibrationConfig.from_mapping(cfg.calibration)


def scenarios(cfg: DictConfig) -> tuple[ScenarioGroup, dict[str, DrivingScene]]:
    """The driving-scenario group of ``cfg.scenario`` and its named scenes, in file order."""
    return load_scenarios(cfg.scenario)


def driving_radar(cfg: DictConfig) -> RadarConfig:
    """The driving radar profile of ``cfg.driving_radar`` (a ``radar`` group option placed under
    its own key, so the paper's stages keep ``cfg.radar``)."""
    return RadarConfig.from_mapping(cfg.driving_radar, where="driving_radar")


def ego_motion(cfg: DictConfig) -> EgoMotionConfig:
    """The moving-car radar settings of ``cfg.ego_motion`` (odometry, robust fit, budget)."""
    return EgoMotionConfig.from_mapping(cfg.ego_motion)


def _track_config():
    """:mod:`blindspot.track.config`, imported when a tracking builder runs. Every stage imports
    this module; a static import would make the import graph (tests/pipeline/
    test_stage_files.py) tie each of them to the tracker, whose changes cannot change their
    outputs. The stages that track import blindspot.track themselves and list it in their deps."""
    import importlib

    return importlib.import_module("blindspot.track.config")


def tracker(cfg: DictConfig):
    """The multi-target tracker settings of ``cfg.tracker`` (clustering, filter, gating,
    association, M-of-N confirmation, deletion): a ``blindspot.track.TrackerConfig``."""
    return _track_config().TrackerConfig.from_mapping(cfg.tracker)


def warning(cfg: DictConfig):
    """The collision-risk, warning and AEB settings of ``cfg.warning``: a
    ``blindspot.safety.config.WarningConfig`` (imported when called, as :func:`_track_config`
    explains for the tracker)."""
    import importlib

    return importlib.import_module("blindspot.safety.config").WarningConfig.from_mapping(
        cfg.warning)


def real_tracking(cfg: DictConfig) -> dict:
    """The real recordings of ``cfg.real_tracking``, each with its tracker settings: the
    ``tracker`` group with the record's ``tracker`` keys laid over it (errors name
    ``real_tracking.recordings.<name>.tracker.<key>``): ``{name: (TrackedRecording,
    TrackerConfig)}``."""
    from omegaconf import OmegaConf

    track_config = _track_config()
    TrackerConfig = track_config.TrackerConfig
    group = track_config.RealTrackingConfig.from_mapping(cfg.real_tracking)
    TrackerConfig.from_mapping(cfg.tracker)  # a bad tracker-group value is named tracker.<key>
    out = {}
    for rec in group.recordings:
        overrides = cfg.real_tracking["recordings"][rec.name].get("tracker") or {}
        merged = OmegaConf.merge(cfg.tracker, overrides)
        out[rec.name] = (rec, TrackerConfig.from_mapping(
            merged, where=f"real_tracking.recordings.{rec.name}.tracker"))
    return out


def array(cfg: DictConfig) -> VirtualArray:
    return array_for(radar(cfg))


def scenes(cfg: DictConfig) -> dict[str, SceneConfig]:
    """{name: SceneConfig} of ``cfg.scene`` in file order."""
    return load_scenes(cfg.scene)


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

    k = evaluation(cfg).kalman
    return KalmanCV(dt=radar(cfg).frame_period_s, process_psd=k.process_psd, meas_std=k.meas_std)


def predictors(cfg: DictConfig, lstm=None) -> dict:
    """The prediction methods of ``cfg.eval.prediction_methods`` by name."""
    from blindspot.traj.baselines import ConstantVelocity

    ev = evaluation(cfg)
    made = {
        "lstm": lstm,
        "constant_velocity": ConstantVelocity(k=ev.cv_fit_points, name="constant_velocity"),
        "kalman": kalman(cfg),
    }
    out = {}
    for name in ev.prediction_methods:
        if name not in made or made[name] is None:
            raise ValueError(f"config key 'eval.prediction_methods' lists {name!r}: expected names "
                             f"from {sorted(k for k, v in made.items() if v is not None)}")
        out[name] = made[name]
    return out
