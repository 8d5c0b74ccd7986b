"""Typed config of the multi-target tracker: the Hydra group ``tracker`` (``conf/tracker/``).

Built through :mod:`blindspot.typed_config`, so a bad value raises
:class:`~blindspot.typed_config.ConfigError` naming ``tracker.<key>``, the value and the allowed
range. The yaml files give the source or the reason of every value.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np

from blindspot.track.moving import DOPPLER_LLR_FORMS, DOPPLER_REFERENCES
from blindspot.typed_config import ConfigError, TypedConfig, setting

__all__ = ["ASSOCIATIONS", "MovingConfig", "TrackerConfig"]

#: Data associators: global nearest neighbour (one detection per track, 2-D assignment) or joint
#: probabilistic data association (every gated detection weighted by its probability).
ASSOCIATIONS = ("gnn", "jpda")


@dataclass(frozen=True)
class MovingConfig(TypedConfig):
    """The moving-object test (``tracker.moving``; :func:`blindspot.track.moving.moving_tracks`,
    its keyword arguments from :func:`blindspot.track.moving.moving_test_settings`): which
    confirmed tracks are moving objects. Until issue 42 these were the ``warning.moving_*``
    keys; ``conf/tracker/gnn_cv.yaml`` gives the meaning and source of each.

    Fields: speed_mps, probability (the kinematic test); doppler_std_mps,
    doppler_log_ratio_min, doppler_llr, doppler_log_ratio_floor, doppler_spread_std_mps,
    doppler_reference (the Doppler refutation); static_evidence_min, static_cell_m,
    static_lag_frames (the static evidence grid), static_exempt_log_ratio (a row whose track's
    own radial speeds make "moving" this many natural-log units likelier than "static" is not
    held back by the grid; null: the grid holds back every row on it); doppler_first_log_ratio
    (the Doppler-first path: a confirmed track whose own radial speeds make "moving" this many
    natural-log units likelier than "static" is moving without waiting for the kinematic
    test; null: off);
    crossing_log_ratio (the crossing prior: a confirmed track whose first radial speeds make
    "stepping toward the ego's path" this many natural-log units likelier than "static" is
    moving; null: off) and its hypothesis, crossing_speed_mps, crossing_speed_std_mps,
    crossing_walker_std_mps, crossing_static_std_mps, crossing_window, crossing_corridor_m
    (:class:`blindspot.track.crossing.CrossingPrior`; the corridor bounds the approach test
    too); approach_probability (the approach test: a velocity whose component toward the
    ego's path passes a one-sided test at this probability is significant,
    :func:`blindspot.track.crossing.approach_z`; null: off).
    """

    GROUP = "tracker.moving"

    speed_mps: float = setting(ge=0.0, le=10.0)
    probability: float = setting(gt=0.0, lt=1.0)
    doppler_std_mps: float = setting(gt=0.0, le=10.0)
    doppler_log_ratio_min: float = setting(ge=-1000.0, le=0.0)
    doppler_llr: str = setting("common_variance", choices=DOPPLER_LLR_FORMS)
    doppler_log_ratio_floor: float | None = setting(None, ge=-1000.0, le=0.0)
    doppler_spread_std_mps: tuple[float, float] | None = setting(None, gt=0.0, le=10.0,
                                                                 ordered=True)
    doppler_reference: str = setting("frame", choices=DOPPLER_REFERENCES)
    static_evidence_min: int = setting(0, ge=0, le=1_000_000)
    static_cell_m: float = setting(0.5, gt=0.0, le=10.0)
    static_lag_frames: int = setting(10, ge=1, le=10_000)
    static_exempt_log_ratio: float | None = setting(None, gt=0.0, le=1000.0)
    doppler_first_log_ratio: float | None = setting(None, gt=0.0, le=1000.0)
    crossing_log_ratio: float | None = setting(None, gt=0.0, le=1000.0)
    crossing_speed_mps: float = setting(1.4, gt=0.0, le=10.0)
    crossing_speed_std_mps: float = setting(0.5, gt=0.0, le=10.0)
    crossing_walker_std_mps: float = setting(0.35, gt=0.0, le=10.0)
    crossing_static_std_mps: float = setting(0.15, gt=0.0, le=10.0)
    crossing_window: int = setting(3, ge=1, le=1000)
    crossing_corridor_m: float = setting(5.0, gt=0.0, le=100.0)
    approach_probability: float | None = setting(None, gt=0.0, lt=1.0)

    def validate(self) -> None:
        spread = self.doppler_spread_std_mps
        if spread is not None and not spread[0] < spread[1]:
            raise ConfigError("doppler_spread_std_mps", list(spread),
                              "[static, walker] with static < walker (the walker hypothesis "
                              "spreads its points' Doppler wider than a static object), or null")
        floor = self.doppler_log_ratio_floor
        if floor is not None and floor > self.doppler_log_ratio_min:
            raise ConfigError("doppler_log_ratio_floor", floor,
                              "at most tracker.moving.doppler_log_ratio_min = "
                              f"{self.doppler_log_ratio_min} (a floor above the bound "
                              "would never let the Doppler test refute a track), or null")


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
        velocity_damping_per_s: K of an Ornstein-Uhlenbeck velocity (Stone Soup's
            ``OrnsteinUhlenbeck``): a coasting track's velocity decays as exp(-K t); 0 = constant
            velocity.
        measurement_noise_m: standard deviation of one object's position (cluster centroid) per
            axis (m).
        init_velocity_std_mps: prior standard deviation of a new track's velocity per axis (its
            mean is zero).
        gate_probability: probability that the true object's measurement falls inside the
            Mahalanobis gate; the gate is the chi-square quantile with 2 degrees of freedom.
        association: ``gnn`` or ``jpda`` (see :data:`ASSOCIATIONS`).
        detection_probability: P_D of an object in a frame (JPDA's hypothesis weights; with a
            sensor's Doppler notch, the miss likelihood of the negative information,
            :func:`blindspot.track.stopped.notch_update`).
        clutter_density_per_m2: spatial density of false objects per frame (JPDA).
        confirm_m, confirm_n: a tentative track is confirmed once it has been updated with a
            measurement in ``confirm_m`` of its last ``confirm_n`` frames, and deleted when its
            first ``confirm_n`` frames cannot give that (M-of-N logic; Blackman & Popoli 1999,
            sec. 6.3).
        priority_max_coast_frames: a confirmed track is associated first (before the
            tentative tracks, with their detections out of reach) only while it has missed at
            most this many frames in a row (counted in time at the median frame period, as
            ``max_misses``); a confirmed track silent for longer competes jointly with the
            tentative ones in the second stage (GNN: one min-sum assignment on Mahalanobis
            distance), so a fresh track sitting on a detection can keep it (a parked car's edge
            track coasting 8 frames took a child's first points 1.45 m off, Euro NCAP CPNCO 20
            km/h); null: every confirmed track first. GNN only.
        max_misses: a confirmed track is deleted once silent (no measurement) for longer than
            this many frames take, the time they span at the recording's median frame period,
            whether the silence comes as frames without points or as no frames at all; until
            then it coasts (predicted only).
        max_stop_s: the longest a track stopped in a sensor's Doppler notch
            (:mod:`blindspot.track.stopped`) is held without a detection after its coasting
            time (s); then it is deleted.
        count_period_s: the frame period (s) at which ``confirm_m``, ``confirm_n``,
            ``max_misses`` and ``priority_max_coast_frames`` are counted; a group of points at
            another median frame period gets the same times (:meth:`counts_at`), so a
            20-frames/s recording confirms on 6 of 10 frames where a 10-frames/s one takes 3 of
            5; null: the counts are frames at any rate.
        doppler_std_mps: the spread of one point's ego-motion-compensated radial speed (m/s);
            set, the GNN gate and assignment cost take each object's median radial speed
            against the one the track's predicted velocity gives along the line of sight (a
            third, Doppler dimension of the Mahalanobis distance, gated at the tail probability
            of ``gate_probability``), where the points carry ``velocity_over_ground_mps``; null
            gates on position alone.
        field_of_view_deg: the sensor's azimuth field of view, full width (deg); a track that
            coasts (no detection updated it this frame: its row's ``coasting``) to a bearing
            outside it, more than half of it off the sensor's boresight, is deleted there,
            since no detection can update it; 360 deletes nothing
            (:data:`blindspot.track.tracker.SENSOR_COLUMNS` and ``SENSOR_HEADING_COLUMN`` give
            the sensor's pose per frame; points without the heading column are not tested:
            recordings differ in the axis their sensor looks along); null keeps such tracks
            until ``max_misses``.
        init_doppler_std_mps: the spread of one point's ego-motion-compensated radial speed
            (m/s) with which a new track's velocity prior is updated by its first object's
            Doppler (blindspot.track.tracker._linear_initiator: the velocity the Doppler and the
            geometry allow, not zero); null: zero-mean start (issue 40).
        init_doppler_along_std_mps: the prior standard deviation of that velocity along the
            sensor's boresight (the road, for a car's radar; ``init_velocity_std_mps`` across
            it): a pedestrian stepping out crosses the road; null: isotropic.
        doppler_confirm_log_ratio: a tentative track confirms on its second consecutive hit
            when its objects' radial speeds make "moving" this many natural-log units likelier
            than "static" (blindspot.track.moving.doppler_motion_log_ratio, point spread
            ``moving.doppler_std_mps``); null: M-of-N only.
        doppler_update_std_mps: the spread of one point's ego-motion-compensated radial speed
            about its object's (m/s) with which every hit's Doppler updates the track's velocity
            after its position (a range-rate measurement, d = u.v + e, e ~ N(0, sd^2 / n); blindspot
            .track.tracker._range_rate_update): a walker turning along the kerb shows it in the
            next frame's radial speed, where positions need several frames; null: positions only.
        moving: the moving-object test (:class:`MovingConfig`); null for recordings that need
            none.
    """

    GROUP = "tracker"
    IGNORED = ("name",)

    cluster_eps_m: float = setting(gt=0.0, le=100.0)
    cluster_min_samples: int = setting(ge=1, le=10_000)
    process_noise_m2ps3: float = setting(gt=0.0, le=1e4)
    velocity_damping_per_s: float = setting(ge=0.0, le=1e3)
    measurement_noise_m: float = setting(gt=0.0, le=100.0)
    init_velocity_std_mps: float = setting(gt=0.0, le=100.0)
    gate_probability: float = setting(gt=0.0, lt=1.0)
    association: str = setting(choices=ASSOCIATIONS)
    detection_probability: float = setting(gt=0.0, lt=1.0)
    clutter_density_per_m2: float = setting(gt=0.0, le=1e6)
    confirm_m: int = setting(ge=1, le=1000)
    confirm_n: int = setting(ge=1, le=1000)
    max_misses: int = setting(ge=0, le=100_000)
    priority_max_coast_frames: int | None = setting(None, ge=0, le=100_000)
    count_period_s: float | None = setting(None, gt=0.0, le=60.0)
    max_stop_s: float = setting(25.0, gt=0.0, le=3600.0)
    doppler_std_mps: float | None = setting(None, gt=0.0, le=100.0)
    field_of_view_deg: float | None = setting(None, gt=0.0, le=360.0)
    init_doppler_std_mps: float | None = setting(None, gt=0.0, le=100.0)
    init_doppler_along_std_mps: float | None = setting(None, gt=0.0, le=100.0)
    doppler_confirm_log_ratio: float | None = setting(None, gt=0.0, le=1000.0)
    doppler_update_std_mps: float | None = setting(None, gt=0.0, le=100.0)
    moving: MovingConfig | None = setting(None)

    def validate(self) -> None:
        if self.confirm_m > self.confirm_n:
            raise ConfigError("confirm_m", self.confirm_m,
                              f"at most confirm_n = {self.confirm_n} (M of N frames)")
        if self.priority_max_coast_frames is not None and self.association != "gnn":
            raise ConfigError("priority_max_coast_frames", self.priority_max_coast_frames,
                              "null with association jpda (JPDA's second stage marks only each "
                              "track's best detection used, so a demoted confirmed track "
                              "would let its other detections start tracks beside it)")
        if self.doppler_std_mps is not None and self.association != "gnn":
            raise ConfigError("doppler_std_mps", self.doppler_std_mps,
                              "null with association jpda (the Doppler gate is GNN's)")

    def counts_at(self, period_s: float) -> tuple[int, int, int, int | None]:
        """(confirm_m, confirm_n, max_misses, priority_max_coast_frames) for frames of
        ``period_s`` seconds: with ``count_period_s`` each count scaled by count_period_s /
        period_s to the nearest frame, halves up (N at least one; M rounded up, so the hit
        fraction does not fall below M / N); unchanged without it, or at that period (to 1e-9).
        At periods of count_period_s * N or longer a track confirms on one hit."""
        if (isinstance(period_s, (bool, np.bool_)) or not isinstance(period_s, numbers.Real)
                or not period_s > 0):
            raise ValueError(f"TrackerConfig.counts_at: period_s must be a positive frame "
                             f"period (s; inf for a single frame); found {period_s!r}")
        m, n, k = self.confirm_m, self.confirm_n, self.priority_max_coast_frames
        scale = (1.0 if self.count_period_s is None or not np.isfinite(period_s)
                 else self.count_period_s / float(period_s))
        if abs(scale - 1.0) <= 1e-9:
            return m, n, self.max_misses, k
        def nearest(count: float) -> int:
            return int(np.floor(count + 0.5))

        n_s = max(1, nearest(n * scale))
        m_s = min(n_s, max(1, int(np.ceil(m * n_s / n - 1e-9))))
        return (m_s, n_s, nearest(self.max_misses * scale),
                None if k is None else nearest(k * scale))


