"""The paper's figures (Figs. 4, 6-10) and the recordings' figure, drawn from pipeline artifacts.

Every function here is pure: plain arrays, DataFrames and dicts in (what the stages read from
``data/`` and ``reports/metrics/``), a matplotlib :class:`~matplotlib.figure.Figure` out. Nothing
is computed beyond choosing and averaging what to draw; the stages save the figure
(:func:`blindspot.io.save_figure`). The Agg backend is used, so no display is needed.

Conventions shared by all figures:

- Radar at the origin looking along +y; x to the right (metres). x-y panels use equal scales.
- One colour per method in every figure (:data:`METHOD_COLOURS`): the LSTM red (as in the
  paper's Fig. 9), constant velocity blue, Kalman green, our two-sided interpolation purple;
  radar points black, simulated truth grey (dashed where it is the future to be predicted).
- Panels are labelled (a), (b), ... as in the paper; the paper's number is quoted beside ours
  where the paper gives one.
"""

from __future__ import annotations

import string
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.patches import Polygon  # noqa: E402

__all__ = [
    "METHOD_COLOURS",
    "METHOD_LABELS",
    "PAPER_PATH_ERROR_MEAN_M",
    "PathCase",
    "scene_title",
    "fig04_lstm_paths",
    "fig06_detection",
    "fig07_scenes",
    "fig08_interpolation",
    "fig09_prediction",
    "fig10_error",
    "fig_recording",
]

PAPER_PATH_ERROR_MEAN_M = 0.09
"""The paper's mean Euclidean error of the predicted path (Fig. 10)."""

METHOD_COLOURS: dict[str, str] = {
    "lstm": "#d62728",               # red: the paper's predictions
    "forward": "#d62728",            # the paper's interpolation is the same LSTM rolled forward
    "constant_velocity": "#1f77b4",
    "kalman": "#2ca02c",
    "bidirectional": "#9467bd",
}
METHOD_LABELS: dict[str, str] = {
    "lstm": "LSTM (paper)",
    "forward": "forward LSTM (paper)",
    "constant_velocity": "constant velocity",
    "kalman": "Kalman (CV)",
    "bidirectional": "two-sided LSTM (ours)",
}
TRUTH_COLOUR = "0.45"
POINT_COLOUR = "black"
CAR_COLOUR = "0.80"
TIME_CMAP = "jet"  # blue (start) -> red (end), as the paper's Fig. 6e


# ----------------------------------------------------------------------------- helpers


def _colour(method: str) -> str:
    return METHOD_COLOURS.get(method, "0.3")


def _label(method: str) -> str:
    return METHOD_LABELS.get(method, method.replace("_", " "))


def _panel(ax: Axes, index: int, title: str) -> None:
    """Title a panel "(a) title", "(b) title", ... (index 0 -> a)."""
    ax.set_title(f"({string.ascii_lowercase[index]}) {title}", loc="left", fontsize=10)


def scene_title(name: str, info: Mapping[str, Any] | None = None) -> str:
    """Readable scene title: ``approach_car`` with turn +45 -> "approach (turn +45°), with car"."""
    base = name[: -len("_nocar")] if name.endswith("_nocar") else (
        name[: -len("_car")] if name.endswith("_car") else name)
    base = base.replace("_", " ")
    if info is None:
        return base
    turn = info.get("turn_deg")
    turn_txt = "" if turn is None else (" (no turn)" if float(turn) == 0 else f" (turn {float(turn):+.0f}°)")
    car = "with car" if info.get("with_car") else "no car"
    return f"{base}{turn_txt}, {car}"


def _draw_car(ax: Axes, polygon: Sequence[Sequence[float]] | np.ndarray | None, label: bool = True) -> None:
    if polygon is None:
        return
    poly = np.asarray(polygon, dtype=float)
    ax.add_patch(Polygon(poly, closed=True, facecolor=CAR_COLOUR, edgecolor="0.35", lw=1.0,
                         zorder=0, label="parked car" if label else None))


