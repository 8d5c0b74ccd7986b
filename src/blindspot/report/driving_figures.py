"""Figures of the driving scenes (issue 11): bird's-eye view of one run, the range-Doppler map
of one frame with the static world's Doppler curve, and the ego-speed error against speed.

Pure functions: artifacts (DataFrames, arrays) in, a matplotlib Figure out; nothing computed but
what to draw (dB, the curve -v cos(theta) drawn from the estimate stored in the artifacts).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from blindspot.report.style import (
    CAR_COLOUR, cell_edges, new_grid, panel_title, to_db,
)
from blindspot.tables import check_columns

__all__ = ["fig_driving_bev", "fig_driving_range_doppler", "fig_ego_speed_error"]

STATIC_COLOUR = "0.55"
MOVING_COLOUR = "tab:red"


def fig_driving_bev(truth: pd.DataFrame, detections: pd.DataFrame,
                    car_polygons: Sequence[Sequence[Sequence[float]]], *, title: str = "",
                    ego_width_m: float = 1.815) -> Figure:
    """Bird's-eye view (world frame, y along the road) of one run: the ego's radar path, the
    parked cars, each pedestrian's true path (dotted while occluded), the detections of every
    frame coloured static (on the ego-motion Doppler curve) or moving.

    truth: the scene's rows of ``driving/truth.parquet`` (ego_y_m, x_m, y_m, pedestrian,
    occluded, time_s); detections: x_m, y_m (world), static."""
    check_columns(truth, ["ego_x_m", "ego_y_m", "x_m", "y_m", "pedestrian", "occluded"], "truth",
                  who="fig_driving_bev")
    check_columns(detections, ["x_m", "y_m", "static"], "detections", who="fig_driving_bev")
    fig, axes = new_grid(1, 1, 9.0, 6.0)
    ax = axes[0, 0]
    from matplotlib.patches import Polygon, Rectangle

    for i, poly in enumerate(car_polygons):
        ax.add_patch(Polygon(np.asarray(poly)[:, ::-1], closed=True, facecolor=CAR_COLOUR, edgecolor="0.35",
                             zorder=0, label="parked cars" if i == 0 else None))
    ego = truth.drop_duplicates("frame")
    ax.plot(ego.ego_y_m, ego.ego_x_m, "k-", lw=1.0, label="ego radar (front bumper) path")
    last = ego.iloc[-1]
    ax.add_patch(Rectangle((last.ego_y_m - 4.358, -ego_width_m / 2), 4.358, ego_width_m,
                           facecolor="none", edgecolor="k", lw=0.8, ls="--",
                           label="ego at the last frame"))
    st = detections[detections.static.to_numpy(bool)]
    mv = detections[~detections.static.to_numpy(bool)]
    ax.scatter(st.y_m, st.x_m, s=4, c=STATIC_COLOUR, label=f"static detections ({len(st)})")
    ax.scatter(mv.y_m, mv.x_m, s=10, c=MOVING_COLOUR, label=f"moving detections ({len(mv)})")
    for name, p in truth.groupby("pedestrian", sort=False):
        seen = np.where(p.occluded.to_numpy(bool), np.nan, 1.0)
        ax.plot(p.y_m, p.x_m, ":", color="tab:blue", lw=1.0)
        ax.plot(p.y_m, p.x_m * seen, "-", color="tab:blue", lw=2.0,
                label=f"pedestrian truth (solid: visible), {name}")
    ax.set_xlabel("y along the road (m)")
    ax.set_ylabel("x (m; the ego's right, kerb side, down)")
    ax.set_aspect("equal", adjustable="box")
    ax.invert_yaxis()  # kerb side (x > 0) drawn below the ego path, as seen from above
    y_lo = float(min(ego.ego_y_m.min(), truth.y_m.min())) - 2
    ax.set_xlim(y_lo, float(max(truth.y_m.max(), ego.ego_y_m.max())) + 4)
    ax.set_ylim(12, -12)
    ax.grid(True, lw=0.4, alpha=0.5)
    ax.legend(fontsize=7, loc="lower left", ncol=2)
    ax.set_title(title, fontsize=10)
    return fig


def fig_driving_range_doppler(frame: Mapping[str, np.ndarray], detections: pd.DataFrame, *,
                              ego_speed_mps: float, odometry_mps: float, v_max_mps: float,
                              pedestrian_truth: Mapping[str, float] | None = None,
                              title: str = "") -> Figure:
    """(a) The range-Doppler map of one frame (dB, the Doppler axis wraps at +-v_max) with its
    detections; (b) the detections' unwrapped radial velocity against azimuth with the static
    world's Doppler curve ``-v cos(theta)`` (v: the radar's RANSAC estimate), static inliers and
    moving detections; the wrapped values faint.

    frame: power (R, D), range_axis_m (R,), velocity_axis_mps (D,). detections: range_m,
    velocity_wrapped_mps, velocity_mps, angle_deg, static. pedestrian_truth: angle_deg,
    radial_velocity_mps, range_m of the pedestrian at that frame (or None)."""
    check_columns(detections, ["range_m", "velocity_wrapped_mps", "velocity_mps", "angle_deg",
                               "static"], "detections", who="fig_driving_range_doppler")
    fig, axes = new_grid(1, 2, 14.0, 4.8)
    ax = axes[0, 0]
    p = to_db(frame["power"])
    ax.pcolormesh(cell_edges(frame["velocity_axis_mps"]), cell_edges(frame["range_axis_m"]), p,
                  cmap="viridis", vmin=np.percentile(p, 5), vmax=p.max(), shading="flat")
    st = detections.static.to_numpy(bool)
    ax.scatter(detections.velocity_wrapped_mps[st], detections.range_m[st], s=18, facecolors="none",
               edgecolors="white", label="static detections")
    ax.scatter(detections.velocity_wrapped_mps[~st], detections.range_m[~st], s=30, marker="x",
               c=MOVING_COLOUR, label="moving detections")
    ax.set_xlabel(f"radial velocity, wrapped into ±{v_max_mps:.2f} m/s")
    ax.set_ylabel("range (m)")
    ax.legend(fontsize=7, loc="upper right")
    panel_title(ax, 0, "range-Doppler map (dB)")
    ax = axes[0, 1]
    th = np.linspace(-80, 80, 321)
    ax.plot(th, -ego_speed_mps * np.cos(np.radians(th)), "k-", lw=1.0,
            label=f"static world −v cos θ, v = {ego_speed_mps:.2f} m/s (radar)")
    ax.scatter(detections.angle_deg, detections.velocity_wrapped_mps, s=8, c="0.8",
               label="wrapped (Doppler bin alone)")
    ax.scatter(detections.angle_deg[st], detections.velocity_mps[st], s=14, c=STATIC_COLOUR,
               label="unwrapped, static")
    ax.scatter(detections.angle_deg[~st], detections.velocity_mps[~st], s=30, marker="x",
               c=MOVING_COLOUR, label="unwrapped, moving")
    if pedestrian_truth is not None:
        ax.plot([pedestrian_truth["angle_deg"]], [pedestrian_truth["radial_velocity_mps"]], "o",
                mfc="none", mec="tab:blue", ms=12, label="pedestrian truth")
    ax.axhspan(-v_max_mps, v_max_mps, color="tab:orange", alpha=0.08,
               label="unambiguous interval")
    ax.set_xlabel("azimuth θ (deg)")
    ax.set_ylabel("radial velocity (m/s, negative = approaching)")
    ax.grid(True, lw=0.4, alpha=0.5)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    panel_title(ax, 1, f"Doppler unwrapped with odometry {odometry_mps:.2f} m/s")
    fig.suptitle(title, fontsize=10)
    return fig


def fig_ego_speed_error(sweep: pd.DataFrame, *, goal_mps: float = 0.1) -> Figure:
    """Left: ego-speed error (radar RANSAC estimate - truth) of every frame against the ego
    speed, driving straight and turning (where the sweep has a ``true_yaw_rate_deg_s`` column),
    its RMS per speed, the odometry's error beside it and the goal. Right (turning frames only,
    when present): the yaw-rate error of every frame, its RMS and the least-squares theory's
    standard deviation (``yaw_rate_sd_theory_deg_s``, median per speed)."""
    check_columns(sweep, ["speed_kmh", "error_mps", "odometry_error_mps"], "sweep",
                  who="fig_ego_speed_error")
    yaw = (sweep.true_yaw_rate_deg_s if "true_yaw_rate_deg_s" in sweep
           else pd.Series(0.0, index=sweep.index))
    turning = sweep[yaw != 0]
    fig, axes = new_grid(1, 2 if len(turning) else 1, 7.0 if turning.empty else 11.0, 4.2)
    ax = axes[0, 0]
    jitter = 0.6
    for sub, marker, what in ((sweep[yaw == 0], "o", "straight"), (turning, "^", "turning")):
        if sub.empty:
            continue
        ax.scatter(sub.speed_kmh - jitter, sub.error_mps, s=10, c="tab:red", marker=marker,
                   label=f"radar (Kellner + RANSAC), per frame, {what}")
    ax.scatter(sweep.speed_kmh + jitter, sweep.odometry_error_mps, s=10, c="tab:blue", alpha=0.6,
               label="odometry (noise + bias), per frame")
    g = sweep.groupby("speed_kmh")
    rms = g.error_mps.apply(lambda e: float(np.sqrt(np.nanmean(e**2))))
    ax.plot(rms.index, rms.values, "k-o", ms=4, label="radar RMS")
    ax.axhline(goal_mps, color="k", ls="--", lw=0.8, label=f"goal ±{goal_mps} m/s RMS")
    ax.axhline(-goal_mps, color="k", ls="--", lw=0.8)
    ax.set_xlabel("ego speed (km/h)")
    ax.set_ylabel("speed error (m/s)")
    ax.grid(True, lw=0.4, alpha=0.5)
    ax.legend(fontsize=7)
    if len(turning):
        check_columns(turning, ["yaw_rate_error_deg_s", "yaw_rate_sd_theory_deg_s"], "sweep",
                      who="fig_ego_speed_error")
        ax = axes[0, 1]
        ax.scatter(turning.speed_kmh, turning.yaw_rate_error_deg_s, s=10, c="tab:red",
                   marker="^", label="radar, per frame")
        gt = turning.groupby("speed_kmh")
        rms_w = gt.yaw_rate_error_deg_s.apply(lambda e: float(np.sqrt(np.nanmean(e**2))))
        theory = gt.yaw_rate_sd_theory_deg_s.median()
        ax.plot(rms_w.index, rms_w.values, "k-o", ms=4, label="RMS")
        ax.plot(theory.index, theory.values, "k:", label="least-squares theory (sd)")
        ax.axhline(0.0, color="0.5", lw=0.6)
        ax.set_xlabel("ego speed (km/h)")
        ax.set_ylabel("yaw-rate error (deg/s)")
        ax.set_title(f"turning at {float(turning.true_yaw_rate_deg_s.iloc[0]):g} deg/s",
                     fontsize=9)
        ax.grid(True, lw=0.4, alpha=0.5)
        ax.legend(fontsize=7)
    return fig