#: Point-cloud log formats the real_tracking stage reads (blindspot.radar.capture).
RECORDING_KINDS = ("ti_gtrack", "radhar")


@dataclass(frozen=True)
class TrackedRecording(TypedConfig):
    """One real recording of the Hydra group ``real_tracking`` (``conf/real_tracking/``).

    Fields:
        name: the recording's key (output names: ``data/tracks/<name>.parquet``).
        kind: ``ti_gtrack`` (TI people-counting TLV log with gtrack targets) or ``radhar``
            (RadHAR ROS text dump).
        path: the file, relative to ``paths.shared_dir`` or absolute.
        frame_period_s: frame period (s) when the file holds no time stamps (ti_gtrack); null
            to use the file's own stamps (radhar).
        static_speed_mps: points with |radial speed| at most this are static clutter and are
            dropped before tracking; null keeps every point.
        min_detectable_speed_mps: the recording's Doppler notch (m/s): it holds no point with a
            radial speed below this (static clutter removed on the sensor, or by
            ``static_speed_mps``); the tracker holds a track that goes silent there as a
            stopped target (:func:`blindspot.track.track_points`); null: no notch.
        boundary_box_m: the scene's walls [x_min, x_max, y_min, y_max] (m, the sensor frame);
            points beyond them are reflections from behind a wall and are dropped before
            tracking (TI's gtrack "boundary box"); null: no walls.
        reference_gate_m: the largest distance (m) at which one of our tracks may stand for a
            reference track (CLEAR MOT); null when the recording has no reference tracker.

    The record's ``tracker`` mapping (keys of the ``tracker`` group) overrides the tracker
    group for this recording; :func:`tracked_recordings` merges and types it.
    """

    IGNORED = ("tracker",)

    name: str = setting()
    kind: str = setting(choices=RECORDING_KINDS)
    path: str = setting()
    frame_period_s: float | None = setting(None, gt=0.0, le=60.0)
    static_speed_mps: float | None = setting(None, ge=0.0, le=100.0)
    min_detectable_speed_mps: float | None = setting(None, gt=0.0, le=100.0)
    boundary_box_m: tuple[float, float, float, float] | None = setting(None, ge=-1000.0,
                                                                         le=1000.0)
    reference_gate_m: float | None = setting(None, gt=0.0, le=100.0)

    def validate(self) -> None:
        if self.kind == "ti_gtrack" and self.frame_period_s is None:
            raise ConfigError("frame_period_s", None,
                              "a positive period (s): a ti_gtrack log holds no time stamps")
        if not self.path:
            raise ConfigError("path", self.path, "a file path")
        box = self.boundary_box_m
        if box is not None and not (box[0] < box[1] and box[2] < box[3]):
            raise ConfigError("boundary_box_m", list(box),
                              "[x_min, x_max, y_min, y_max] with x_min < x_max and y_min < y_max")