def _draw_radar(ax: Axes, label: bool = True) -> None:
    ax.plot([0.0], [0.0], marker="^", ms=9, color="black", ls="none", zorder=5,
            label="radar" if label else None)


def _xy_limits(ax: Axes, chunks: Sequence[np.ndarray | None], margin_m: float = 0.6,
               square: bool = False) -> None:
    """Equal-scale x-y limits that contain every finite point of ``chunks`` (each (..., 2)).

    ``square``: widen the shorter side so x and y span the same length (uniform panels).
    """
    pts = [np.asarray(c, dtype=float).reshape(-1, 2) for c in chunks if c is not None and np.size(c)]
    xy = np.concatenate(pts) if pts else np.zeros((1, 2))
    xy = xy[np.isfinite(xy).all(axis=1)]
    if not len(xy):
        xy = np.zeros((1, 2))
    lo, hi = xy.min(axis=0) - margin_m, xy.max(axis=0) + margin_m
    if square:
        centre, half = 0.5 * (lo + hi), 0.5 * float(np.max(hi - lo))
        lo, hi = centre - half, centre + half
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal", adjustable="box")


def _radar_direction(ax: Axes) -> str:
    """"radar: 12 m ↘" (distance and direction from the panel centre to the origin)."""
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    c = -np.array([(x0 + x1) / 2, (y0 + y1) / 2])
    arrows = "→↗↑↖←↙↓↘"
    k = int(np.round(np.degrees(np.arctan2(c[1], c[0])) / 45.0)) % 8
    return f"radar (origin): {np.hypot(*c):.0f} m {arrows[k]}"


def _note(ax: Axes, text: str, fontsize: float = 8) -> None:
    """A text box placed where it hides the least data (matplotlib's legend "best" placement)."""
    leg = ax.legend(handles=[], title=text, loc="best", title_fontsize=fontsize, framealpha=0.9)
    leg._legend_box.align = "left"  # noqa: SLF001 - left-aligned multi-line note
    ax.add_artist(leg)


def _xy_axes(ax: Axes) -> None:
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m, boresight)")
    ax.grid(True, lw=0.4, alpha=0.5)


def _db(power: np.ndarray) -> np.ndarray:
    p = np.asarray(power, dtype=float)
    floor = np.finfo(float).tiny
    return 10.0 * np.log10(np.maximum(p, floor))


def _edges(axis: np.ndarray) -> np.ndarray:
    """Cell edges of a uniformly (or nearly) spaced axis of cell centres."""
    a = np.asarray(axis, dtype=float)
    if a.size == 1:
        return np.array([a[0] - 0.5, a[0] + 0.5])
    mid = 0.5 * (a[1:] + a[:-1])
    return np.concatenate([[a[0] - (mid[0] - a[0])], mid, [a[-1] + (a[-1] - mid[-1])]])


def _xy(df: pd.DataFrame, x: str = "x_m", y: str = "y_m") -> np.ndarray:
    return df[[x, y]].to_numpy(dtype=float)


def _require(df: pd.DataFrame, columns: Sequence[str], what: str) -> None:
    missing = [c for c in columns if c not in df.columns]
    if missing:
        raise ValueError(f"{what}: missing columns {missing}; found {list(df.columns)}")


def _grid(n_rows: int, n_cols: int, width: float, height: float) -> tuple[Figure, np.ndarray]:
    fig, axes = plt.subplots(n_rows, n_cols, figsize=(width, height), squeeze=False,
                             layout="constrained")
    return fig, axes


# ----------------------------------------------------------------------------- Fig. 4


