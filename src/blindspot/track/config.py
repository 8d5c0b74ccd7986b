"""Typed config of the multi-target tracker: the Hydra group ``tracker`` (``conf/tracker/``).

Built through :mod:`blindspot.typed_config`, so a bad value raises
:class:`~blindspot.typed_config.ConfigError` naming ``tracker.<key>``, the value and the allowed
range. The yaml files give the source or the reason of every value.
"""

from __future__ import annotations

from dataclasses import dataclass

from blindspot.typed_config import ConfigError, TypedConfig, setting

__all__ = ["ASSOCIATIONS", "TrackerConfig"]

#: Data associators: global nearest neighbour (one detection per track, 2-D assignment) or joint
#: probabilistic data association (every gated detection weighted by its probability).
ASSOCIATIONS = ("gnn", "jpda")


@dataclass(frozen=True)
class TrackerConfig(TypedConfig):
    """The Hydra group ``tracker``: clustering, filter, gating, association, track management.

    Fields (units in the names):
        cluster_eps_m: DBSCAN neighbourhood radius; points of one frame closer than this (chained)
            form one object (Ester et al. 1996).
        cluster_min_samples: DBSCAN core-point count; an isolated point with fewer neighbours is
            noise and never reaches the tracker (1 = every point is an object).
        process_noise_m2ps3: spectral density q of the white-noise acceleration of the constant
            velocity model, per axis (m^2/s^3; Bar-Shalom, Li & Kirubarajan 2001, sec. 6.2).
        measurement_noise_m: standard deviation of one object's position (cluster centroid) per
            axis (m).
        init_velocity_std_mps: prior standard deviation of a new track's velocity per axis (its
            mean is zero).
        gate_probability: probability that the true object's measurement falls inside the
            Mahalanobis gate; the gate is the chi-square quantile with 2 degrees of freedom.
        association: ``gnn`` or ``jpda`` (see :data:`ASSOCIATIONS`).
        detection_probability: P_D of an object in a frame (JPDA's hypothesis weights).
        clutter_density_per_m2: spatial density of false objects per frame (JPDA).
        confirm_m, confirm_n: a tentative track is confirmed once it has been updated with a
            measurement in ``confirm_m`` of its last ``confirm_n`` frames, and deleted when its
            first ``confirm_n`` frames cannot give that (M-of-N logic; Blackman & Popoli 1999,
            sec. 6.3).
        max_misses: a confirmed track is deleted after this many consecutive frames without a
            measurement; until then it coasts (predicted only).
    """

    GROUP = "tracker"
    IGNORED = ("name",)

    cluster_eps_m: float = setting(gt=0.0, le=100.0)
    cluster_min_samples: int = setting(ge=1, le=10_000)
    process_noise_m2ps3: float = setting(gt=0.0, le=1e4)
    measurement_noise_m: float = setting(gt=0.0, le=100.0)
    init_velocity_std_mps: float = setting(gt=0.0, le=100.0)
    gate_probability: float = setting(gt=0.0, lt=1.0)
    association: str = setting(choices=ASSOCIATIONS)
    detection_probability: float = setting(gt=0.0, lt=1.0)
    clutter_density_per_m2: float = setting(gt=0.0, le=1e6)
    confirm_m: int = setting(ge=1, le=1000)
    confirm_n: int = setting(ge=1, le=1000)
    max_misses: int = setting(ge=0, le=100_000)

    def validate(self) -> None:
        if self.confirm_m > self.confirm_n:
            raise ConfigError("confirm_m", self.confirm_m,
                              f"at most confirm_n = {self.confirm_n} (M of N frames)")
