"""Figures and tables of the collision-risk / warning / AEB evaluation (issue 12). They read the
safety stage's artifacts (data/safety/*.parquet, reports/metrics/safety.json) and compute no
science: every number drawn is a column of those files.

- :func:`fig_safety_timeline`: one run (the figure scene, CPNCO-like at 30 km/h): bird's-eye view
  with the ego's braked path, the pedestrian's truth and track, the ego's position at the
  warning, the AEB request and the end; below, P(collision) per predictor over time with the
  thresholds, and the ego speed under braking.
- :func:`fig_operating_characteristic`: false activations against avoided collisions as the AEB
  threshold sweeps, one curve per predictor (per input).
- :func:`fig_ncap_grid`: Euro NCAP-shaped grid (ego speed x impact point) per predictor, cells
  coloured by the 2026 band of the mean impact speed.
- :func:`fig_lead_times`: warning lead times (true TTC at the warning) per predictor and speed.
- :func:`ncap_grid_markdown`: the grid as a Markdown table for the README.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from blindspot.report.style import CAR_COLOUR, method_colour, new_grid, panel_title
from blindspot.tables import check_columns

__all__ = ["fig_safety_timeline", "fig_operating_characteristic", "fig_ncap_grid",
           "fig_lead_times", "ncap_grid_markdown", "PREDICTOR_LABELS"]

PREDICTOR_LABELS = {"none": "none (stays put)", "constant_velocity": "constant velocity",
                    "kalman": "Kalman (CV)", "lstm": "scene LSTM",
                    "lstm_direct": "scene LSTM, direct"}
BAND_COLOURS = {"green": "#3a9d23", "yellow": "#f2d300", "orange": "#f28c00",
                "brown": "#8b5a2b", "red": "#d62728"}
INPUT_STYLES = {"tracker": "-", "oracle": "--", "noisy_position": ":"}


def _colour(name: str) -> str:
    return "0.3" if name == "none" else method_colour(name)


def fig_safety_timeline(truth: pd.DataFrame, tracks: pd.DataFrame, risk: pd.DataFrame,
                        timeline: pd.DataFrame, outcome: pd.DataFrame,
                        car_polygons: Sequence, *, ego_width_m: float, ego_length_m: float,
                        warning_threshold: float, aeb_threshold: float, predictor: str,
                        title: str = "") -> Figure:
    """One run. truth: the scene's truth rows; tracks: its track rows (x_m, y_m, frame,
    track_id, confirmed); risk: its risk rows of every predictor (predictor, frame,
    p_collision) of one input; timeline: the braked ego of each predictor (predictor, time_s,
    ego_y_m, ego_speed_mps); outcome: its scene_outcomes rows (predictor, warning_s, aeb_s,
    impact_speed_kmh, avoided). ``predictor`` is the one drawn in the bird's-eye view."""
    check_columns(truth, ["time_s", "ego_y_m", "x_m", "y_m", "pedestrian", "occluded"], "truth",
                  who="fig_safety_timeline")
    check_columns(timeline, ["predictor", "time_s", "ego_y_m", "ego_speed_mps"], "timeline",
                  who="fig_safety_timeline")
    from matplotlib.patches import Polygon, Rectangle

    fig, axes = new_grid(3, 1, 10.0, 11.0)
    ax = axes[0, 0]
    for i, poly in enumerate(car_polygons):
        ax.add_patch(Polygon(np.asarray(poly)[:, ::-1], closed=True, facecolor=CAR_COLOUR,
                             edgecolor="0.35", zorder=0, label="parked cars" if i == 0 else None))
    for name, p in truth.groupby("pedestrian", sort=False):
        seen = np.where(p.occluded.to_numpy(bool), np.nan, 1.0)
        ax.plot(p.y_m, p.x_m, ":", color="tab:blue", lw=1.0)
        ax.plot(p.y_m, p.x_m * seen, "-", color="tab:blue", lw=2.0,
                label=f"{name} truth (solid: in line of sight)")
    conf = tracks[tracks.confirmed.astype(bool)]
    ax.plot(tracks.y_m, tracks.x_m, ".", color="0.5", ms=4, label="track (tentative)")
    ax.plot(conf.y_m, conf.x_m, "o", color="k", ms=4, label="track (confirmed)")
    line = timeline[timeline.predictor == predictor]
    row = outcome[outcome.predictor == predictor].iloc[0]
    marks = [("warning", row.warning_s, "tab:orange"), ("AEB request", row.aeb_s, "tab:red")]
    for label, t, c in marks:
        if np.isfinite(t):
            y = float(np.interp(t, line.time_s, line.ego_y_m))
            ax.add_patch(Rectangle((y - ego_length_m, -ego_width_m / 2), ego_length_m,
                                   ego_width_m, facecolor="none", edgecolor=c, lw=1.5,
                                   label=f"ego at the {label} (t = {t:.2f} s)"))
    end = line.iloc[-1]
    ax.add_patch(Rectangle((end.ego_y_m - ego_length_m, -ego_width_m / 2), ego_length_m,
                           ego_width_m, facecolor="none", edgecolor="k", lw=1.0, ls="--",
                           label=f"ego at t = {end.time_s:.1f} s"))
    ax.set_xlabel("y along the road (m)")
    ax.set_ylabel("x (m; kerb side down)")
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlim(-25, 8)
    ax.set_ylim(6, -6)
    ax.grid(True, lw=0.4, alpha=0.5)
    ax.legend(fontsize=7, loc="upper left", ncol=2)
    verdict = ("avoided" if row.avoided else f"impact at {row.impact_speed_kmh:.1f} km/h")
    panel_title(ax, 0, f"{title} - {PREDICTOR_LABELS.get(predictor, predictor)}: {verdict}")
    ax = axes[1, 0]
    for name, g in risk.groupby("predictor", sort=False):
        g = g.groupby("frame", as_index=False).p_collision.max()
        t = truth.drop_duplicates("frame").set_index("frame").time_s.reindex(g.frame)
        ax.step(t, g.p_collision, where="post", color=_colour(name),
                label=PREDICTOR_LABELS.get(name, name))
    ax.axhline(warning_threshold, color="tab:orange", ls="--", lw=1, label="warning threshold")
    ax.axhline(aeb_threshold, color="tab:red", ls="--", lw=1, label="AEB threshold")
    vis = truth[~truth.occluded.astype(bool)].time_s
    if len(vis):
        ax.axvline(vis.min(), color="tab:blue", lw=1, ls=":", label="first in line of sight")
    col = truth.collision_time_s.dropna()
    if len(col):
        ax.axvline(col.min(), color="k", lw=1, ls=":", label="collision without braking")
    ax.set_xlim(truth.time_s.min(), truth.time_s.max())
    ax.set_ylim(-0.02, 1.02)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("P(collision)")
    ax.legend(fontsize=7, ncol=2)
    ax.grid(True, lw=0.4, alpha=0.5)
    panel_title(ax, 1, "risk of the scene (largest over its confirmed tracks)")
    ax = axes[2, 0]
    for name, g in timeline.groupby("predictor", sort=False):
        ax.plot(g.time_s, g.ego_speed_mps * 3.6, color=_colour(name),
                label=PREDICTOR_LABELS.get(name, name))
    ax.set_xlabel("time (s)")
    ax.set_ylabel("ego speed (km/h)")
    ax.set_xlim(truth.time_s.min(), truth.time_s.max())
    ax.grid(True, lw=0.4, alpha=0.5)
    ax.legend(fontsize=7)
    panel_title(ax, 2, "ego speed with the AEB each predictor triggers")
    return fig