@dataclass(frozen=True)
class PathCase:
    """One panel of Fig. 4: a test path's input window, the LSTM rollout and the true future.

    Attributes:
        motion: "approaching", "receding" or "perpendicular".
        path_id: the path's id in ``data/paths/paths.parquet``.
        start: index of the window's first point within the path.
        history: (W, 2) measured radar points of the input window, NaN where missed.
        history_true: (W, 2) true positions over the window.
        prediction: (H, 2) the LSTM's autoregressive predictions.
        future_true: (H, 2) the true continuation.
        ade_m: mean time-aligned error of the prediction, if computed by the caller.
        split: the split the path belongs to ("test", or "val" when the test split has too
            few paths of that motion).
    """

    motion: str
    path_id: int
    start: int
    history: np.ndarray
    history_true: np.ndarray
    prediction: np.ndarray
    future_true: np.ndarray
    ade_m: float | None = None
    split: str = "test"


def fig04_lstm_paths(cases: Sequence[PathCase], dt_s: float = 0.1,
                     val_rmse_m: float | None = None) -> Figure:
    """Fig. 4: input path and LSTM predictions on test paths, one panel per case.

    The paper's layout has five cases: (a)(b) approaching, (c)(d) receding, (e) perpendicular.
    Panels sit on a grid of three columns; a free grid cell holds the shared legend.
    ``val_rmse_m`` (one-step validation RMSE) goes into the figure title beside the paper's 0.07.
    """
    if not cases:
        raise ValueError("fig04_lstm_paths: no cases to draw")
    n = len(cases)
    n_cols = min(n, 3)
    n_rows = int(np.ceil(n / n_cols))
    fig, axes = _grid(n_rows, n_cols, 4.4 * n_cols, 4.3 * n_rows)
    handles: list[Any] = []
    for i, (ax, case) in enumerate(zip(axes.flat, cases)):
        hist = np.asarray(case.history, dtype=float)
        pred = np.asarray(case.prediction, dtype=float)
        fut = np.asarray(case.future_true, dtype=float)
        htrue = np.asarray(case.history_true, dtype=float)
        W = len(hist)
        seen = np.isfinite(hist).all(axis=1)
        h = [
            ax.plot(*htrue.T, color=TRUTH_COLOUR, lw=1.0, label="true path (input window)")[0],
            ax.plot(*np.vstack([htrue[-1:], fut]).T, color=TRUTH_COLOUR, lw=1.5, ls="--",
                    label="true continuation")[0],
            ax.plot(*hist[seen].T, ".", color=POINT_COLOUR, ms=4,
                    label=f"input: {W} radar points (missed ones not drawn)")[0],
            ax.plot(*np.vstack([hist[seen][-1:], pred]).T, "-", color=_colour("lstm"), lw=1.8,
                    label="LSTM prediction, autoregressive")[0],
        ]
        ax.plot(*pred[-1], "x", color=_colour("lstm"), ms=8, mew=2)
        ax.plot(*fut[-1], "x", color=TRUTH_COLOUR, ms=8, mew=2)
        handles = handles or h
        _xy_limits(ax, [hist, htrue, pred, fut], margin_m=0.8, square=True)
        _xy_axes(ax)
        ade_txt = f"\nADE {case.ade_m:.2f} m" if case.ade_m is not None else ""
        _note(ax, f"{seen.sum()}/{W} points seen{ade_txt}\n{_radar_direction(ax)}")
        _panel(ax, i, f"{case.motion}: {case.split} path {case.path_id}, points {case.start}-{case.start + W - 1}")
    free = list(axes.flat)[n:]
    for ax in free:
        ax.set_axis_off()
    x_mark = [plt.Line2D([], [], color=_colour("lstm"), marker="x", ls="none", mew=2,
                         label=f"last predicted / true point ({len(cases[0].prediction)} steps, "
                               f"{len(cases[0].prediction) * dt_s:g} s)")]
    if free:
        free[0].legend(handles=handles + x_mark, loc="center", fontsize=9, frameon=False)
    else:
        fig.legend(handles=handles + x_mark, loc="lower center", ncol=3, fontsize=8)
    rmse = "" if val_rmse_m is None else f"; one-step validation RMSE {val_rmse_m:.3f} m (paper 0.07)"
    fig.suptitle("Fig. 4: LSTM predictions on simulated paths unseen in training (window of 50 radar points, "
                 f"each prediction fed back){rmse}", fontsize=11)
    return fig


