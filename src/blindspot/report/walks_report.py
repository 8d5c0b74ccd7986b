"""The many-walk benchmark's figure and table, from ``reports/metrics/benchmark.json`` and
``reports/metrics/benchmark_paired.json``.

Pure: the two JSON files written by the ``benchmark`` stage, merged, in (``{"n_walks": N,
method: {metric: {"mean", "ci95": [lo, hi], "n"}}, "paired": {"a - b": {metric: {...}}},
"lstm_members": {...}}``), a figure / Markdown out; nothing is computed here but the layout.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from blindspot.report.online_label import online_setting_label
from blindspot.report.style import method_colour, method_label, new_grid, panel_title

__all__ = ["benchmark_figure", "benchmark_table", "benchmark_methods", "PREDICTION_METRICS"]

PREDICTION_METRICS = ("path_error_mean_m", "path_error_first_m", "ade_0.5s", "fde_0.5s",
                      "ade_1s", "fde_1s", "ade_2s", "fde_2s")
_NAMES = {"path_error_mean_m": "paper's metric", "path_error_first_m": "paper's metric, 1st point",
          "hidden_mean_m": "hidden frames", "coverage_50": "50 % ellipse",
          "coverage_90": "90 % ellipse", "coverage_95": "95 % ellipse", "nll": "NLL (nats)"}


def _fmt(entry: Mapping[str, Any] | None, digits: int = 3) -> str:
    if not entry or entry.get("mean") is None or not np.isfinite(entry["mean"]):
        return "-"
    lo, hi = entry["ci95"]
    return f"{entry['mean']:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}]"


def benchmark_methods(metrics: Mapping[str, Any]) -> tuple[list[str], list[str]]:
    """(prediction methods, fill methods) of a benchmark.json: every top-level key whose value is
    a mapping of metrics, except ``paired``, the seed-ensemble members (``lstm_member<i>``) and
    their summary (``lstm_members``), which have their own table, and ``online_setting``;
    fills are the ``fill_<method>`` keys. Both lists keep the file's order."""
    keys = [k for k, v in metrics.items() if isinstance(v, Mapping)
            and k not in ("paired", "lstm_members", "online_setting")
            and not k.startswith("lstm_member")]
    fills = [k for k in keys if k.startswith("fill_")]
    return [k for k in keys if k not in fills], fills


def _members(metrics: Mapping[str, Any]) -> list[str]:
    return [k for k in metrics if k.startswith("lstm_member") and k != "lstm_members"]


