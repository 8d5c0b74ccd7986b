"""The paper's path figures: LSTM rollouts (Fig. 4), the scenes' points (Fig. 7), the interpolation
of the hidden frames (Fig. 8) and the future-path predictions (Fig. 9).

Every function is pure: DataFrames and dicts of the pipeline's artifacts in (``data/`` and
``reports/metrics/``), a matplotlib :class:`~matplotlib.figure.Figure` out; nothing is computed
beyond choosing what to draw. The stages save the figures (:func:`blindspot.io.save_figure`).
The look (colours per method, panel titles, x-y axes) is :mod:`blindspot.report.style`'s.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.patches import Polygon

from blindspot.report.paper_values import PATH_ERROR_MEAN_M, VAL_RMSE
from blindspot.report.style import (
    CAR_COLOUR,
    POINT_COLOUR,
    TIME_CMAP,
    TRUTH_COLOUR,
    add_note,
    draw_car,
    draw_radar,
    label_xy_axes,
    method_colour,
    method_label,
    new_grid,
    panel_title,
    radar_direction,
    scene_title,
    set_xy_limits,
    xy_of,
)
from blindspot.tables import check_columns

__all__ = [
    "PathCase",
    "fig04_lstm_paths",
    "fig07_scenes",
    "fig08_interpolation",
    "fig09_prediction",
]


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
    ``val_rmse_m`` (one-step validation RMSE) goes into the figure title beside the paper's
    (:data:`~blindspot.report.paper_values.VAL_RMSE`).
    """
    if not cases:
        raise ValueError("fig04_lstm_paths: no cases to draw")
    n = len(cases)
    n_cols = min(n, 3)
    n_rows = int(np.ceil(n / n_cols))
    fig, axes = new_grid(n_rows, n_cols, 4.4 * n_cols, 4.3 * n_rows)
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
            ax.plot(*np.vstack([hist[seen][-1:], pred]).T, "-", color=method_colour("lstm"), lw=1.8,
                    label="LSTM prediction, autoregressive")[0],
        ]
        ax.plot(*pred[-1], "x", color=method_colour("lstm"), ms=8, mew=2)
        ax.plot(*fut[-1], "x", color=TRUTH_COLOUR, ms=8, mew=2)
        handles = handles or h
        set_xy_limits(ax, [hist, htrue, pred, fut], margin_m=0.8, square=True)
        label_xy_axes(ax)
        ade_txt = f"\nADE {case.ade_m:.2f} m" if case.ade_m is not None else ""
        add_note(ax, f"{seen.sum()}/{W} points seen{ade_txt}\n{radar_direction(ax)}")
        panel_title(ax, i, f"{case.motion}: {case.split} path {case.path_id}, points {case.start}-{case.start + W - 1}")
    free = list(axes.flat)[n:]
    for ax in free:
        ax.set_axis_off()
    x_mark = [plt.Line2D([], [], color=method_colour("lstm"), marker="x", ls="none", mew=2,
                         label=f"last predicted / true point ({len(cases[0].prediction)} steps, "
                               f"{len(cases[0].prediction) * dt_s:g} s)")]
    if free:
        free[0].legend(handles=handles + x_mark, loc="center", fontsize=9, frameon=False)
    else:
        fig.legend(handles=handles + x_mark, loc="lower center", ncol=3, fontsize=8)
    rmse = "" if val_rmse_m is None else f"; one-step validation RMSE {val_rmse_m:.3f} m (paper {VAL_RMSE.value})"
    fig.suptitle("Fig. 4: LSTM predictions on simulated paths unseen in training (window of "
                 f"{len(cases[0].history)} radar points, each prediction fed back){rmse}", fontsize=11)
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
    check_columns(points, ("scene", "frame", "time_s", "x_m", "y_m"), "fig07 points",
                  who="fig07_scenes")
    check_columns(truth, ("scene", "frame", "x_m", "y_m", "occluded"), "fig07 truth",
                  who="fig07_scenes")
    if not pairs:
        raise ValueError("fig07_scenes: no scene pairs")
    n = len(pairs)
    fig, axes = new_grid(2, n, 4.8 * n, 9.0)
    names = [name for pair in pairs for name in pair]
    all_xy = [xy_of(truth[truth.scene.isin(names)]), xy_of(points[points.scene.isin(names)]), np.zeros((1, 2))]
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
            draw_car(ax, info.get("car_polygon_xy_m"), label=False)
            ax.plot(*xy_of(tr).T, color=TRUTH_COLOUR, lw=0.8)
            hid = tr.occluded.to_numpy(bool)
            if hid.any():
                ax.plot(*xy_of(tr[hid]).T, ".", color="orange", ms=5, zorder=1)
            sc = ax.scatter(pts.x_m, pts.y_m, c=pts.time_s, cmap=TIME_CMAP, vmin=0, vmax=t_max,
                            s=12, zorder=3)
            draw_radar(ax, label=False)
            set_xy_limits(ax, all_xy)
            label_xy_axes(ax)
            hidden_txt = f"\nhidden behind the car: {hid.sum()} frames" if hid.any() else ""
            add_note(ax, f"radar points in {len(pts)}/{len(tr)} frames{hidden_txt}")
            panel_title(ax, row * n + col, scene_title(name, info))
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
    check_columns(tracks, ("scene", "method", "frame", "x_m", "y_m", "observed", "filled",
                           "hidden"), "fig08 tracks", who="fig08_interpolation")
    names = list(dict.fromkeys(tracks.scene))
    methods = list(dict.fromkeys(tracks.method))
    if not names:
        raise ValueError("fig08_interpolation: no tracks")
    n = len(names)
    fig, axes = new_grid(1, n, 5.4 * n, 5.0)
    everything = [xy_of(truth[truth.scene.isin(names)]),
                  xy_of(tracks[tracks.filled.to_numpy(bool)]) if tracks.filled.any() else None]
    everything += [np.asarray(scenes[s]["car_polygon_xy_m"]) for s in names if scenes[s].get("car_polygon_xy_m")]
    for i, (ax, name) in enumerate(zip(axes.flat, names)):
        info = scenes[name]
        tr = truth[truth.scene == name].sort_values("frame")
        scene_tracks = tracks[tracks.scene == name]
        first = scene_tracks[scene_tracks.method == methods[0]].sort_values("frame")
        obs = first[first.observed.to_numpy(bool)]
        draw_car(ax, info.get("car_polygon_xy_m"), label=False)
        ax.plot(*xy_of(tr).T, color=TRUTH_COLOUR, lw=1.2, ls="--")
        hid = tr.occluded.to_numpy(bool)
        ax.plot(*xy_of(tr[hid]).T, ".", color="orange", ms=4, zorder=1)
        ax.plot(*xy_of(obs).T, ".", color=POINT_COLOUR, ms=5, zorder=4)
        lines = []
        for method in methods:
            m = scene_tracks[scene_tracks.method == method].sort_values("frame")
            xy = xy_of(m)
            filled = m.filled.to_numpy(bool)
            # each filled run starts from the observed point before it (the rollout's origin);
            # where it ends away from the reappearance point, that mismatch is the method's error
            draw = filled | np.roll(filled, -1)
            draw[-1] = filled[-1]
            seg = np.where(draw[:, None], xy, np.nan)
            err = metrics.get(method, {}).get(name, {}).get("hidden_mean_m")
            label = method_label(method) + (f": {err:.2f} m" if err is not None else "")
            lines.append(ax.plot(*seg.T, "-", color=method_colour(method), lw=1.8, zorder=3, label=label)[0])
            ax.plot(*xy[filled].T, ".", color=method_colour(method), ms=3, zorder=3)
        set_xy_limits(ax, everything, margin_m=0.4)
        label_xy_axes(ax)
        ax.legend(handles=lines, fontsize=8, loc="best", title="mean error on hidden frames",
                  title_fontsize=8)
        panel_title(ax, i, scene_title(name, info))
    handles = [
        plt.Line2D([], [], color=TRUTH_COLOUR, lw=1.2, ls="--", label="true path"),
        plt.Line2D([], [], color="orange", marker=".", ls="none", ms=8,
                   label="true position while hidden"),
        plt.Line2D([], [], color=POINT_COLOUR, marker=".", ls="none", ms=8, label="radar points"),
        Polygon(np.zeros((3, 2)), facecolor=CAR_COLOUR, edgecolor="0.35", label="parked car"),
    ] + [plt.Line2D([], [], color=method_colour(m), lw=1.8, label=f"{method_label(m)}: filled frames") for m in methods]
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=8)
    fig.suptitle("Fig. 8: interpolation of the frames where the pedestrian is hidden behind the car "
                 "(paper: forward LSTM rollout; no number given)", fontsize=12)
    return fig


