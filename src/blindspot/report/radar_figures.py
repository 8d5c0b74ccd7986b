"""Radar maps and spectra: one frame through the detection chain (the paper's Fig. 6) and a real
recording's range-Doppler map with its detections.

Every function is pure: the arrays and DataFrames of the pipeline's artifacts in, a matplotlib
:class:`~matplotlib.figure.Figure` out; nothing is computed beyond choosing what to draw (and
power in dB). The stages save the figures (:func:`blindspot.io.save_figure`). The look is
:mod:`blindspot.report.style`'s.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from blindspot.report.paper_values import FIG6E_ACCUMULATED_FRAMES
from blindspot.report.style import (
    TIME_CMAP,
    TRUTH_COLOUR,
    cell_edges,
    draw_car,
    draw_radar,
    label_xy_axes,
    new_grid,
    panel_title,
    set_xy_limits,
    to_db,
    xy_of,
)
from blindspot.tables import check_columns

__all__ = ["fig06_detection", "fig_recording"]


# ----------------------------------------------------------------------------- Fig. 6


def fig06_detection(frame: Mapping[str, Any], detections: pd.DataFrame, *,
                    true_angle_deg: float | None, true_xy_m: Sequence[float] | None,
                    point: Mapping[str, float] | None, static_xy_m: np.ndarray | None,
                    scene_points: pd.DataFrame, scene_truth: pd.DataFrame | None = None,
                    car_polygon: Sequence[Sequence[float]] | None = None,
                    scene_name: str = "",
                    n_accumulate: int = int(FIG6E_ACCUMULATED_FRAMES.value)) -> Figure:
    """Fig. 6 (a-e): one frame through the chain, and the points of the scene over time.

    Args:
        frame: the arrays of ``data/detect/fig06_frame.npz``: power and threshold (R, D),
            mask (R, D) bool, range_axis_m (R,), velocity_axis_mps (D,), spectrum (A,) or empty,
            angles_deg (A,), spectrum_detection (row of ``detections`` or -1), frame, time_s.
        detections: that frame's detections (range_m, velocity_mps, angle_deg, moving, snr_db).
        true_angle_deg, true_xy_m: the pedestrian's true angle and position at that frame.
        point: the pedestrian point of that frame (x_m, y_m, optionally range_m, angle_deg), or
            None if none was found.
        static_xy_m: (K, 2) positions of the static (car) detections removed as clutter.
        scene_points: the scene's points (frame, time_s, x_m, y_m) for panel (e).
        scene_truth: the scene's truth (frame, x_m, y_m) drawn as a thin line in (d), (e).
        car_polygon: the car footprint (N, 2) or None.
        n_accumulate: frames accumulated in (e) (default: the paper's,
            :data:`~blindspot.report.paper_values.FIG6E_ACCUMULATED_FRAMES`).
    """
    check_columns(detections, ("range_m", "velocity_mps", "moving"), "fig06 detections",
                  who="fig06_detection")
    power = np.asarray(frame["power"], dtype=float)
    threshold = np.asarray(frame["threshold"], dtype=float)
    mask = np.asarray(frame["mask"], dtype=bool)
    rng_ax = np.asarray(frame["range_axis_m"], dtype=float)
    vel_ax = np.asarray(frame["velocity_axis_mps"], dtype=float)
    if power.shape != (rng_ax.size, vel_ax.size) or threshold.shape != power.shape or mask.shape != power.shape:
        raise ValueError(f"fig06 frame: power {power.shape}, threshold {threshold.shape}, mask {mask.shape} "
                         f"must all be (range {rng_ax.size}, velocity {vel_ax.size})")
    frame_no = int(np.asarray(frame.get("frame", -1)))
    time_s = float(np.asarray(frame.get("time_s", np.nan)))

    fig = plt.figure(figsize=(17, 9.5), layout="constrained")
    gs = fig.add_gridspec(2, 6)
    ax_a = fig.add_subplot(gs[0, 0:2])
    ax_b = fig.add_subplot(gs[0, 2:4])
    ax_c = fig.add_subplot(gs[0, 4:6])
    ax_d = fig.add_subplot(gs[1, 0:3])
    ax_e = fig.add_subplot(gs[1, 3:6])
    re, ve = cell_edges(rng_ax), cell_edges(vel_ax)

    # (a) range-velocity map
    p_db = to_db(power)
    top, floor = float(np.nanmax(p_db)), float(np.nanpercentile(p_db, 5))
    im = ax_a.pcolormesh(ve, re, p_db, cmap="viridis", vmin=floor - 3.0, vmax=top, shading="flat")
    fig.colorbar(im, ax=ax_a, label="power (dB re 1 ADC code²)")
    ax_a.set_xlabel("radial velocity (m/s)")
    ax_a.set_ylabel("range (m)")
    panel_title(ax_a, 0, "range-velocity map (FFT)")

    # (b) CFAR: power above the adaptive threshold
    margin = p_db - to_db(threshold)
    im = ax_b.pcolormesh(ve, re, np.clip(margin, -20, 20), cmap="RdBu_r", vmin=-20, vmax=20,
                         shading="flat")
    fig.colorbar(im, ax=ax_b, label="power over CA-CFAR threshold (dB)")
    if mask.any():
        ax_b.contour(vel_ax, rng_ax, mask.astype(float), levels=[0.5], colors="black",
                     linewidths=0.8)
    mov = detections["moving"].to_numpy(bool)
    ax_b.plot(detections.velocity_mps[~mov], detections.range_m[~mov], "s", mfc="none", mec="black",
              ms=9, mew=1.5, label=f"static: car ({(~mov).sum()})")
    ax_b.plot(detections.velocity_mps[mov], detections.range_m[mov], "o", mfc="none", mec="magenta",
              ms=9, mew=1.8, label=f"moving: pedestrian ({mov.sum()})")
    ax_b.plot([], [], color="black", lw=0.8, label=f"CFAR cells ({mask.sum()})")
    if (~mov).any():
        car = detections[~mov]
        ax_b.annotate("car (static)", xy=(0.0, float(car.range_m.max())), xytext=(0.6, float(car.range_m.max()) + 4),
                      fontsize=8, arrowprops=dict(arrowstyle="->", lw=0.8))
    if mov.any():
        ped = detections[mov]
        ax_b.annotate("pedestrian", xy=(float(ped.velocity_mps.mean()), float(ped.range_m.max())),
                      xytext=(float(ped.velocity_mps.mean()) - 1.0, float(ped.range_m.max()) + 6),
                      fontsize=8, arrowprops=dict(arrowstyle="->", lw=0.8))
    ax_b.set_xlabel("radial velocity (m/s)")
    ax_b.set_ylabel("range (m)")
    ax_b.legend(fontsize=7, loc="upper right")
    panel_title(ax_b, 1, "CA-CFAR detections")

    # (c) MUSIC pseudo-spectrum
    spectrum = np.asarray(frame.get("spectrum", np.zeros(0)), dtype=float)
    angles = np.asarray(frame.get("angles_deg", np.zeros(0)), dtype=float)
    row = int(np.asarray(frame.get("spectrum_detection", -1)))
    if spectrum.size and spectrum.size == angles.size:
        s_db = to_db(spectrum / np.max(spectrum))
        ax_c.plot(angles, s_db, color="black", lw=1.0, label="MUSIC pseudo-spectrum")
        if 0 <= row < len(detections) and np.isfinite(detections["angle_deg"].iloc[row]):
            est = float(detections["angle_deg"].iloc[row])
            ax_c.axvline(est, color="magenta", lw=1.5, label=f"estimated {est:+.1f}°")
        if true_angle_deg is not None:
            ax_c.axvline(true_angle_deg, color=TRUTH_COLOUR, ls="--", lw=1.5,
                         label=f"true {true_angle_deg:+.1f}°")
        ax_c.set_ylim(max(float(s_db.min()), -50.0) - 2, 3)
        ax_c.legend(fontsize=8, loc="lower right")
        centre = angles[int(np.argmax(spectrum))]
        ins = ax_c.inset_axes((0.62, 0.45, 0.35, 0.4))
        near = np.abs(angles - centre) <= 6.0
        ins.plot(angles[near], s_db[near], color="black", lw=1.0)
        for line in ax_c.lines[1:]:
            ins.axvline(line.get_xdata()[0], color=line.get_color(), ls=line.get_linestyle(), lw=1.2)
        ins.set_xlim(centre - 6.0, centre + 6.0)
        ins.tick_params(labelsize=7)
        ins.set_title("zoom (deg)", fontsize=7)
        if 0 <= row < len(detections):
            d = detections.iloc[row]
            ax_c.text(0.02, 0.97, f"detection at {d.range_m:.1f} m, {d.velocity_mps:+.2f} m/s",
                      transform=ax_c.transAxes, va="top", fontsize=8)
    else:
        ax_c.text(0.5, 0.5, "no moving detection in this frame", ha="center", va="center",
                  transform=ax_c.transAxes)
    ax_c.set_xlim(-90, 90)
    ax_c.set_xticks(np.arange(-90, 91, 30))
    ax_c.set_xlabel("angle (deg, + towards +x)")
    ax_c.set_ylabel("pseudo-spectrum (dB re peak)")
    ax_c.grid(True, lw=0.4, alpha=0.5)
    panel_title(ax_c, 2, "MUSIC angle of the pedestrian")

    # (d) the pedestrian's point on the x-y plane
    truth_xy = xy_of(scene_truth) if scene_truth is not None else None
    draw_car(ax_d, car_polygon)
    if static_xy_m is not None and len(static_xy_m):
        ax_d.plot(*np.asarray(static_xy_m).T, "s", mfc="none", mec="0.3", ms=7,
                  label="static detections (removed)")
    if point is not None:
        ray = "pedestrian point"
        if "range_m" in point and "angle_deg" in point:
            ray += f" (R = {point['range_m']:.2f} m, θ = {point['angle_deg']:+.1f}°)"
        ax_d.plot([0.0, point["x_m"]], [0.0, point["y_m"]], color="magenta", lw=0.8, ls=":")
        ax_d.plot(point["x_m"], point["y_m"], "o", color="magenta", ms=9, label=ray)
    if true_xy_m is not None:
        ax_d.plot(*true_xy_m, "+", color="black", ms=12, mew=2, label="true position")
    draw_radar(ax_d)
    chunks = [np.zeros((1, 2)), np.asarray(car_polygon) if car_polygon is not None else None,
              np.array([[point["x_m"], point["y_m"]]]) if point is not None else None,
              np.asarray([true_xy_m]) if true_xy_m is not None else None, static_xy_m]
    set_xy_limits(ax_d, chunks, margin_m=1.0, square=True)
    label_xy_axes(ax_d)
    ax_d.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    panel_title(ax_d, 3, f"pedestrian position (eq. 7), frame {frame_no}, t = {time_s:.1f} s")

    # (e) points over the scene, blue -> red by time
    pts = scene_points.sort_values("frame")
    pts = pts[pts.frame < pts.frame.min() + n_accumulate] if len(pts) else pts
    draw_car(ax_e, car_polygon)
    if truth_xy is not None:
        ax_e.plot(*truth_xy.T, color=TRUTH_COLOUR, lw=0.8, label="true path")
    sc = ax_e.scatter(pts.x_m, pts.y_m, c=pts.time_s, cmap=TIME_CMAP, s=14, zorder=3,
                      label=f"pedestrian points ({len(pts)})")
    fig.colorbar(sc, ax=ax_e, label="time (s)")
    draw_radar(ax_e)
    set_xy_limits(ax_e, [xy_of(pts), truth_xy, np.zeros((1, 2)),
                      np.asarray(car_polygon) if car_polygon is not None else None], square=True)
    label_xy_axes(ax_e)
    ax_e.legend(fontsize=8, loc="best")
    panel_title(ax_e, 4, f"points accumulated over {n_accumulate} frames")
    fig.suptitle(f"Fig. 6: detection chain on one simulated frame ({scene_name}, frame {frame_no})",
                 fontsize=12)
    return fig


# ----------------------------------------------------------------------------- recordings


def fig_recording(power: np.ndarray, detections: np.ndarray | pd.DataFrame,
                  range_axis_m: np.ndarray, velocity_axis_mps: np.ndarray, title: str,
                  dynamic_range_db: float = 60.0) -> Figure:
    """A recording's range-Doppler map in dB with its CFAR detections marked.

    Args:
        power: (R, D) detection map (|X|^2 summed over channels), zero Doppler centred.
        detections: (R, D) bool CFAR mask, or a DataFrame with range_m and velocity_mps
            (and optionally ``moving``) of the selected detections.
        range_axis_m: (R,) range of each row. velocity_axis_mps: (D,) velocity of each column.
        title: shown above the map (e.g. the recording's name).
        dynamic_range_db: largest colour scale span below the map's peak (the scale starts at
            the noise floor when that is closer).
    """
    power = np.asarray(power, dtype=float)
    r, v = np.asarray(range_axis_m, dtype=float), np.asarray(velocity_axis_mps, dtype=float)
    if power.ndim != 2 or power.shape != (r.size, v.size):
        raise ValueError(f"fig_recording: power must be (range {r.size}, velocity {v.size}), "
                         f"found {power.shape}")
    fig, axes = new_grid(1, 1, 7.0, 5.6)
    ax = axes[0, 0]
    p_db = to_db(power)
    top, floor = float(np.nanmax(p_db)), float(np.nanpercentile(p_db, 5)) - 3.0
    im = ax.pcolormesh(cell_edges(v), cell_edges(r), p_db, cmap="viridis",
                       vmin=max(floor, top - dynamic_range_db), vmax=top, shading="flat")
    fig.colorbar(im, ax=ax, label="power (dB re 1 ADC code², summed over channels)")
    if isinstance(detections, pd.DataFrame):
        check_columns(detections, ("range_m", "velocity_mps"), "fig_recording detections",
                      who="fig_recording")
        mov = (detections["moving"].to_numpy(bool) if "moving" in detections.columns
               else np.zeros(len(detections), bool))
        ax.plot(detections.velocity_mps[~mov], detections.range_m[~mov], "s", mfc="none",
                mec="white", ms=7, mew=1.3, label=f"static detections ({(~mov).sum()})")
        ax.plot(detections.velocity_mps[mov], detections.range_m[mov], "o", mfc="none",
                mec="magenta", ms=7, mew=1.5, label=f"moving detections ({mov.sum()})")
    else:
        mask = np.asarray(detections, dtype=bool)
        if mask.shape != power.shape:
            raise ValueError(f"fig_recording: detection mask {mask.shape} must match power {power.shape}")
        ri, di = np.nonzero(mask)
        ax.plot(v[di], r[ri], "o", mfc="none", mec="magenta", ms=5, mew=1.0,
                label=f"CFAR detections ({mask.sum()} cells)")
    ax.set_xlabel("radial velocity (m/s)")
    ax.set_ylabel("range (m)")
    ax.legend(fontsize=8, loc="upper right", facecolor="0.9")
    ax.set_title(title, fontsize=11)
    return fig