BOUND_LABELS = {"line_of_sight": "line of sight", "radar_point": "a radar point",
                "confirmed_track": "a {m}-of-{n} confirmable track"}


def fig_operating_characteristic(curves: pd.DataFrame, operating: Mapping[str, Mapping],
                                 bounds: Mapping[str, float] | None = None,
                                 confirm: tuple[int, int] = (3, 5)) -> Figure:
    """curves: threshold, avoided_rate, false_activation_rate, predictor, input.
    operating: input -> predictor -> {"avoided_rate", "false_activation_rate"} (the configured
    threshold's point). bounds: perception bound name (:mod:`blindspot.safety.bound`) -> its
    avoided rate, drawn at 0 % false activations (a perfect decider has none); confirm: the
    (M, N) of the confirmed-track bound (``safety_bound.json`` settings), for its label."""
    check_columns(curves, ["threshold", "avoided_rate", "false_activation_rate", "predictor",
                           "input"], "curves", who="fig_operating_characteristic")
    fig, axes = new_grid(1, 1, 8.0, 6.0)
    ax = axes[0, 0]
    for (inp, name), g in curves.groupby(["input", "predictor"], sort=False):
        g = g.sort_values("threshold", ascending=False)
        ax.plot(100 * g.false_activation_rate, 100 * g.avoided_rate, INPUT_STYLES.get(inp, "-"),
                color=_colour(name), label=f"{PREDICTOR_LABELS.get(name, name)} ({inp})")
        pt = operating.get(inp, {}).get(name)
        if pt:
            ax.plot(100 * pt["false_activation_rate"], 100 * pt["avoided_rate"], "o",
                    color=_colour(name))
    bounds = dict(bounds or {})
    order = ([k for k in BOUND_LABELS if k in bounds]
             + [k for k in bounds if k not in BOUND_LABELS])
    for i, name in enumerate(order):                 # earliest information first
        ax.plot(0.0, 100 * bounds[name], marker="^Ds"[i % 3], ls="none", ms=8, color="0.15",
                label="bound: AEB once there is "
                      + BOUND_LABELS.get(name, name).format(m=confirm[0], n=confirm[1]))
    ax.axvline(1.0, color="0.4", ls=":", lw=1, label="goal: <= 1 % false activations")
    ax.set_xlabel("false activations (% of non-intruding scenes)")
    ax.set_ylabel("collisions avoided (% of intruding scenes)")
    ax.set_xlim(-2, 102)
    ax.set_ylim(-2, 102)
    ax.grid(True, lw=0.4, alpha=0.5)
    ax.legend(fontsize=7)
    panel_title(ax, 0, "system operating characteristic (AEB threshold swept; dots: configured)")
    return fig


