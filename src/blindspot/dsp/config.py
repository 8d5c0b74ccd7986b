"""Typed configuration of the detection chain: the Hydra groups ``cfar``, ``doa`` and ``detect``
as frozen dataclasses, validated on construction (a bad value raises
:class:`~blindspot.radar.config.ConfigError` naming ``group.key``, the value and the allowed range).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from blindspot.dsp.cfar import DOMAINS, MODES
from blindspot.dsp.doa import METHODS
from blindspot.dsp.range_doppler import WINDOW_NAMES
from blindspot.dsp.snapshots import SNAPSHOT_MODES
from blindspot.radar.config import ConfigError

__all__ = ["CfarConfig", "DoaConfig", "DetectConfig"]

def _plain(mapping: Any, where: str) -> dict[str, Any]:
    if mapping is None:
        return {}
    try:
        from omegaconf import DictConfig, OmegaConf

        if isinstance(mapping, DictConfig):
            return dict(OmegaConf.to_container(mapping, resolve=True))  # type: ignore[arg-type]
    except ImportError:  # pragma: no cover
        pass
    if not isinstance(mapping, Mapping):
        raise ConfigError(where, mapping, "a mapping of keys")
    return dict(mapping)


class _Reader:
    """Reads keys of one config group, validating and naming ``group.key`` in errors."""

    def __init__(self, mapping: Any, where: str, known: Iterable[str]):
        self.m, self.where = _plain(mapping, where), where
        unknown = sorted(set(self.m) - set(known))
        if unknown:
            raise ConfigError(f"{where}.{unknown[0]}", self.m[unknown[0]],
                              f"one of the keys {sorted(known)}")

    def get(self, key: str, default: Any) -> Any:
        return self.m.get(key, default)

    def fail(self, key: str, allowed: str):
        raise ConfigError(f"{self.where}.{key}", self.m.get(key), allowed)

    def choice(self, key: str, default: str, allowed: Iterable[str]) -> str:
        v = self.get(key, default)
        if v not in tuple(allowed):
            self.fail(key, f"one of {tuple(allowed)}")
        return v

    def number(self, key: str, default: float | None, lo: float, hi: float,
               optional: bool = False, open_lo: bool = False) -> float | None:
        v = self.get(key, default)
        if v is None and optional:
            return None
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) \
            and (lo < v if open_lo else lo <= v) and v <= hi
        if not ok:
            self.fail(key, f"a number in {'(' if open_lo else '['}{lo:g}, {hi:g}]"
                      + (" or null" if optional else ""))
        return float(v)

    def integer(self, key: str, default: int | None, lo: int, hi: int,
                optional: bool = False) -> int | None:
        v = self.get(key, default)
        if v is None and optional:
            return None
        if not (isinstance(v, int) and not isinstance(v, bool) and lo <= v <= hi):
            self.fail(key, f"an integer in [{lo}, {hi}]" + (" or null" if optional else ""))
        return int(v)

    def pair(self, key: str, default: tuple[int, int], hi: int) -> tuple[int, int]:
        v = self.get(key, default)
        if isinstance(v, int) and not isinstance(v, bool):
            v = (v, v)
        if not (isinstance(v, (list, tuple)) and len(v) == 2
                and all(isinstance(i, int) and not isinstance(i, bool) and 0 <= i <= hi
                        for i in v)):
            self.fail(key, f"[range, doppler] cells, integers in [0, {hi}]")
        return int(v[0]), int(v[1])

    def boolean(self, key: str, default: bool) -> bool:
        v = self.get(key, default)
        if not isinstance(v, bool):
            self.fail(key, "true or false")
        return v


@dataclass(frozen=True)
class CfarConfig:
    """Hydra group ``cfar``. ``method``: ca | go | so | os; exactly one of ``pfa`` / ``scale``;
    ``domain``: power | db (db only with scale); ``n_looks``: integer or "channels" (= n_tx *
    n_rx, the number of |X|^2 terms summed into the map) used by the ``pfa`` factor; ``rank``: OS
    quantile."""

    method: str = "ca"
    guard: tuple[int, int] = (2, 2)
    train: tuple[int, int] = (8, 4)
    pfa: float | None = None
    scale: float | None = None
    domain: str = "power"
    rank: float = 0.75
    n_looks: int | str = 1

    @classmethod
    def from_mapping(cls, mapping: Any, where: str = "cfar") -> CfarConfig:
        r = _Reader(mapping, where, cls.__dataclass_fields__)
        method = r.choice("method", "ca", MODES + ("os",))
        pfa = r.number("pfa", None, 0.0, 0.5, optional=True, open_lo=True)
        scale = r.number("scale", None, 0.0, 1e6, optional=True, open_lo=True)
        if (pfa is None) == (scale is None):
            raise ConfigError(f"{where}.pfa", {"pfa": pfa, "scale": scale},
                              "exactly one of pfa or scale (the other null)")
        domain = r.choice("domain", "power", DOMAINS)
        if pfa is not None and domain != "power":
            r.fail("domain", "'power' when pfa is given (dB-domain thresholds need scale)")
        looks = r.get("n_looks", 1)
        if not (looks == "channels" or (isinstance(looks, int) and not isinstance(looks, bool)
                                        and looks >= 1)):
            r.fail("n_looks", "a positive integer or 'channels'")
        return cls(method=method, guard=r.pair("guard", (2, 2), 64),
                   train=r.pair("train", (8, 4), 256), pfa=pfa, scale=scale, domain=domain,
                   rank=r.number("rank", 0.75, 0.0, 1.0, open_lo=True), n_looks=looks)


@dataclass(frozen=True)
class DoaConfig:
    """Hydra group ``doa``: method music | bartlett | capon, n_signals, scan grid
    (grid_deg: [start, stop, step]), forward_backward, subarray (elements, null = none), loading."""

    method: str = "music"
    n_signals: int = 3
    grid_deg: tuple[float, float, float] = (-90.0, 90.0, 0.25)
    forward_backward: bool = True
    subarray: int | None = 64
    loading: float = 0.0

    @classmethod
    def from_mapping(cls, mapping: Any, where: str = "doa") -> DoaConfig:
        r = _Reader(mapping, where, cls.__dataclass_fields__)
        grid = r.get("grid_deg", [-90.0, 90.0, 0.25])
        if not (isinstance(grid, (list, tuple)) and len(grid) == 3
                and all(isinstance(g, (int, float)) for g in grid)
                and -90 <= grid[0] < grid[1] <= 90 and 0 < grid[2] <= (grid[1] - grid[0]) / 2):
            r.fail("grid_deg", "[start, stop, step] degrees within -90..90, at least 3 points")
        return cls(method=r.choice("method", "music", METHODS),
                   n_signals=r.integer("n_signals", 3, 1, 1024),
                   grid_deg=tuple(float(g) for g in grid),  # type: ignore[arg-type]
                   forward_backward=r.boolean("forward_backward", True),
                   subarray=r.integer("subarray", 64, 2, 4096, optional=True),
                   loading=r.number("loading", 0.0, 0.0, 1e6))

    def grid(self) -> np.ndarray:
        start, stop, step = self.grid_deg
        return np.arange(start, stop + step / 2, step)


@dataclass(frozen=True)
class DetectConfig:
    """Hydra group ``detect``: windows, range window, peak grouping, clutter removal, DOA budget,
    snapshot mode, point grouping. See conf/detect/paper.yaml for the meaning of every key."""

    range_window: str = "hann"
    doppler_window: str = "hann"
    min_range_m: float = 1.0
    max_range_m: float | None = None
    peak_only: bool = True
    min_speed_mps: float = 0.11
    max_detections: int = 10
    snapshots: str = "cells"
    cell_half: tuple[int, int] = (1, 1)
    tdm_compensation: bool = True
    cluster_gap_m: float = 1.0
    workers: int = 1

    @classmethod
    def from_mapping(cls, mapping: Any, where: str = "detect") -> DetectConfig:
        r = _Reader(mapping, where, cls.__dataclass_fields__)
        out = cls(
            range_window=r.choice("range_window", "hann", WINDOW_NAMES),
            doppler_window=r.choice("doppler_window", "hann", WINDOW_NAMES),
            min_range_m=r.number("min_range_m", 1.0, 0.0, 1e4),
            max_range_m=r.number("max_range_m", None, 0.0, 1e4, optional=True, open_lo=True),
            peak_only=r.boolean("peak_only", True),
            min_speed_mps=r.number("min_speed_mps", 0.11, 0.0, 1e3),
            max_detections=r.integer("max_detections", 10, 0, 100_000),
            snapshots=r.choice("snapshots", "cells", SNAPSHOT_MODES),
            cell_half=r.pair("cell_half", (1, 1), 16),
            tdm_compensation=r.boolean("tdm_compensation", True),
            cluster_gap_m=r.number("cluster_gap_m", 1.0, 0.0, 1e3, open_lo=True),
            workers=r.integer("workers", 1, 1, 256),
        )
        if out.max_range_m is not None and out.max_range_m <= out.min_range_m:
            r.fail("max_range_m", f"null or more than min_range_m = {out.min_range_m}")
        return out