def benchmark_table(metrics: Mapping[str, Any], command: str) -> str:
    """Markdown: prediction metrics per method, interpolation per fill method, coverage where a
    method gives a distribution, paired differences; every cell ``mean [95 % interval]`` (m)."""
    preds, fills = benchmark_methods(metrics)
    n = metrics.get("n_walks")
    lines = [f"Many-walk benchmark: {n} randomised occluded walks of the paper's scene, mean "
             f"[95 % bootstrap interval] over walks, m. `{command}`", ""]
    lines += ["| method | " + " | ".join(_NAMES.get(m, m) for m in PREDICTION_METRICS) + " |",
              "|---|" + "---|" * len(PREDICTION_METRICS)]
    for p in preds:
        lines.append(f"| {method_label(p)} | " + " | ".join(_fmt(metrics[p].get(m))
                                                          for m in PREDICTION_METRICS) + " |")
    members = _members(metrics)
    if members:
        seed0 = metrics.get("lstm_members", {}).get("seeds_from", 0)
        lines += ["", f"Each network of the LSTM's seed ensemble alone (seeds {seed0}-"
                  f"{seed0 + len(members) - 1}), on the same walks: what one training run gives.", "",
                  "| network | " + " | ".join(_NAMES.get(m, m) for m in PREDICTION_METRICS) + " |",
                  "|---|" + "---|" * len(PREDICTION_METRICS)]
        lines += [f"| seed {seed0 + i} | " + " | ".join(_fmt(metrics[p].get(m))
                                                      for m in PREDICTION_METRICS) + " |"
                  for i, p in enumerate(members)]
    if fills:
        lines += ["", "| interpolation | error on hidden frames (m) |", "|---|---|"]
        lines += [f"| {f[len('fill_'):]} | {_fmt(metrics[f].get('hidden_mean_m'))} |"
                  for f in fills]
    cov = [p for p in preds if "coverage_90" in metrics[p]]
    if cov:
        keys = ("coverage_50", "coverage_90", "coverage_95", "nll")
        lines += ["", "| method | " + " | ".join(_NAMES[k] for k in keys) + " |",
                  "|---|" + "---|" * len(keys)]
        lines += [f"| {method_label(p)} | " + " | ".join(_fmt(metrics[p].get(k)) for k in keys)
                  + " |" for p in cov]
    online = [p for p in preds if "online_coverage_90" in metrics[p]]
    if online:
        keys = ("online_coverage_50", "online_coverage_90", "online_coverage_95")
        settings = metrics.get("online_setting") or {}
        lines += ["", "Online ellipses: the walks met one after another, each walk's ellipses "
                  "from the outcomes of the walks before it (the validation scores before any); "
                  "each method's setting is the one it chose among `calibration.online_*` on "
                  "validation streams (the calibration stage's online.json; ACI gamma / window "
                  "/ rescale after, or scale eta / kappa).", "",
                  "| method | setting | " + " | ".join(_NAMES[k[len("online_"):]] for k in keys)
                  + " |", "|---|---|" + "---|" * len(keys)]
        lines += [f"| {method_label(p)} | {online_setting_label(settings.get(p))} | "
                  + " | ".join(_fmt(metrics[p].get(k)) for k in keys) + " |" for p in online]
    paired = metrics.get("paired", {})
    if paired:
        keys = ("path_error_mean_m", "ade_1s", "fde_2s", "hidden_mean_m")
        lines += ["", "Paired differences (bootstrap of per-walk differences; negative = the "
                  "first method has the smaller error):", "",
                  "| difference | " + " | ".join(_NAMES.get(k, k) for k in keys) + " |",
                  "|---|" + "---|" * len(keys)]
        lines += [f"| {pair} | " + " | ".join(_fmt(d.get(k)) for k in keys) + " |"
                  for pair, d in paired.items()]
    return "\n".join(lines) + "\n"


def benchmark_figure(metrics: Mapping[str, Any], three_walks: Mapping[str, Any] | None = None
                     ) -> Figure:
    """(a) ADE / FDE at 0.5, 1, 2 s and the paper's metric per prediction method, mean with
    its 95 % interval over the walks (the three-walk values of ``evaluate.json`` as open
    markers where given); (b) interpolation error on hidden frames per fill method."""
    preds, fills = benchmark_methods(metrics)
    fig, axes = new_grid(1, 2, 13.0, 4.6)
    ax_a, ax_b = axes[0]
    x = np.arange(len(PREDICTION_METRICS))
    width = 0.8 / max(len(preds), 1)
    for i, p in enumerate(preds):
        mean = np.array([metrics[p].get(m, {}).get("mean", np.nan) for m in PREDICTION_METRICS])
        ci = np.array([metrics[p].get(m, {}).get("ci95", [np.nan, np.nan])
                       for m in PREDICTION_METRICS], float)
        xs = x + (i - (len(preds) - 1) / 2) * width
        ax_a.errorbar(xs, mean, yerr=[mean - ci[:, 0], ci[:, 1] - mean], fmt="o", ms=4,
                      capsize=3, color=method_colour(p), label=method_label(p))
        if three_walks and p in three_walks:
            old = [three_walks[p].get(m, np.nan) for m in PREDICTION_METRICS]
            ax_a.plot(xs, old, "o", mfc="none", color=method_colour(p), ms=6,
                      label=f"{method_label(p)}, three paper walks")
    ax_a.set_xticks(x, [_NAMES.get(m, m).replace("paper's metric", "paper")
                        for m in PREDICTION_METRICS], rotation=30, ha="right")
    ax_a.set_ylabel("error (m)")
    ax_a.legend(fontsize=7)
    panel_title(ax_a, 0, f"prediction, {metrics.get('n_walks')} walks (95 % intervals)")
    for i, f in enumerate(fills):
        e = metrics[f].get("hidden_mean_m", {})
        if e:
            ax_b.errorbar([i], [e["mean"]], yerr=[[e["mean"] - e["ci95"][0]],
                                                  [e["ci95"][1] - e["mean"]]],
                          fmt="s", capsize=4, color="k")
    ax_b.set_xticks(range(len(fills)), [f[len("fill_"):] for f in fills])
    ax_b.set_ylabel("mean error on hidden frames (m)")
    panel_title(ax_b, 1, "interpolation behind the car")
    return fig
