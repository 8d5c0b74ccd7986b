"""Typed configuration of the detection chain: the Hydra groups ``cfar``, ``doa`` and ``detect``
as frozen dataclasses built through :mod:`blindspot.typed_config` (a bad value raises
:class:`~blindspot.typed_config.ConfigError` naming ``group.key``, the value and the allowed range).

conf/ is the source of truth: every key is required (no defaults that could drift from
``conf/cfar/*.yaml``, ``conf/doa/*.yaml``, ``conf/detect/paper.yaml``). Build them with
``CfarConfig.from_mapping(cfg.cfar)`` etc.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from blindspot.typed_config import ConfigError, TypedConfig, setting

# The choices of the groups, declared here (this module imports no algorithm, so a stage that
# only builds configs does not depend on the algorithms' code) and used by the algorithms.
CFAR_DOMAINS = ("power", "db")            # where a CFAR scale multiplies the training mean
CFAR_MODES = ("ca", "go", "so")           # cell averaging, greatest-of, smallest-of (+ "os")
DOA_METHODS = ("music", "bartlett", "capon")
PEAK_ORDERS = ("spectrum", "power")       # which pseudo-spectrum peak is first (dsp.doa)
WINDOW_NAMES = ("hann", "hamming", "blackman", "blackmanharris", "rect")
SNAPSHOT_MODES = ("cells", "chirps")      # neighbourhood cells, or the range bin across chirps
RANGE_INTERPOLATIONS = ("ipdft", "none")  # sub-bin range of a detection (dsp.subbin), or the bin
POINT_ESTIMATORS = ("median", "strongest", "centroid")  # the body's point from its cluster (dsp.points)

__all__ = ["CfarConfig", "DoaConfig", "DetectConfig"]


@dataclass(frozen=True)
class CfarConfig(TypedConfig):
    """Hydra group ``cfar``. ``method``: ca | go | so | os; exactly one of ``pfa`` / ``scale``;
    ``domain``: power | db (db only with scale); ``n_looks``: integer or "channels" (= n_tx *
    n_rx, the number of |X|^2 terms summed into the map) used by the ``pfa`` factor; ``rank``: OS
    quantile."""

    GROUP = "cfar"

    method: str = setting(choices=CFAR_MODES + ("os",))
    guard: tuple[int, int] = setting(ge=0, le=64, doc="[range, doppler] cells, integers in [0, 64]")
    train: tuple[int, int] = setting(ge=0, le=256,
                                     doc="[range, doppler] cells, integers in [0, 256]")
    pfa: float | None = setting(gt=0.0, le=0.5)
    scale: float | None = setting(gt=0.0, le=1e6)
    domain: str = setting(choices=CFAR_DOMAINS)
    rank: float = setting(gt=0.0, le=1.0)
    n_looks: int | str = setting(ge=1, choices=("channels",))

    def validate(self) -> None:
        broken = threshold_rule(self.pfa, self.scale, self.domain)
        if broken:
            raise ConfigError(*broken)


def threshold_rule(pfa, scale, domain: str) -> tuple[str, Any, str] | None:
    """The CFAR threshold's rule across its settings, or None when it holds: exactly one of
    ``pfa`` / ``scale``, and ``pfa`` only in the power domain (its factor is a square-law
    detector's). Returns ``(key, value, what is allowed)`` of the broken part: one rule, raised
    as a ConfigError by :class:`CfarConfig` and as a CfarError by the functions of
    :mod:`blindspot.dsp.cfar`."""
    if (pfa is None) == (scale is None):
        return "pfa", {"pfa": pfa, "scale": scale}, "exactly one of pfa or scale (the other null)"
    if pfa is not None and domain != "power":
        return "domain", domain, "'power' when pfa is given (dB-domain thresholds need scale)"
    return None


@dataclass(frozen=True)
class DoaConfig(TypedConfig):
    """Hydra group ``doa``: method music | bartlett | capon, n_signals, scan grid
    (grid_deg: [start, stop, step]), forward_backward, subarray (elements, null = none), loading,
    peak_order spectrum | power (:func:`blindspot.dsp.doa.doa_angles`)."""

    GROUP = "doa"

    method: str = setting(choices=DOA_METHODS)
    n_signals: int = setting(ge=1, le=1024)
    grid_deg: tuple[float, float, float] = setting(
        doc="[start, stop, step] degrees within -90..90, at least 3 points")
    forward_backward: bool = setting()
    subarray: int | None = setting(ge=2, le=4096)
    loading: float = setting(ge=0.0, le=1e6)
    peak_order: str = setting(choices=PEAK_ORDERS)

    def validate(self) -> None:
        start, stop, step = self.grid_deg
        if not (-90 <= start < stop <= 90 and 0 < step <= (stop - start) / 2):
            raise ConfigError("grid_deg", list(self.grid_deg),
                              "[start, stop, step] degrees within -90..90, at least 3 points")

    def grid(self) -> np.ndarray:
        start, stop, step = self.grid_deg
        return np.arange(start, stop + step / 2, step)


@dataclass(frozen=True)
class DetectConfig(TypedConfig):
    """Hydra group ``detect``: windows, range window, peak grouping, clutter removal, DOA budget,
    snapshot mode, point grouping. See conf/detect/paper.yaml for the meaning of every key."""

    GROUP = "detect"

    range_window: str = setting(choices=WINDOW_NAMES)
    doppler_window: str = setting(choices=WINDOW_NAMES)
    min_range_m: float = setting(ge=0.0, le=1e4)
    max_range_m: float | None = setting(gt=0.0, le=1e4)
    peak_only: bool = setting()
    min_speed_mps: float = setting(ge=0.0, le=1e3)
    max_detections: int = setting(ge=0, le=100_000)
    snapshots: str = setting(choices=SNAPSHOT_MODES)
    cell_half: tuple[int, int] = setting(ge=0, le=16,
                                         doc="[range, doppler] cells, integers in [0, 16]")
    tdm_compensation: bool = setting()
    cluster_gap_m: float = setting(gt=0.0, le=1e3)
    range_interpolation: str = setting(choices=RANGE_INTERPOLATIONS)
    point_estimator: str = setting(choices=POINT_ESTIMATORS)
    workers: int = setting(ge=1, le=256)

    def validate(self) -> None:
        if self.max_range_m is not None and self.max_range_m <= self.min_range_m:
            raise ConfigError("max_range_m", self.max_range_m,
                              f"null or more than min_range_m = {self.min_range_m}")


# the moving-car chain's peak rule: the detect group's 3 x 3 range-Doppler rule (peak_only), or
# range, Doppler and angle together (blindspot.dsp.detections.angle_peaks)
PEAK_SEARCHES = ("range_doppler", "range_doppler_angle")


@dataclass(frozen=True)
class EgoMotionConfig(TypedConfig):
    """The Hydra group ``ego_motion`` (``conf/ego_motion/default.yaml``): odometry model,
    robust fit, static-world tolerance, the driving chain's detection budget and range, and the
    ego-speed evaluation's frames per speed (:mod:`blindspot.dsp.ego_motion`,
    :mod:`blindspot.dsp.driving`). See the yaml file for the meaning of every key."""

    GROUP = "ego_motion"

    odometry_noise_mps: float = setting(ge=0.0, le=10.0)
    odometry_bias_mps: float = setting(ge=-10.0, le=10.0)
    ransac_threshold_mps: float = setting(gt=0.0, le=10.0)
    min_inliers: int = setting(ge=2, le=10_000)
    static_tolerance_mps: float = setting(ge=0.0, le=10.0)
    max_detections: int = setting(ge=1, le=10_000)
    max_range_m: float = setting(gt=1.0, le=1e4)
    sweep_frames: int = setting(ge=1, le=10_000)
    sweep_yaw_rate_deg_s: float = setting(0.0, ge=-60.0, le=60.0)
    seed: int = setting(0, ge=0, le=2**63 - 1)
    peak_search: str = setting("range_doppler", choices=PEAK_SEARCHES)
    max_candidates: int = setting(256, ge=1, le=100_000)


BRIDGE_METHODS = ("track_gate", "none")


@dataclass(frozen=True)
class BridgeConfig(TypedConfig):
    """Hydra group ``bridge``: points of a target moving across the line of sight, whose radial
    speed the static-clutter filter cannot tell from zero (blindspot.dsp.zero_doppler).
    ``method``: track_gate | none; ``history_s``: points before a gap fitted by a constant
    velocity line; ``max_gap_s``: longest extrapolation; ``gate_m``: gate radius around the
    predicted position; ``margin_mps``: how far above the clutter threshold the predicted radial
    speed may be."""

    GROUP = "bridge"

    method: str = setting(choices=BRIDGE_METHODS)
    history_s: float = setting(gt=0.0, le=60.0)
    max_gap_s: float = setting(gt=0.0, le=60.0)
    gate_m: float = setting(gt=0.0, le=100.0)
    margin_mps: float = setting(ge=0.0, le=100.0)
