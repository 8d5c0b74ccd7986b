"""The pipeline's DVC plots: one line per series (method or ensemble member), with a legend.

DVC's own renderer draws a long table (``method, step, error_m``) as one zigzag line per revision
and loads vega from a CDN. So the two plots are drawn here, from wide tables (one column per
series), as SVG images: ``dvc plots show`` embeds images as they are (no script, no internet) and
``dvc plots diff`` puts one revision's image beside another's. Legend and axis labels stay text
in the SVG (``svg.fonttype: none``), readable by a test and by a search; ids are salted with a
constant, so the same data give the same bytes.
"""

from __future__ import annotations

from collections.abc import Mapping

import matplotlib

matplotlib.use("Agg")

import pandas as pd  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from blindspot.report.style import method_colour, method_label  # noqa: E402
from blindspot.tables import check_columns  # noqa: E402

__all__ = ["SVG_RC", "history_wide", "error_by_step_wide", "series_figure"]

SVG_RC: Mapping[str, object] = {"svg.fonttype": "none", "svg.hashsalt": "blindspot"}


def history_wide(history: pd.DataFrame, value: str = "val_rmse_m") -> pd.DataFrame:
    """The training history (one row per member and epoch; ``member``, ``seed``, ``epoch`` and
    ``value`` columns) as one row per epoch and one column per member, named
    ``member <i> (seed <s>)``; a history without ``member`` is one series, ``value``."""
    check_columns(history, ("epoch", value), "training history", who="history_wide")
    if "member" not in history:
        return history[["epoch", value]].reset_index(drop=True)
    names = {m: f"member {m}" + (f" (seed {s})" if s is not None else "")
             for m, s in history.groupby("member", sort=True)["seed"].first().items()} \
        if "seed" in history else {m: f"member {m}" for m in history["member"].unique()}
    wide = history.pivot(index="epoch", columns="member", values=value).sort_index()
    wide.columns = [names[m] for m in wide.columns]
    return wide.reset_index()


def error_by_step_wide(curve: pd.DataFrame, value: str = "error_m") -> pd.DataFrame:
    """The error per prediction step (``method``, ``step``, ``time_s``, ``value``; one row per
    method and step) as one row per step (``step``, ``time_s``) and one column per method, in
    the order the methods first appear."""
    check_columns(curve, ("method", "step", "time_s", value), "error per prediction step",
                  who="error_by_step_wide")
    order = list(dict.fromkeys(curve["method"]))
    wide = curve.pivot(index=["step", "time_s"], columns="method", values=value)
    return wide[order].reset_index().rename_axis(columns=None)


def series_figure(wide: pd.DataFrame, x: str, *, xlabel: str, ylabel: str, title: str,
                  methods: bool = False) -> Figure:
    """One line per column of ``wide`` but ``x`` (and ``step``/``time_s``, when not ``x``),
    against ``x``, with a legend entry each; ``methods``: colours and labels of
    :mod:`~blindspot.report.style` (the columns are method names)."""
    series = [c for c in wide.columns if c not in {x, "step", "time_s"}]
    if not series:
        raise ValueError(f"plot {title!r}: no series besides the x column {x!r} "
                         f"(columns: {list(wide.columns)})")
    fig = Figure(figsize=(7.0, 4.2))
    ax = fig.subplots()
    for name in series:
        style = {"color": method_colour(name), "label": method_label(name)} if methods \
            else {"label": str(name)}
        ax.plot(wide[x], wide[name], marker="o", markersize=2.5, linewidth=1.4, **style)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(title="method" if methods else "series", fontsize=8)
    fig.tight_layout()
    return fig