# ----------------------------------------------------------------------------- Fig. 9


# Squared Mahalanobis radius of the 90 % ellipse of a 2-D Gaussian: the chi-square(2) quantile
# -2 ln(1 - 0.9) (e.g. Bar-Shalom, Li & Kirubarajan 2001, section 1.4.17).
ELLIPSE_LEVEL = 0.9
ELLIPSE_R2 = -2.0 * np.log(1.0 - ELLIPSE_LEVEL)


def draw_ellipses(ax, pred: pd.DataFrame, colour: str, every: int = 5) -> None:
    """The 90 % ellipse of every ``every``-th predicted point (and the last), from the
    ``cov_xx_m2``, ``cov_xy_m2``, ``cov_yy_m2`` columns of the predictions where present."""
    from matplotlib.patches import Ellipse

    if not {"cov_xx_m2", "cov_xy_m2", "cov_yy_m2"} <= set(pred.columns):
        return
    p = pred.sort_values("step")
    keep = (p.step.to_numpy() % every == 0) | (p.step.to_numpy() == p.step.max())
    p = p[keep & np.isfinite(p.cov_xx_m2.to_numpy())]
    if p.empty:
        return
    cov = np.stack([np.stack([p.cov_xx_m2, p.cov_xy_m2], -1),
                    np.stack([p.cov_xy_m2, p.cov_yy_m2], -1)], -2)     # (n, 2, 2)
    w, v = np.linalg.eigh(cov)                                          # ascending
    for (x, y), (minor, major), vec in zip(xy_of(p), w, v):
        ax.add_patch(Ellipse((x, y), 2 * np.sqrt(ELLIPSE_R2 * major),
                             2 * np.sqrt(ELLIPSE_R2 * minor),
                             angle=np.degrees(np.arctan2(vec[1, 1], vec[0, 1])),
                             facecolor="none", edgecolor=colour, lw=0.8, alpha=0.7, zorder=4))


