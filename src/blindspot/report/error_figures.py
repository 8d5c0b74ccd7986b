"""Prediction errors: the error against prediction step (the paper's Fig. 10).

Pure: the per-scene error curves and the metrics of ``reports/metrics/evaluate.json`` in, a
matplotlib :class:`~matplotlib.figure.Figure` out. The one thing computed here is the mean over
scenes of each step's error (what the curve shows; the per-scene errors are the evaluate
stage's). The look is :mod:`blindspot.report.style`'s.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from blindspot.report.paper_values import PATH_ERROR_MEAN_M
from blindspot.report.style import method_colour, method_label, new_grid, panel_title
from blindspot.tables import check_columns

__all__ = ["fig10_error"]


# ----------------------------------------------------------------------------- Fig. 10


def fig10_error(curves: pd.DataFrame, metrics: Mapping[str, Any], dt_s: float = 0.1) -> Figure:
    """Fig. 10: Euclidean error against prediction step, averaged over the car scenes.

    (a) the paper's metric (each predicted point's distance to the nearest point of the actual
    path): solid against the simulated truth, dotted against the radar track of the same walk
    without the car (what the paper could measure), with the paper's mean
    (:data:`~blindspot.report.paper_values.PATH_ERROR_MEAN_M`) as a reference line;
    (b) the time-aligned error (predicted point k against the true position at step k).

    Args:
        curves: per scene and step (method, scene, step, error_m, path_error_m and optionally
            path_error_radar_m), i.e. ``data/evaluate/error_by_step_per_scene.csv``; averaged
            over scenes here.
        metrics: ``reports/metrics/evaluate.json``.
    """
    check_columns(curves, ("method", "step", "error_m", "path_error_m"), "fig10 curves",
                  who="fig10_error")
    cols = [c for c in ("error_m", "path_error_m", "path_error_radar_m") if c in curves.columns]
    mean = curves.groupby(["method", "step"], sort=False)[cols].mean().reset_index()
    methods = list(dict.fromkeys(mean.method))
    fig, axes = new_grid(1, 2, 13.0, 4.8)
    ax_a, ax_b = axes[0]
    for method in methods:
        m = mean[mean.method == method].sort_values("step")
        met = metrics.get(method, {})
        c = method_colour(method)
        pe, pr = met.get("path_error_mean_m"), met.get("path_error_radar_mean_m")
        ax_a.plot(m.step, m.path_error_m, "-o", ms=3, color=c,
                  label=f"{method_label(method)} vs truth" + (f": mean {pe:.2f} m" if pe is not None else ""))
        if "path_error_radar_m" in m and np.isfinite(m.path_error_radar_m).any():
            ax_a.plot(m.step, m.path_error_radar_m, ":", color=c, lw=1.5,
                      label=f"{method_label(method)} vs radar track" + (f": mean {pr:.2f} m" if pr is not None else ""))
        ade = met.get("ade_m")
        ax_b.plot(m.step, m.error_m, "-o", ms=3, color=c,
                  label=method_label(method) + (f": ADE {ade:.2f} m, FDE {met.get('fde_m', np.nan):.2f} m"
                                          if ade is not None else ""))
    paper_mean_m = PATH_ERROR_MEAN_M.value
    ax_a.axhline(paper_mean_m, color="black", ls="--", lw=1.2, label=f"paper mean {paper_mean_m} m")
    for ax in (ax_a, ax_b):
        ax.set_xlabel(f"prediction step ({dt_s:g} s each)")
        ax.set_ylabel("Euclidean error (m)")
        ax.set_ylim(bottom=0)
        ax.grid(True, lw=0.4, alpha=0.5)
        ax.legend(fontsize=7, loc="upper left")
        sec = ax.secondary_xaxis("top", functions=(lambda s: s * dt_s, lambda t: t / dt_s))
        sec.set_xlabel("horizon (s)")
    n_scenes = curves.scene.nunique() if "scene" in curves.columns else None
    over = f" (mean over {n_scenes} car scenes)" if n_scenes else ""
    panel_title(ax_a, 0, "paper's metric: distance to the nearest actual point")
    panel_title(ax_b, 1, "time-aligned error: distance to the true position at the same time")
    fig.suptitle(f"Fig. 10: prediction error against step{over}", fontsize=12)
    return fig
