"""The AEB operating point chosen on one Monte-Carlo draw and read on another (issue 40).

Issue 40's goal is a pair: the share of intruding scenes avoided once the child is visible
(``avoided_after_visible_rate``) at least 0.80 *at* a false-activation rate of at most 3 %. A
fixed AEB threshold (``warning.aeb_threshold``) meets the second half only by chance. The way a
detector is set for a false-alarm budget is Neyman and Pearson's (1933): among the thresholds
whose false-activation rate on the tuning draw is at most the target
(``warning.false_activation_target``), the one that avoids most once the child is visible; the
held-out draw is then read at that threshold (:func:`operating_point_at`), so its rates are
those of a setting chosen elsewhere. Where no threshold of the tuning draw keeps to the target,
the choice is the threshold with the fewest false activations (then the most avoided), marked
``target_met: false``. Ties go to the larger threshold (the same rates on the tuning draw, fewer
activations in expectation).

The curves are :func:`blindspot.safety.evaluation.operating_curve`'s: one row per threshold with
``threshold``, ``avoided_rate``, ``avoided_after_visible_rate`` and ``false_activation_rate``.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from blindspot.arrays import check_number
from blindspot.safety.evaluation import wilson

__all__ = ["OPERATING_COLUMNS", "choose_operating_point", "operating_point_at", "choose_in_block",
           "read_in_block"]

#: The columns of an operating characteristic these functions read.
OPERATING_COLUMNS = ("threshold", "avoided_rate", "avoided_after_visible_rate",
                     "false_activation_rate")


def _unit_interval(value, name: str, who: str) -> float:
    """``value`` checked to be a number in (0, 1)."""
    x = check_number(value, name, gt=0.0, who=who)
    if x >= 1.0:
        raise ValueError(f"{who}: {name}: expected a number in (0, 1), found {value!r}")
    return x


def _checked(curve: pd.DataFrame, who: str) -> pd.DataFrame:
    if not isinstance(curve, pd.DataFrame):
        raise TypeError(f"{who}: curve: expected a DataFrame (operating_curve's), found "
                        f"{type(curve).__name__}")
    missing = [c for c in OPERATING_COLUMNS if c not in curve.columns]
    if missing:
        raise KeyError(f"{who}: curve: missing columns {missing}; expected "
                       f"{list(OPERATING_COLUMNS)}")
    if curve.empty or curve[list(OPERATING_COLUMNS)].isna().any().any():
        raise ValueError(f"{who}: curve: expected at least one threshold and no missing rate "
                         f"(a draw with intruding and non-intruding scenes), found "
                         f"{len(curve)} rows, {int(curve.isna().any(axis=1).sum())} with NaN")
    if curve.threshold.duplicated().any():
        raise ValueError(f"{who}: curve: expected one row per threshold, found duplicates of "
                         f"{sorted(curve.threshold[curve.threshold.duplicated()].unique())[:3]}")
    return curve


def choose_operating_point(curve: pd.DataFrame, false_activation_target: float) -> dict:
    """The tuning draw's AEB threshold (module docstring) and its rates there.

    Args:
        curve: one predictor's operating characteristic on the tuning draw
            (:data:`OPERATING_COLUMNS`).
        false_activation_target: the largest false-activation rate allowed, in (0, 1).

    Returns:
        ``{"aeb_threshold", "false_activation_target", "target_met", "avoided_rate",
        "avoided_after_visible_rate", "false_activation_rate"}`` (rates on the tuning draw).

    Raises:
        TypeError, KeyError, ValueError: a curve that is not a DataFrame, lacks a column, is
            empty, holds NaN or repeats a threshold; a target outside (0, 1).
    """
    who = "choose_operating_point"
    _unit_interval(false_activation_target, "false_activation_target", who)
    c = _checked(curve, who)
    fa = c.false_activation_rate.to_numpy(float)
    av = c.avoided_after_visible_rate.to_numpy(float)
    thr = c.threshold.to_numpy(float)
    ok = fa <= false_activation_target + 1e-12
    # lexsort: the last key is the primary one; every key ascending, so negate to prefer large
    order = (np.lexsort((-thr, fa, -av, ~ok)) if ok.any()
             else np.lexsort((-thr, -av, fa)))
    best = c.iloc[int(order[0])]
    return {"aeb_threshold": float(best.threshold),
            "false_activation_target": float(false_activation_target),
            "target_met": bool(ok.any()),
            "avoided_rate": float(best.avoided_rate),
            "avoided_after_visible_rate": float(best.avoided_after_visible_rate),
            "false_activation_rate": float(best.false_activation_rate)}


def operating_point_at(curve: pd.DataFrame, threshold: float, n_intruding: int,
                       n_non_intruding: int) -> dict:
    """The rates of ``curve`` (one predictor's operating characteristic, e.g. the held-out
    draw's) at the AEB ``threshold`` chosen on another draw, with their Wilson 95 % intervals
    (the counts are the rates times ``n_intruding`` / ``n_non_intruding``, the draw's scenes).

    Returns:
        ``{"aeb_threshold", "avoided_rate", "avoided_rate_ci95", "avoided_after_visible_rate",
        "avoided_after_visible_rate_ci95", "false_activation_rate",
        "false_activation_rate_ci95"}``.

    Raises:
        TypeError, KeyError, ValueError: a bad curve (as :func:`choose_operating_point`), a
            threshold not on the curve's grid (the draws must sweep the same thresholds), scene
            counts below 1, or rates that are not whole counts of those scenes.
    """
    who = "operating_point_at"
    c = _checked(curve, who)
    _unit_interval(threshold, "threshold", who)
    for name, n in (("n_intruding", n_intruding), ("n_non_intruding", n_non_intruding)):
        if isinstance(n, bool) or not (isinstance(n, (int, np.integer)) and n >= 1):
            raise ValueError(f"{who}: {name}: expected an integer >= 1, found {n!r}")
    at = np.flatnonzero(np.isclose(c.threshold.to_numpy(float), threshold, rtol=0, atol=1e-9))
    if at.size != 1:
        raise ValueError(f"{who}: threshold: expected one of the curve's thresholds "
                         f"({c.threshold.min():g}..{c.threshold.max():g}, {len(c)} of them; both "
                         f"draws sweep warning.n_thresholds), found {threshold!r}")
    row = c.iloc[int(at[0])]
    out: dict = {"aeb_threshold": float(row.threshold)}
    for key, n in (("avoided_rate", n_intruding), ("avoided_after_visible_rate", n_intruding),
                   ("false_activation_rate", n_non_intruding)):
        k = float(row[key]) * n
        if abs(k - round(k)) > 1e-6:
            raise ValueError(f"{who}: curve: {key} {float(row[key])!r} is not a whole count of "
                             f"{n} scenes (n_intruding / n_non_intruding of another draw?)")
        out[key] = float(row[key])
        out[f"{key}_ci95"] = wilson(int(round(k)), int(n))
    return out


def _curve_of(curves: pd.DataFrame, predictor: str, who: str) -> pd.DataFrame:
    """The tracker input's operating characteristic of ``predictor`` in an assessment's curves
    (columns ``input`` and ``predictor`` beside :data:`OPERATING_COLUMNS`)."""
    missing = [c for c in ("input", "predictor") if c not in curves.columns]
    if missing:
        raise KeyError(f"{who}: curves: missing columns {missing} (assess()'s curves)")
    c = curves[(curves.input == "tracker") & (curves.predictor == predictor)]
    if c.empty:
        raise ValueError(f"{who}: curves: no tracker-input curve of predictor {predictor!r} "
                         f"(found {sorted(curves.predictor.unique())})")
    return c


def choose_in_block(block: dict, curves: pd.DataFrame, false_activation_target: float) -> dict:
    """A copy of a draw's block (:func:`blindspot.safety.draws.draw_block` of the tuning draw)
    with each predictor's ``operating_point`` (:func:`choose_operating_point` on its tracker
    curve in ``curves``)."""
    out = dict(block)
    for name, m in block.items():
        if isinstance(m, dict):
            out[name] = {**m, "operating_point": choose_operating_point(
                _curve_of(curves, name, "choose_in_block"), false_activation_target)}
    return out


def read_in_block(block: dict, curves: pd.DataFrame, tuning: dict) -> dict:
    """A copy of a draw's block (the held-out draw's) with each predictor's
    ``at_tuning_operating_point``: :func:`operating_point_at` its tracker curve in ``curves``,
    at the threshold the tuning draw's block (``tuning``, of :func:`choose_in_block`) chose for
    it. Raises KeyError naming a predictor the tuning block has no operating point for."""
    out = dict(block)
    for name, m in block.items():
        if not isinstance(m, dict):
            continue
        chosen = (tuning.get(name) or {}).get("operating_point")
        if not chosen:
            raise KeyError(f"read_in_block: tuning: no operating_point for predictor {name!r} "
                           "(rerun the safety_tuning stage with the same warning.predictors)")
        out[name] = {**m, "at_tuning_operating_point": {
            **operating_point_at(_curve_of(curves, name, "read_in_block"),
                                 chosen["aeb_threshold"], block["n_intruding"],
                                 block["n_non_intruding"]),
            "false_activation_target": chosen["false_activation_target"]}}
    return out