# ----------------------------------------------------------------------------- Fig. 6


def fig06_detection(frame: Mapping[str, Any], detections: pd.DataFrame, *,
                    true_angle_deg: float | None, true_xy_m: Sequence[float] | None,
                    point: Mapping[str, float] | None, static_xy_m: np.ndarray | None,
                    scene_points: pd.DataFrame, scene_truth: pd.DataFrame | None = None,
                    car_polygon: Sequence[Sequence[float]] | None = None,
                    scene_name: str = "", n_accumulate: int = 100) -> Figure:
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
        n_accumulate: frames accumulated in (e) (the paper: 100).
    """
    _require(detections, ("range_m", "velocity_mps", "moving"), "fig06 detections")
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
    re, ve = _edges(rng_ax), _edges(vel_ax)

    # (a) range-velocity map
    p_db = _db(power)
    top, floor = float(np.nanmax(p_db)), float(np.nanpercentile(p_db, 5))
    im = ax_a.pcolormesh(ve, re, p_db, cmap="viridis", vmin=floor - 3.0, vmax=top, shading="flat")
    fig.colorbar(im, ax=ax_a, label="power (dB re 1 ADC code²)")
    ax_a.set_xlabel("radial velocity (m/s)")
    ax_a.set_ylabel("range (m)")
    _panel(ax_a, 0, "range-velocity map (FFT)")

    # (b) CFAR: power above the adaptive threshold
    margin = p_db - _db(threshold)
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
    _panel(ax_b, 1, "CA-CFAR detections")

    # (c) MUSIC pseudo-spectrum
    spectrum = np.asarray(frame.get("spectrum", np.zeros(0)), dtype=float)
    angles = np.asarray(frame.get("angles_deg", np.zeros(0)), dtype=float)
    row = int(np.asarray(frame.get("spectrum_detection", -1)))
    if spectrum.size and spectrum.size == angles.size:
        s_db = _db(spectrum / np.max(spectrum))
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
    _panel(ax_c, 2, "MUSIC angle of the pedestrian")

    # (d) the pedestrian's point on the x-y plane
    truth_xy = _xy(scene_truth) if scene_truth is not None else None
    _draw_car(ax_d, car_polygon)
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
    _draw_radar(ax_d)
    chunks = [np.zeros((1, 2)), np.asarray(car_polygon) if car_polygon is not None else None,
              np.array([[point["x_m"], point["y_m"]]]) if point is not None else None,
              np.asarray([true_xy_m]) if true_xy_m is not None else None, static_xy_m]
    _xy_limits(ax_d, chunks, margin_m=1.0, square=True)
    _xy_axes(ax_d)
    ax_d.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    _panel(ax_d, 3, f"pedestrian position (eq. 7), frame {frame_no}, t = {time_s:.1f} s")

    # (e) points over the scene, blue -> red by time
    pts = scene_points.sort_values("frame")
    pts = pts[pts.frame < pts.frame.min() + n_accumulate] if len(pts) else pts
    _draw_car(ax_e, car_polygon)
    if truth_xy is not None:
        ax_e.plot(*truth_xy.T, color=TRUTH_COLOUR, lw=0.8, label="true path")
    sc = ax_e.scatter(pts.x_m, pts.y_m, c=pts.time_s, cmap=TIME_CMAP, s=14, zorder=3,
                      label=f"pedestrian points ({len(pts)})")
    fig.colorbar(sc, ax=ax_e, label="time (s)")
    _draw_radar(ax_e)
    _xy_limits(ax_e, [_xy(pts), truth_xy, np.zeros((1, 2)),
                      np.asarray(car_polygon) if car_polygon is not None else None], square=True)
    _xy_axes(ax_e)
    ax_e.legend(fontsize=8, loc="best")
    _panel(ax_e, 4, f"points accumulated over {n_accumulate} frames")
    fig.suptitle(f"Fig. 6: detection chain on one simulated frame ({scene_name}, frame {frame_no})",
                 fontsize=12)
    return fig


# ----------------------------------------------------------------------------- Fig. 7


def fig07_scenes(points: pd.DataFrame, truth: pd.DataFrame, scenes: Mapping[str, Mapping[str, Any]],
                 pairs: Sequence[tuple[str, str]]) -> Figure:
    """Fig. 7 (a-f): each direction without the car (top row) and with it (bottom row).

    Args:
        points: ``data/localise/points.parquet`` (scene, frame, time_s, x_m, y_m).
        truth: ``data/simulate/truth.parquet`` (scene, frame, x_m, y_m, occluded).
        scenes: ``data/simulate/scenes.json`` (with_car, car_polygon_xy_m, turn_deg, n_frames).
        pairs: (no-car scene, car scene) per direction, in column order.
    """
    _require(points, ("scene", "frame", "time_s", "x_m", "y_m"), "fig07 points")
    _require(truth, ("scene", "frame", "x_m", "y_m", "occluded"), "fig07 truth")
    if not pairs:
        raise ValueError("fig07_scenes: no scene pairs")
    n = len(pairs)
    fig, axes = _grid(2, n, 4.8 * n, 9.0)
    names = [name for pair in pairs for name in pair]
    all_xy = [_xy(truth[truth.scene.isin(names)]), _xy(points[points.scene.isin(names)]), np.zeros((1, 2))]
    all_xy += [np.asarray(scenes[s]["car_polygon_xy_m"]) for s in names if scenes[s].get("car_polygon_xy_m")]
    t_max = float(truth[truth.scene.isin(names)].frame.max() + 1) * float(
        next(iter(scenes.values())).get("frame_period_s", 0.1))
    sc = None
    for col, pair in enumerate(pairs):
        for row, name in enumerate(pair):
            ax = axes[row, col]
            info = scenes[name]
            tr = truth[truth.scene == name].sort_values("frame")
            pts = points[points.scene == name].sort_values("frame")
            _draw_car(ax, info.get("car_polygon_xy_m"), label=False)
            ax.plot(*_xy(tr).T, color=TRUTH_COLOUR, lw=0.8)
            hid = tr.occluded.to_numpy(bool)
            if hid.any():
                ax.plot(*_xy(tr[hid]).T, ".", color="orange", ms=5, zorder=1)
            sc = ax.scatter(pts.x_m, pts.y_m, c=pts.time_s, cmap=TIME_CMAP, vmin=0, vmax=t_max,
                            s=12, zorder=3)
            _draw_radar(ax, label=False)
            _xy_limits(ax, all_xy)
            _xy_axes(ax)
            hidden_txt = f"\nhidden behind the car: {hid.sum()} frames" if hid.any() else ""
            _note(ax, f"radar points in {len(pts)}/{len(tr)} frames{hidden_txt}")
            _panel(ax, row * n + col, scene_title(name, info))
    handles = [
        plt.Line2D([], [], color=TRUTH_COLOUR, lw=0.8, label="true path"),
        plt.Line2D([], [], color="orange", marker=".", ls="none", ms=8,
                   label="true position while hidden behind the car"),
        plt.Line2D([], [], color="tab:blue", marker="o", ls="none", ms=5,
                   label="radar point (colour: time)"),
        Polygon(np.zeros((3, 2)), facecolor=CAR_COLOUR, edgecolor="0.35", label="parked car"),
        plt.Line2D([], [], color="black", marker="^", ls="none", ms=8, label="radar"),
    ]
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=9)
    if sc is not None:
        fig.colorbar(sc, ax=axes, label="time (s)", shrink=0.6)
    fig.suptitle("Fig. 7: pedestrian points per frame, three directions without (top) and with "
                 "(bottom) the parked car", fontsize=12)
    return fig


# ----------------------------------------------------------------------------- Fig. 8


def fig08_interpolation(tracks: pd.DataFrame, truth: pd.DataFrame,
                        scenes: Mapping[str, Mapping[str, Any]],
                        metrics: Mapping[str, Mapping[str, Any]]) -> Figure:
    """Fig. 8: the hidden part of each car scene's path filled by every method.

    Args:
        tracks: ``data/interpolate/tracks.parquet`` (scene, method, frame, x_m, y_m, observed,
            filled, hidden).
        truth: ``data/simulate/truth.parquet``.
        scenes: ``data/simulate/scenes.json``.
        metrics: ``reports/metrics/interpolate.json`` ({method: {scene: {hidden_mean_m, ...}}}).
    """
    _require(tracks, ("scene", "method", "frame", "x_m", "y_m", "observed", "filled", "hidden"),
             "fig08 tracks")
    names = list(dict.fromkeys(tracks.scene))
    methods = list(dict.fromkeys(tracks.method))
    if not names:
        raise ValueError("fig08_interpolation: no tracks")
    n = len(names)
    fig, axes = _grid(1, n, 5.4 * n, 5.0)
    everything = [_xy(truth[truth.scene.isin(names)]),
                  _xy(tracks[tracks.filled.to_numpy(bool)]) if tracks.filled.any() else None]
    everything += [np.asarray(scenes[s]["car_polygon_xy_m"]) for s in names if scenes[s].get("car_polygon_xy_m")]
    for i, (ax, name) in enumerate(zip(axes.flat, names)):
        info = scenes[name]
        tr = truth[truth.scene == name].sort_values("frame")
        scene_tracks = tracks[tracks.scene == name]
        first = scene_tracks[scene_tracks.method == methods[0]].sort_values("frame")
        obs = first[first.observed.to_numpy(bool)]
        _draw_car(ax, info.get("car_polygon_xy_m"), label=False)
        ax.plot(*_xy(tr).T, color=TRUTH_COLOUR, lw=1.2, ls="--")
        hid = tr.occluded.to_numpy(bool)
        ax.plot(*_xy(tr[hid]).T, ".", color="orange", ms=4, zorder=1)
        ax.plot(*_xy(obs).T, ".", color=POINT_COLOUR, ms=5, zorder=4)
        lines = []
        for method in methods:
            m = scene_tracks[scene_tracks.method == method].sort_values("frame")
            xy = _xy(m)
            filled = m.filled.to_numpy(bool)
            # each filled run starts from the observed point before it (the rollout's origin);
            # where it ends away from the reappearance point, that mismatch is the method's error
            draw = filled | np.roll(filled, -1)
            draw[-1] = filled[-1]
            seg = np.where(draw[:, None], xy, np.nan)
            err = metrics.get(method, {}).get(name, {}).get("hidden_mean_m")
            label = _label(method) + (f": {err:.2f} m" if err is not None else "")
            lines.append(ax.plot(*seg.T, "-", color=_colour(method), lw=1.8, zorder=3, label=label)[0])
            ax.plot(*xy[filled].T, ".", color=_colour(method), ms=3, zorder=3)
        _xy_limits(ax, everything, margin_m=0.4)
        _xy_axes(ax)
        ax.legend(handles=lines, fontsize=8, loc="best", title="mean error on hidden frames",
                  title_fontsize=8)
        _panel(ax, i, scene_title(name, info))
    handles = [
        plt.Line2D([], [], color=TRUTH_COLOUR, lw=1.2, ls="--", label="true path"),
        plt.Line2D([], [], color="orange", marker=".", ls="none", ms=8,
                   label="true position while hidden"),
        plt.Line2D([], [], color=POINT_COLOUR, marker=".", ls="none", ms=8, label="radar points"),
        Polygon(np.zeros((3, 2)), facecolor=CAR_COLOUR, edgecolor="0.35", label="parked car"),
    ] + [plt.Line2D([], [], color=_colour(m), lw=1.8, label=f"{_label(m)}: filled frames") for m in methods]
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=8)
    fig.suptitle("Fig. 8: interpolation of the frames where the pedestrian is hidden behind the car "
                 "(paper: forward LSTM rollout; no number given)", fontsize=12)
    return fig


# ----------------------------------------------------------------------------- Fig. 9


def fig09_prediction(inputs: pd.DataFrame, predictions: pd.DataFrame, truth: pd.DataFrame,
                     scenes: Mapping[str, Mapping[str, Any]],
                     metrics: Mapping[str, Any]) -> Figure:
    """Fig. 9: future path predicted by every method from the (interpolated) input track.

    Args:
        inputs: the input track per scene (scene, frame, x_m, y_m, observed), e.g. the rows of
            ``data/interpolate/tracks.parquet`` of the prediction input method before the
            prediction start.
        predictions: ``data/predict/predictions.parquet`` (scene, method, step, frame, x_m, y_m).
        truth: ``data/simulate/truth.parquet``.
        scenes: ``data/simulate/scenes.json``.
        metrics: ``reports/metrics/evaluate.json`` ({method: {per_scene: {scene: {...}}}}).
    """
    _require(predictions, ("scene", "method", "step", "frame", "x_m", "y_m"), "fig09 predictions")
    _require(inputs, ("scene", "frame", "x_m", "y_m"), "fig09 inputs")
    names = list(dict.fromkeys(predictions.scene))
    methods = list(dict.fromkeys(predictions.method))
    if not names:
        raise ValueError("fig09_prediction: no predictions")
    n = len(names)
    fig, axes = _grid(1, n, 5.4 * n, 5.0)
    everything = [_xy(truth[truth.scene.isin(names)]), _xy(predictions)]
    everything += [np.asarray(scenes[s]["car_polygon_xy_m"]) for s in names if scenes[s].get("car_polygon_xy_m")]
    for i, (ax, name) in enumerate(zip(axes.flat, names)):
        info = scenes[name]
        pred = predictions[predictions.scene == name]
        start = int(pred.frame.min())
        tr = truth[truth.scene == name].sort_values("frame")
        past, future = tr[tr.frame < start], tr[tr.frame >= start - 1]
        inp = inputs[(inputs.scene == name) & (inputs.frame < start)].sort_values("frame")
        _draw_car(ax, info.get("car_polygon_xy_m"), label=False)
        ax.plot(*_xy(past).T, color=TRUTH_COLOUR, lw=0.8)
        ax.plot(*_xy(future).T, color=TRUTH_COLOUR, lw=1.6, ls="--")
        ax.plot(*_xy(future)[-1], "x", color=TRUTH_COLOUR, ms=8, mew=2)
        ax.plot(*_xy(inp).T, "-", color="black", lw=1.2, zorder=4)
        if "observed" in inp.columns:
            seen = inp[inp.observed.to_numpy(bool)]
            ax.plot(*_xy(seen).T, ".", color="black", ms=4, zorder=4)
        lines = []
        for method in methods:
            p = pred[pred.method == method].sort_values("step")
            xy = _xy(p)
            joined = np.vstack([_xy(inp)[-1:], xy]) if len(inp) else xy
            m = metrics.get(method, {}).get("per_scene", {}).get(name, {})
            val, ade = m.get("path_error_mean_m"), m.get("ade_m")
            label = _label(method) + (f": {val:.2f} m" if val is not None else "") + (
                f" (ADE {ade:.2f} m)" if ade is not None else "")
            lines.append(ax.plot(*joined.T, "-", color=_colour(method), lw=1.8, zorder=5, label=label)[0])
            ax.plot(*xy[-1], "x", color=_colour(method), ms=8, mew=2, zorder=5)
        _xy_limits(ax, everything, margin_m=0.4)
        _xy_axes(ax)
        steps = int(pred.step.max())
        ax.legend(handles=lines, fontsize=7.5, loc="best",
                  title=f"paper's metric over {steps} steps (paper {PAPER_PATH_ERROR_MEAN_M} m)",
                  title_fontsize=7.5)
        _panel(ax, i, scene_title(name, info) + f", from frame {start}")
    handles = [
        plt.Line2D([], [], color="black", lw=1.2, marker=".", label="input track (dots: radar points)"),
        plt.Line2D([], [], color=TRUTH_COLOUR, lw=0.8, label="true path"),
        plt.Line2D([], [], color=TRUTH_COLOUR, lw=1.6, ls="--", label="true future"),
        plt.Line2D([], [], color="black", marker="x", ls="none", mew=2, label="end of prediction / truth"),
        Polygon(np.zeros((3, 2)), facecolor=CAR_COLOUR, edgecolor="0.35", label="parked car"),
    ] + [plt.Line2D([], [], color=_colour(m), lw=1.8, label=_label(m)) for m in methods]
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=8)
    fig.suptitle("Fig. 9: future path predicted from the interpolated track (black: input, red: LSTM "
                 "as in the paper)", fontsize=12)
    return fig


# ----------------------------------------------------------------------------- Fig. 10


def fig10_error(curves: pd.DataFrame, metrics: Mapping[str, Any], dt_s: float = 0.1,
                paper_mean_m: float = PAPER_PATH_ERROR_MEAN_M) -> Figure:
    """Fig. 10: Euclidean error against prediction step, averaged over the car scenes.

    (a) the paper's metric (each predicted point's distance to the nearest point of the actual
    path): solid against the simulated truth, dotted against the radar track of the same walk
    without the car (what the paper could measure), with the paper's mean as a reference line;
    (b) the time-aligned error (predicted point k against the true position at step k).

    Args:
        curves: per scene and step (method, scene, step, error_m, path_error_m and optionally
            path_error_radar_m), i.e. ``data/evaluate/error_by_step_per_scene.csv``; averaged
            over scenes here.
        metrics: ``reports/metrics/evaluate.json``.
    """
    _require(curves, ("method", "step", "error_m", "path_error_m"), "fig10 curves")
    cols = [c for c in ("error_m", "path_error_m", "path_error_radar_m") if c in curves.columns]
    mean = curves.groupby(["method", "step"], sort=False)[cols].mean().reset_index()
    methods = list(dict.fromkeys(mean.method))
    fig, axes = _grid(1, 2, 13.0, 4.8)
    ax_a, ax_b = axes[0]
    for method in methods:
        m = mean[mean.method == method].sort_values("step")
        met = metrics.get(method, {})
        c = _colour(method)
        pe, pr = met.get("path_error_mean_m"), met.get("path_error_radar_mean_m")
        ax_a.plot(m.step, m.path_error_m, "-o", ms=3, color=c,
                  label=f"{_label(method)} vs truth" + (f": mean {pe:.2f} m" if pe is not None else ""))
        if "path_error_radar_m" in m and np.isfinite(m.path_error_radar_m).any():
            ax_a.plot(m.step, m.path_error_radar_m, ":", color=c, lw=1.5,
                      label=f"{_label(method)} vs radar track" + (f": mean {pr:.2f} m" if pr is not None else ""))
        ade = met.get("ade_m")
        ax_b.plot(m.step, m.error_m, "-o", ms=3, color=c,
                  label=_label(method) + (f": ADE {ade:.2f} m, FDE {met.get('fde_m', np.nan):.2f} m"
                                          if ade is not None else ""))
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
    _panel(ax_a, 0, "paper's metric: distance to the nearest actual point")
    _panel(ax_b, 1, "time-aligned error: distance to the true position at the same time")
    fig.suptitle(f"Fig. 10: prediction error against step{over}", fontsize=12)
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
    fig, axes = _grid(1, 1, 7.0, 5.6)
    ax = axes[0, 0]
    p_db = _db(power)
    top, floor = float(np.nanmax(p_db)), float(np.nanpercentile(p_db, 5)) - 3.0
    im = ax.pcolormesh(_edges(v), _edges(r), p_db, cmap="viridis",
                       vmin=max(floor, top - dynamic_range_db), vmax=top, shading="flat")
    fig.colorbar(im, ax=ax, label="power (dB re 1 ADC code², summed over channels)")
    if isinstance(detections, pd.DataFrame):
        _require(detections, ("range_m", "velocity_mps"), "fig_recording detections")
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
