"""Shared look of the report's figures: colours, labels, panel titles and the x-y axes helpers.

The figure modules (:mod:`~blindspot.report.radar_figures`, :mod:`~blindspot.report.path_figures`,
:mod:`~blindspot.report.error_figures`) draw with these, so every figure follows the same
conventions:

- Radar at the origin looking along +y; x to the right (metres). x-y panels use equal scales.
- One colour per method in every figure (:data:`METHOD_COLOURS`): the LSTM red (as in the
  paper's Fig. 9), constant velocity blue, Kalman green, our two-sided interpolation purple,
  our direct multi-step LSTM orange;
  radar points black, simulated truth grey (dashed where it is the future to be predicted).
- Panels are labelled (a), (b), ... as in the paper; the paper's number is quoted beside ours
  where the paper gives one (:mod:`blindspot.report.paper_values`).

Importing this module selects matplotlib's Agg backend, so no display is needed.
"""

from __future__ import annotations

import string
from collections.abc import Mapping, Sequence
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
    "TRUTH_COLOUR",
    "POINT_COLOUR",
    "CAR_COLOUR",
    "TIME_CMAP",
    "method_colour",
    "method_label",
    "panel_title",
    "scene_title",
    "draw_car",
    "draw_radar",
    "set_xy_limits",
    "radar_direction",
    "add_note",
    "label_xy_axes",
    "to_db",
    "cell_edges",
    "xy_of",
    "new_grid",
]

METHOD_COLOURS: dict[str, str] = {
    "lstm": "#d62728",               # red: the paper's predictions
    "forward": "#d62728",            # the paper's interpolation is the same LSTM rolled forward
    "constant_velocity": "#1f77b4",
    "kalman": "#2ca02c",
    "bidirectional": "#9467bd",
    "lstm_direct": "#ff7f0e",        # orange: the direct multi-step LSTM (blindspot.traj.direct)
}
METHOD_LABELS: dict[str, str] = {
    "lstm": "LSTM (paper)",
    "forward": "forward LSTM (paper)",
    "constant_velocity": "constant velocity",
    "kalman": "Kalman (CV)",
    "bidirectional": "two-sided LSTM (ours)",
    "lstm_direct": "direct LSTM (ours)",
}
TRUTH_COLOUR = "0.45"
POINT_COLOUR = "black"
CAR_COLOUR = "0.80"
TIME_CMAP = "jet"  # blue (start) -> red (end), as the paper's Fig. 6e


def method_colour(method: str) -> str:
    """The colour of ``method`` in every figure (grey for a method without one)."""
    return METHOD_COLOURS.get(method, "0.3")


def method_label(method: str) -> str:
    """The legend label of ``method`` ("kalman" -> "Kalman (CV)"; unknown: underscores to spaces)."""
    return METHOD_LABELS.get(method, method.replace("_", " "))


def panel_title(ax: Axes, index: int, title: str) -> None:
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


def draw_car(ax: Axes, polygon: Sequence[Sequence[float]] | np.ndarray | None, label: bool = True) -> None:
    """The parked car's footprint (N, 2) in metres as a grey patch under the data; None: nothing."""
    if polygon is None:
        return
    poly = np.asarray(polygon, dtype=float)
    ax.add_patch(Polygon(poly, closed=True, facecolor=CAR_COLOUR, edgecolor="0.35", lw=1.0,
                         zorder=0, label="parked car" if label else None))


def draw_radar(ax: Axes, label: bool = True) -> None:
    """The radar at the origin, a black triangle."""
    ax.plot([0.0], [0.0], marker="^", ms=9, color="black", ls="none", zorder=5,
            label="radar" if label else None)


def set_xy_limits(ax: Axes, chunks: Sequence[np.ndarray | None], margin_m: float = 0.6,
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


def radar_direction(ax: Axes) -> str:
    """"radar: 12 m ↘" (distance and direction from the panel centre to the origin)."""
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    c = -np.array([(x0 + x1) / 2, (y0 + y1) / 2])
    arrows = "→↗↑↖←↙↓↘"
    k = int(np.round(np.degrees(np.arctan2(c[1], c[0])) / 45.0)) % 8
    return f"radar (origin): {np.hypot(*c):.0f} m {arrows[k]}"


def add_note(ax: Axes, text: str, fontsize: float = 8) -> None:
    """A text box placed where it hides the least data (matplotlib's legend "best" placement)."""
    leg = ax.legend(handles=[], title=text, loc="best", title_fontsize=fontsize, framealpha=0.9)
    leg._legend_box.align = "left"  # noqa: SLF001 - left-aligned multi-line note
    ax.add_artist(leg)


def label_xy_axes(ax: Axes) -> None:
    """Axis labels and grid of an x-y panel (metres, y along the boresight)."""
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m, boresight)")
    ax.grid(True, lw=0.4, alpha=0.5)


def to_db(power: np.ndarray) -> np.ndarray:
    """10 log10 of a power array (any shape), floored at the smallest positive float."""
    p = np.asarray(power, dtype=float)
    floor = np.finfo(float).tiny
    return 10.0 * np.log10(np.maximum(p, floor))


def cell_edges(axis: np.ndarray) -> np.ndarray:
    """Cell edges of a uniformly (or nearly) spaced axis of cell centres."""
    a = np.asarray(axis, dtype=float)
    if a.size == 1:
        return np.array([a[0] - 0.5, a[0] + 0.5])
    mid = 0.5 * (a[1:] + a[:-1])
    return np.concatenate([[a[0] - (mid[0] - a[0])], mid, [a[-1] + (a[-1] - mid[-1])]])


def xy_of(df: pd.DataFrame, x: str = "x_m", y: str = "y_m") -> np.ndarray:
    """(N, 2) float positions in metres from the columns ``x`` and ``y`` of ``df``."""
    return df[[x, y]].to_numpy(dtype=float)


def new_grid(n_rows: int, n_cols: int, width: float, height: float) -> tuple[Figure, np.ndarray]:
    """A figure of ``width`` x ``height`` inches with an (n_rows, n_cols) array of axes, constrained layout."""
    fig, axes = plt.subplots(n_rows, n_cols, figsize=(width, height), squeeze=False,
                             layout="constrained")
    return fig, axes