def fig_ncap_grid(grid: pd.DataFrame, predictors: Sequence[str]) -> Figure:
    """grid: speed_kmh, impact_pct, n, n_avoided, impact_speed_kmh_mean, band, predictor (one
    input)."""
    check_columns(grid, ["speed_kmh", "impact_pct", "n", "n_avoided", "impact_speed_kmh_mean",
                         "band", "predictor"], "grid", who="fig_ncap_grid")
    from matplotlib.patches import Rectangle

    fig, axes = new_grid(1, len(predictors), 3.6 * len(predictors), 4.6)
    speeds = np.sort(grid.speed_kmh.unique())
    pcts = np.sort(grid.impact_pct.unique())
    for i, name in enumerate(predictors):
        ax = axes[0, i]
        g = grid[grid.predictor == name].set_index(["speed_kmh", "impact_pct"])
        for r, v in enumerate(speeds):
            for c, p in enumerate(pcts):
                if (v, p) not in g.index:
                    continue
                cell = g.loc[(v, p)]
                ax.add_patch(Rectangle((c, r), 1, 1, facecolor=BAND_COLOURS[cell.band],
                                       edgecolor="w"))
                ax.text(c + 0.5, r + 0.5, f"{int(cell.n_avoided)}/{int(cell.n)}\n"
                        f"{cell.impact_speed_kmh_mean:.0f} km/h", ha="center", va="center",
                        fontsize=7, color="w" if cell.band in ("red", "brown", "green") else "k")
        ax.set_xlim(0, len(pcts))
        ax.set_ylim(0, len(speeds))
        ax.set_xticks(np.arange(len(pcts)) + 0.5, [f"{p:g} %" for p in pcts])
        ax.set_yticks(np.arange(len(speeds)) + 0.5, [f"{v:g}" for v in speeds])
        ax.set_xlabel("impact point")
        if i == 0:
            ax.set_ylabel("ego speed (km/h)")
        panel_title(ax, i, PREDICTOR_LABELS.get(name, name))
    fig.suptitle("Euro NCAP 2026 bands of the mean impact speed (cell: avoided/scenes, mean "
                 "impact speed)", fontsize=9)
    return fig


