"""Typed configuration of the safety room: the Hydra group ``warning``
(``conf/warning/default.yaml``; see the yaml file for the meaning and source of every value).

Build it with ``WarningConfig.from_mapping(cfg.warning)``; a bad value raises
:class:`~blindspot.typed_config.ConfigError` naming ``warning.<key>``, the value and the range.
"""

from __future__ import annotations

from dataclasses import dataclass

from typing import Any

from blindspot.typed_config import ConfigError, TypedConfig, plain, setting

__all__ = ["PREDICTORS", "PROBABILITY_METHODS", "LSTM_HISTORY", "AEB_GATES", "BrakingConfig",
           "OracleConfig", "WarningConfig", "MOVED_KEYS"]

PREDICTORS: tuple[str, ...] = ("none", "constant_velocity", "kalman", "lstm", "lstm_direct",
                                "track_state")
PROBABILITY_METHODS: tuple[str, ...] = ("max_step", "union")
LSTM_HISTORY: tuple[str, ...] = ("cv_backfill", "hold_first")
AEB_GATES: tuple[str, ...] = ("none", "stopping_time")


@dataclass(frozen=True)
class BrakingConfig(TypedConfig):
    """AEB actuation: ``latency_s`` from the request to the first brake pressure, a ramp at
    ``jerk_mps3`` to ``decel_mps2``, then held to standstill."""

    GROUP = "warning.aeb"

    latency_s: float = setting(ge=0.0, le=5.0)
    jerk_mps3: float = setting(gt=0.0, le=1000.0)
    decel_mps2: float = setting(gt=0.0, le=20.0)


@dataclass(frozen=True)
class OracleConfig(TypedConfig):
    """The oracle-association reference tracks (:mod:`blindspot.safety.oracle`)."""

    GROUP = "warning.oracle"

    process_psd: float = setting(gt=0.0, le=100.0)
    meas_std_m: float = setting(gt=0.0, le=10.0)
    init_vel_std_mps: float = setting(gt=0.0, le=100.0)
    confirm_points: int = setting(ge=1, le=100)
    max_coast_frames: int = setting(ge=0, le=1000)


#: Keys that left the warning group (issue 42): the moving-object test classes tracks, so its
#: settings are the tracker's, ``warning.moving_<x>`` -> ``tracker.moving.<x>``.
MOVED_KEYS: dict[str, str] = {
    f"moving_{k}": f"tracker.moving.{k}"
    for k in ("speed_mps", "probability", "doppler_std_mps", "doppler_log_ratio_min",
              "doppler_llr", "doppler_log_ratio_floor", "doppler_spread_std_mps",
              "doppler_reference", "static_evidence_min", "static_cell_m", "static_lag_frames")}


@dataclass(frozen=True)
class WarningConfig(TypedConfig):
    """The Hydra group ``warning``: predictors, risk, warning/AEB thresholds, AEB model,
    outcome grid, statistics. See ``conf/warning/default.yaml``."""

    GROUP = "warning"

    predictors: tuple[str, ...] = setting(choices=PREDICTORS, min_items=1)
    reference_predictors: tuple[str, ...] = setting(choices=PREDICTORS, min_items=1)
    horizon_s: float = setting(gt=0.0, le=10.0)
    pedestrian_radius_m: float = setting(ge=0.0, le=2.0)
    probability: str = setting(choices=PROBABILITY_METHODS)
    lstm_history: str = setting(choices=LSTM_HISTORY)
    max_history_s: float = setting(gt=0.0, le=60.0)
    warning_threshold: float = setting(gt=0.0, lt=1.0)
    aeb_threshold: float = setting(gt=0.0, lt=1.0)
    decision_delay_s: float = setting(ge=0.0, le=2.0)
    aeb: BrakingConfig = setting()
    sensitivity_decel_mps2: float = setting(gt=0.0, le=20.0)
    outcome_dt_s: float = setting(gt=0.0, le=0.1)
    extend_s: float = setting(ge=0.0, le=30.0)
    n_thresholds: int = setting(ge=2, le=10_000)
    n_bootstrap: int = setting(ge=100, le=1_000_000)
    oracle: OracleConfig = setting()
    aeb_gate: str = setting("none", choices=AEB_GATES)
    aeb_gate_margin_s: float = setting(0.0, ge=0.0, le=5.0)
    max_coast_s: float | None = setting(None, ge=0.0, le=60.0)
    false_activation_target: float = setting(0.03, gt=0.0, lt=1.0)
    tail_thresholds: tuple[float, ...] = setting((), gt=0.0, lt=1.0)
    seed: int = setting(0, ge=0, le=2**63 - 1)

    @classmethod
    def from_mapping(cls, mapping: Any, where: str | None = None) -> "WarningConfig":
        """As :meth:`TypedConfig.from_mapping`; a key of :data:`MOVED_KEYS` raises
        :class:`ConfigError` naming its new key."""
        m = plain(mapping)
        if isinstance(m, dict):
            for key in m:
                if key in MOVED_KEYS:
                    raise ConfigError(key, m[key], f"nothing: the key moved to "
                                      f"{MOVED_KEYS[key]} (issue 42); set it there").under(
                                          where or cls.GROUP)
        return super().from_mapping(m, where)

    def validate(self) -> None:
        extra = sorted(set(self.reference_predictors) - set(self.predictors))
        if extra:
            raise ConfigError("reference_predictors", list(self.reference_predictors),
                              f"a subset of warning.predictors {list(self.predictors)}")
        if len(set(self.predictors)) != len(self.predictors):
            raise ConfigError("predictors", list(self.predictors),
                              "each predictor named once")
        if self.warning_threshold > self.aeb_threshold:
            raise ConfigError("warning_threshold", self.warning_threshold,
                              f"at most warning.aeb_threshold = {self.aeb_threshold} (the warning "
                              "comes before or with the AEB request)")
