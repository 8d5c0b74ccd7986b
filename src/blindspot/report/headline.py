"""The headline metrics: about twenty numbers, from the detailed metrics files, that a table shows.

The detailed files (``reports/metrics/<stage>.json``) hold thousands of numbers each; other code and
checks read them. ``dvc exp show`` and ``dvc metrics diff`` need a few, each one column: so one
flat file, ``reports/metrics/headline.json``, is the pipeline's only DVC ``metrics:`` file, and its
keys are also the headline metrics of the pipeline's MLflow parent run (``headline.<key>``).

Every key is ``(source file, path in it)`` or a mean over the parts of a path (``*``); a key
whose source file (or entry) is absent is left out, so a partly run pipeline still gets a file.
Values are rounded to four significant digits: the table's columns stay narrow, and no run-to-run
float noise below that shows as a change. The order below is the table's column order (DVC
collapses columns from the right when the terminal is narrow, so the most read come first).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

__all__ = ["HEADLINE", "SOURCES", "headline_metrics", "read_sources", "round_sig"]

# key -> (source stage file, dotted path; "*" means the mean over every entry at that level)
HEADLINE: dict[str, tuple[str, str]] = {
    "paper_err_m": ("evaluate", "lstm.path_error_mean_m"),      # the paper's metric (0.09 m)
    "ade_m": ("evaluate", "lstm.ade_m"),
    "fde_m": ("evaluate", "lstm.fde_m"),
    "kalman_ade_m": ("evaluate", "kalman.ade_m"),
    "val_rmse_m": ("train", "lstm.val.rmse_m"),                 # the paper's Table 1 (0.07 m)
    "test_rmse_m": ("train", "lstm.test.rmse_m"),
    "loc_median_m": ("localise", "*.error_median_m"),
    "fill_hidden_m": ("interpolate", "kalman.all_scenes.hidden_mean_m"),
    "walks_ade_m": ("benchmark", "lstm.ade_m.mean"),
    "walks_fde_m": ("benchmark", "lstm.fde_m.mean"),
    "ethucy_ade": ("ethucy", "{best}.avg.ade"),                  # the best ETH/UCY model
    "ethucy_fde": ("ethucy", "{best}.avg.fde"),
    "ethucy_lstm_ade": ("ethucy", "lstm.avg.ade"),
    "cov90": ("calibration", "lstm.sim_paths.coverage_90"),
    "avoided_rate": ("safety", "lstm.avoided_rate"),
    "false_act_rate": ("safety", "lstm.false_activation_rate"),
    "lead_time_s": ("safety", "lstm.lead_time_s_median"),
    "bound_avoided": ("safety_bound", "confirmed_track.avoided_rate"),
    "ego_rms_mps": ("ego_motion", "rms_error_mps.*"),
    "detect_rate": ("driving_measure", "by_speed_kmh.*.detection_rate_visible"),
}
SOURCES: tuple[str, ...] = tuple(dict.fromkeys(src for src, _ in HEADLINE.values()))


def round_sig(value: float, digits: int = 4) -> float:
    """``value`` rounded to ``digits`` significant digits (0 and non-finite values unchanged)."""
    if value == 0 or not math.isfinite(value):
        return float(value)
    return round(float(value), digits - 1 - math.floor(math.log10(abs(value))))


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value) if math.isfinite(value) else None


def _lookup(data: Any, parts: list[str]) -> list[float]:
    """Numbers at the dotted ``parts`` of ``data``; ``*`` walks every entry of a mapping."""
    if not parts:
        number = _number(data)
        return [] if number is None else [number]
    if not isinstance(data, Mapping):
        return []
    head, rest = parts[0], parts[1:]
    if head == "*":
        return [v for item in data.values() for v in _lookup(item, rest)]
    return _lookup(data[head], rest) if head in data else []


def headline_metrics(sources: Mapping[str, Mapping[str, Any] | None]) -> dict[str, float]:
    """The headline keys (in :data:`HEADLINE` order) found in ``sources`` (stage name -> parsed
    metrics file, None when the file is absent); a ``*`` path gives the mean of what it finds."""
    out: dict[str, float] = {}
    for key, (source, path) in HEADLINE.items():
        data = sources.get(source)
        if not data:
            continue
        if "{best}" in path:
            if not isinstance(data.get("best"), str):
                continue
            path = path.replace("{best}", data["best"])
        found = _lookup(data, path.split("."))
        if found:
            out[key] = round_sig(sum(found) / len(found))
    return out


def read_sources(paths: Mapping[str, str | Path]) -> dict[str, dict[str, Any] | None]:
    """Stage name -> its parsed metrics file at ``paths[stage]`` (None when absent)."""
    return {name: json.loads(Path(p).read_text()) if Path(p).is_file() else None
            for name, p in paths.items()}