def fig_lead_times(scenes: pd.DataFrame, predictors: Sequence[str]) -> Figure:
    """scenes: the evaluated intruding scenes of one input (predictor, speed_kmh,
    lead_time_s)."""
    check_columns(scenes, ["predictor", "speed_kmh", "lead_time_s"], "scenes", who="fig_lead_times")
    fig, axes = new_grid(1, 1, 9.0, 5.0)
    ax = axes[0, 0]
    speeds = np.sort(scenes.speed_kmh.unique())
    w = 0.8 / max(len(predictors), 1)
    for i, name in enumerate(predictors):
        g = scenes[scenes.predictor == name]
        data = [g[g.speed_kmh == v].lead_time_s.dropna().to_numpy() for v in speeds]
        pos = np.arange(len(speeds)) + (i - (len(predictors) - 1) / 2) * w
        keep = [j for j, d in enumerate(data) if len(d)]
        if keep:
            bp = ax.boxplot([data[j] for j in keep], positions=pos[keep], widths=w * 0.9,
                            patch_artist=True, manage_ticks=False)
            for b in bp["boxes"]:
                b.set_facecolor(_colour(name))
                b.set_alpha(0.6)
        ax.plot([], [], "s", color=_colour(name), label=PREDICTOR_LABELS.get(name, name))
        for j, d in enumerate(data):
            n_all = int((g.speed_kmh == speeds[j]).sum())
            ax.text(pos[j], -0.15, f"{len(d)}/{n_all}", ha="center", fontsize=6)
    ax.set_xticks(np.arange(len(speeds)), [f"{v:g}" for v in speeds])
    ax.set_xlabel("ego speed (km/h)   (numbers: scenes warned / intruding scenes)")
    ax.set_ylabel("warning lead time = true TTC at the warning (s)")
    ax.grid(True, lw=0.4, alpha=0.5)
    ax.legend(fontsize=7)
    panel_title(ax, 0, "warning lead times")
    return fig


def ncap_grid_markdown(grid: pd.DataFrame, predictor: str) -> str:
    """The grid of one predictor as Markdown: rows ego speed, columns impact point, cells
    'avoided/scenes, mean impact km/h (band)', and '; k braked before the lead pedestrian was
    visible' where k scenes' AEB request came from a frame before anything (line of sight or a
    radar point of it) showed it (grids without ``n_aeb_before_visible`` show none)."""
    g = grid[grid.predictor == predictor]
    pcts = np.sort(g.impact_pct.unique())
    lines = ["| ego speed | " + " | ".join(f"{p:g} %" for p in pcts) + " |",
             "|---|" + "---|" * len(pcts)]

    def cell(c: pd.Series) -> str:
        text = (f"{int(c['n_avoided'])}/{int(c['n'])} avoided, "
                f"{c['impact_speed_kmh_mean']:.1f} km/h ({c['band']})")
        early = int(c.get("n_aeb_before_visible", 0))
        return text + (f"; {early} braked before the lead pedestrian was visible"
                       if early else "")

    for v, r in g.groupby("speed_kmh"):
        cells = r.set_index("impact_pct")
        lines.append(f"| {v:g} km/h | " + " | ".join(
            cell(cells.loc[p]) if p in cells.index else "-" for p in pcts) + " |")
    return "\n".join(lines) + "\n"