@dataclass(frozen=True)
class RealTrackingConfig(TypedConfig):
    """The Hydra group ``real_tracking``: the real point-cloud recordings the tracker runs on
    (``recordings``: a mapping of :class:`TrackedRecording` by name)."""

    GROUP = "real_tracking"
    IGNORED = ("name",)

    recordings: tuple[TrackedRecording, ...] = setting(min_items=1)


def tracked_recordings(cfg) -> dict:
    """The real recordings of ``cfg.real_tracking`` (the composed config), each with its tracker
    settings: the ``tracker`` group with the record's ``tracker`` keys laid over it (errors name
    ``real_tracking.recordings.<name>.tracker.<key>``): ``{name: (TrackedRecording,
    TrackerConfig)}``."""
    from omegaconf import OmegaConf

    group = RealTrackingConfig.from_cfg(cfg)
    TrackerConfig.from_cfg(cfg)  # a bad tracker-group value is named tracker.<key>
    out = {}
    for rec in group.recordings:
        overrides = cfg.real_tracking["recordings"][rec.name].get("tracker") or {}
        merged = OmegaConf.merge(cfg.tracker, overrides)
        out[rec.name] = (rec, TrackerConfig.from_mapping(
            merged, where=f"real_tracking.recordings.{rec.name}.tracker"))
    return out
