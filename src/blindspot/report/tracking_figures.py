"""Figures of the tracker on real recordings (issue 12): our tracks against TI's on the
people-counting log, and the walker's track over the RadHAR point cloud.

Pure functions: the stage's artifacts (points and tracks as DataFrames) in, a matplotlib Figure
out; nothing is computed but what to draw.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from blindspot.report.style import new_grid, panel_title
from blindspot.tables import check_columns

__all__ = ["fig_tracks_against_reference", "fig_track_over_points"]

_TRACK_COLS = ("frame", "track_id", "x_m", "y_m")


def _colours(ids) -> dict:
    cmap = plt.get_cmap("tab10")
    return {tid: cmap(i % 10) for i, tid in enumerate(sorted(ids))}


def fig_tracks_against_reference(points: pd.DataFrame, tracks: pd.DataFrame,
                                 reference: pd.DataFrame, *, title: str, metrics: dict,
                                 axes_labels: tuple[str, str] = ("x (m)", "y (m)")) -> Figure:
    """Bird's-eye view: (a) the points of every frame (grey) with our confirmed tracks (one
    colour per id, start marked) and the reference tracks (black dashed); (b) x of each track
    against time, ours and the reference's, so an identity switch shows as a colour change.

    Args:
        points: ``x_m``, ``y_m`` of every point.
        tracks: our confirmed tracks: ``frame``, ``time_s``, ``track_id``, ``x_m``, ``y_m``.
        reference: reference tracks: ``frame``, ``time_s``, ``track_id``, ``x_m``, ``y_m``.
        title: figure title.
        metrics: printed in the legend title (``mota``, ``id_switches``,
            ``median_distance_m``, ``gate_m``).
    """
    check_columns(points, ("x_m", "y_m"), "points", who="fig_tracks_against_reference")
    check_columns(tracks, (*_TRACK_COLS, "time_s"), "tracks", who="fig_tracks_against_reference")
    check_columns(reference, (*_TRACK_COLS, "time_s"), "reference tracks",
                  who="fig_tracks_against_reference")
    fig, axes = new_grid(1, 2, 11.0, 5.0)
    ax, ax_t = axes[0]
    ax.scatter(points.x_m, points.y_m, s=2, c="0.75", lw=0, label="points (all frames)")
    col = _colours(tracks.track_id.unique())
    for tid, t in reference.groupby("track_id"):
        ax.plot(t.x_m, t.y_m, "k--", lw=1.0, label="TI gtrack" if tid == reference.track_id.min() else None)
        ax_t.plot(t.time_s, t.x_m, "k--", lw=1.0)
    for tid, t in tracks.groupby("track_id"):
        ax.plot(t.x_m, t.y_m, "-", color=col[tid], lw=1.6, label=f"ours, track {tid}")
        ax.plot(t.x_m.iloc[0], t.y_m.iloc[0], "o", color=col[tid], ms=5)
        ax_t.plot(t.time_s, t.x_m, "-", color=col[tid], lw=1.6)
    _sensor_frame(ax, axes_labels)
    leg = (f"MOTA {metrics.get('mota', float('nan')):.3f}, ID switches "
           f"{metrics.get('id_switches')}, median distance "
           f"{metrics.get('median_distance_m', float('nan')):.3f} m (gate {metrics.get('gate_m')} m)")
    ax.legend(fontsize=7, loc="lower left", title=leg, title_fontsize=7)
    panel_title(ax, 0, "bird's-eye view")
    ax_t.set_xlabel("time (s)")
    ax_t.set_ylabel(axes_labels[0])
    panel_title(ax_t, 1, "x against time (colour = our id, dashed = TI)")
    fig.suptitle(title, fontsize=11)
    return fig


def _sensor_frame(ax, axes_labels: tuple[str, str]) -> None:
    """The radar at the origin of a bird's-eye panel in the recording's own sensor frame."""
    ax.plot(0, 0, "k^", ms=8, label="radar")
    ax.set_aspect("equal")
    ax.set_xlabel(axes_labels[0])
    ax.set_ylabel(axes_labels[1])


def fig_track_over_points(points: pd.DataFrame, tracks: pd.DataFrame, *, title: str,
                          metrics: dict,
                          axes_labels: tuple[str, str] = ("x (m)", "y (m)")) -> Figure:
    """(a) Bird's-eye view of the static points (grey, dropped), the moving points (coloured by
    time) and our confirmed tracks (one colour per id); (b) x of the moving points and of the
    tracks against time (the walker's loop).

    Args:
        points: ``time_s``, ``x_m``, ``y_m``, ``static`` of every point.
        tracks: our confirmed tracks: ``time_s``, ``track_id``, ``x_m``, ``y_m``.
        title: figure title.
        metrics: printed in the legend (``n_tracks``, ``longest_track_coverage``,
            ``static_points_dropped``).
    """
    check_columns(points, ("time_s", "x_m", "y_m", "static"), "points", who="fig_track_over_points")
    check_columns(tracks, ("time_s", "track_id", "x_m", "y_m"), "tracks",
                  who="fig_track_over_points")
    fig, axes = new_grid(1, 2, 11.0, 5.0)
    ax, ax_t = axes[0]
    static, moving = points[points.static], points[~points.static]
    ax.scatter(static.x_m, static.y_m, s=3, c="0.7", lw=0, label="static points (dropped)")
    sc = ax.scatter(moving.x_m, moving.y_m, s=4, c=moving.time_s, cmap="viridis", lw=0,
                    label="moving points")
    col = _colours(tracks.track_id.unique())
    for tid, t in tracks.groupby("track_id"):
        ax.plot(t.x_m, t.y_m, "-", color=col[tid], lw=1.2, label=f"track {tid}")
        ax_t.plot(t.time_s, t.x_m, "-", color=col[tid], lw=1.4, label=f"track {tid}")
    ax_t.scatter(moving.time_s, moving.x_m, s=3, c="0.4", lw=0, label="moving points")
    fig.colorbar(sc, ax=ax, label="time (s)")
    _sensor_frame(ax, axes_labels)
    leg = (f"{metrics.get('n_tracks')} confirmed track(s); longest covers "
           f"{100 * metrics.get('longest_track_coverage', np.nan):.1f} % of the walk; "
           f"{100 * metrics.get('static_points_dropped', np.nan):.0f} % of points static")
    ax.legend(fontsize=7, loc="upper left", title=leg, title_fontsize=7)
    panel_title(ax, 0, "bird's-eye view")
    ax_t.set_xlabel("time (s)")
    ax_t.set_ylabel(axes_labels[0])
    ax_t.legend(fontsize=7)
    panel_title(ax_t, 1, "x against time")
    fig.suptitle(title, fontsize=11)
    return fig
