"""Reliability figure of predictive distributions: nominal vs empirical ellipse coverage.

Reads the numbers the ETH/UCY stage wrote (``{method: {fold: {"reliability": {"levels",
"coverage"}}}}``, empirical coverage of the ``level`` ellipse of every predicted point on each
test scene after the val-fitted scale); computes nothing. One panel per fold, one line per
method, the diagonal = perfect calibration, and the +/- 2 percentage-point band issue 10 asks
every fold to stay in at 50 / 90 / 95 %.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from matplotlib.figure import Figure

from blindspot.report.style import new_grid, panel_title

__all__ = ["reliability_figure"]

_COLOURS = {"cvm": "#1f77b4", "kalman": "#2ca02c", "lstm": "#d62728", "gru": "#9467bd",
            "mlp": "#ff7f0e", "transformer": "#8c564b"}


def reliability_figure(reliability: Mapping[str, Mapping[str, Mapping[str, Any]]],
                       folds: Sequence[str]) -> Figure:
    """Nominal (x) vs empirical (y) coverage per method, one panel per fold.

    Args:
        reliability: ``{method: {fold: {"reliability": {"levels": [...], "coverage": [...]}}}}``
            (fractions in [0, 1]).
        folds: panels, in order.

    Raises:
        KeyError: a method without the ``reliability`` entry of a fold.
    """
    fig, axes = new_grid(1, len(folds), 2.6 * len(folds), 2.9)
    for i, (ax, fold) in enumerate(zip(axes.ravel(), folds)):
        ax.fill_between([0, 1], [-0.02, 0.98], [0.02, 1.02], color="0.9", lw=0,
                        label="nominal +/- 2 pp")
        ax.plot([0, 1], [0, 1], color="0.4", lw=0.8, ls="--")
        for method, rows in reliability.items():
            if fold not in rows:
                continue
            r = rows[fold]["reliability"]
            ax.plot(r["levels"], r["coverage"], marker="o", ms=3, lw=1.2,
                    color=_COLOURS.get(method, "0.3"), label=method)
        ax.set_xlim(0, 1)
        ax.set_ylim(0, 1)
        ax.set_aspect("equal")
        ax.set_xlabel("nominal coverage")
        if i == 0:
            ax.set_ylabel("empirical coverage (test)")
        panel_title(ax, i, fold)
    axes.ravel()[0].legend(fontsize=7, loc="upper left")
    fig.suptitle("ETH/UCY: reliability of the predicted ellipses (scale fitted on val)",
                 fontsize=9)
    return fig