def fig09_prediction(inputs: pd.DataFrame, predictions: pd.DataFrame, truth: pd.DataFrame,
                     scenes: Mapping[str, Mapping[str, Any]],
                     metrics: Mapping[str, Any]) -> Figure:
    """Fig. 9: future path predicted by every method from the (interpolated) input track.

    Args:
        inputs: the input track per scene (scene, frame, x_m, y_m, observed), e.g. the rows of
            ``data/interpolate/tracks.parquet`` of the prediction input method before the
            prediction start.
        predictions: ``data/predict/predictions.parquet`` (scene, method, step, frame, x_m, y_m;
            with cov_xx_m2, cov_xy_m2, cov_yy_m2 the 90 % ellipses of every 5th step are drawn).
        truth: ``data/simulate/truth.parquet``.
        scenes: ``data/simulate/scenes.json``.
        metrics: ``reports/metrics/evaluate.json`` ({method: {per_scene: {scene: {...}}}}).
    """
    check_columns(predictions, ("scene", "method", "step", "frame", "x_m", "y_m"),
                  "fig09 predictions", who="fig09_prediction")
    check_columns(inputs, ("scene", "frame", "x_m", "y_m"), "fig09 inputs", who="fig09_prediction")
    names = list(dict.fromkeys(predictions.scene))
    methods = list(dict.fromkeys(predictions.method))
    if not names:
        raise ValueError("fig09_prediction: no predictions")
    n = len(names)
    fig, axes = new_grid(1, n, 5.4 * n, 5.0)
    everything = [xy_of(truth[truth.scene.isin(names)]), xy_of(predictions)]
    everything += [np.asarray(scenes[s]["car_polygon_xy_m"]) for s in names if scenes[s].get("car_polygon_xy_m")]
    for i, (ax, name) in enumerate(zip(axes.flat, names)):
        info = scenes[name]
        pred = predictions[predictions.scene == name]
        start = int(pred.frame.min())
        tr = truth[truth.scene == name].sort_values("frame")
        past, future = tr[tr.frame < start], tr[tr.frame >= start - 1]
        inp = inputs[(inputs.scene == name) & (inputs.frame < start)].sort_values("frame")
        draw_car(ax, info.get("car_polygon_xy_m"), label=False)
        ax.plot(*xy_of(past).T, color=TRUTH_COLOUR, lw=0.8)
        ax.plot(*xy_of(future).T, color=TRUTH_COLOUR, lw=1.6, ls="--")
        ax.plot(*xy_of(future)[-1], "x", color=TRUTH_COLOUR, ms=8, mew=2)
        ax.plot(*xy_of(inp).T, "-", color="black", lw=1.2, zorder=4)
        if "observed" in inp.columns:
            seen = inp[inp.observed.to_numpy(bool)]
            ax.plot(*xy_of(seen).T, ".", color="black", ms=4, zorder=4)
        lines = []
        for method in methods:
            p = pred[pred.method == method].sort_values("step")
            xy = xy_of(p)
            joined = np.vstack([xy_of(inp)[-1:], xy]) if len(inp) else xy
            m = metrics.get(method, {}).get("per_scene", {}).get(name, {})
            val, ade = m.get("path_error_mean_m"), m.get("ade_m")
            label = method_label(method) + (f": {val:.2f} m" if val is not None else "") + (
                f" (ADE {ade:.2f} m)" if ade is not None else "")
            lines.append(ax.plot(*joined.T, "-", color=method_colour(method), lw=1.8, zorder=5, label=label)[0])
            draw_ellipses(ax, p, method_colour(method))
            ax.plot(*xy[-1], "x", color=method_colour(method), ms=8, mew=2, zorder=5)
        set_xy_limits(ax, everything, margin_m=0.4)
        label_xy_axes(ax)
        steps = int(pred.step.max())
        ax.legend(handles=lines, fontsize=7.5, loc="best",
                  title=f"paper's metric over {steps} steps (paper {PATH_ERROR_MEAN_M.value} m)",
                  title_fontsize=7.5)
        panel_title(ax, i, scene_title(name, info) + f", from frame {start}")
    handles = [
        plt.Line2D([], [], color="black", lw=1.2, marker=".", label="input track (dots: radar points)"),
        plt.Line2D([], [], color=TRUTH_COLOUR, lw=0.8, label="true path"),
        plt.Line2D([], [], color=TRUTH_COLOUR, lw=1.6, ls="--", label="true future"),
        plt.Line2D([], [], color="black", marker="x", ls="none", mew=2, label="end of prediction / truth"),
        Polygon(np.zeros((3, 2)), facecolor=CAR_COLOUR, edgecolor="0.35", label="parked car"),
    ] + [plt.Line2D([], [], color=method_colour(m), lw=1.8, label=method_label(m)) for m in methods]
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=8)
    fig.suptitle("Fig. 9: future path predicted from the interpolated track (black: input, red: LSTM "
                 "as in the paper; ellipses: 90 % of the calibrated predictive distribution, "
                 "every 5th step)", fontsize=12)
    return fig
