"""The AEB operating point chosen on one Monte-Carlo draw and read on another (issue 40).

Issue 40's goal is a pair: the share of intruding scenes avoided once the child is visible
(``avoided_after_visible_rate``) at least 0.80 *at* a false-activation rate of at most 3 %. A
fixed AEB threshold (``warning.aeb_threshold``) meets the second half only by chance. The way a
detector is set for a false-alarm budget is Neyman and Pearson's (1933): among the thresholds
whose false-activation rate on the tuning draw is at most the target
(``warning.false_activation_target``), the one that avoids most once the child is visible; the
held-out draw is then read at that threshold (:func:`operating_point_at`,
:func:`operating_blocks`), so its rates are those of a setting chosen elsewhere. Where no
threshold of the tuning draw keeps to the target, the choice is the threshold with the fewest
false activations (then the most avoided), marked ``target_met: false``. Ties go to the larger
threshold: on any draw a larger threshold requests in a subset of the scenes a smaller one
does, so it false-activates no more often. The rule uses the point estimate of the tuning
draw's false-activation rate, not an upper bound, so nothing keeps the held-out rate at the
chosen threshold within the target: read ``false_activation_within_target`` with its
interval.

The curves are :func:`blindspot.safety.evaluation.operating_curve`'s: one row per threshold with
``threshold``, ``avoided_rate``, ``avoided_after_visible_rate`` and ``false_activation_rate``;
the draws keep them in their blocks (:func:`blindspot.safety.draws.draw_block`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from blindspot.arrays import check_count, check_number
from blindspot.safety.draws import draw_curve
from blindspot.safety.evaluation import wilson
from blindspot.tables import check_columns

__all__ = ["OPERATING_COLUMNS", "choose_operating_point", "operating_point_at",
           "operating_blocks"]

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
    check_columns(curve, OPERATING_COLUMNS, "curve", error=KeyError, who=who,
                  note=f"expected {list(OPERATING_COLUMNS)}")
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
        ``{"aeb_threshold", "false_activation_target", "target_met", "top_of_grid",
        "avoided_rate", "avoided_after_visible_rate", "false_activation_rate"}`` (rates on the
        tuning draw; ``top_of_grid``: the largest threshold swept was chosen, so the grid may
        stop short of a better one).

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
            "top_of_grid": bool(best.threshold == thr.max()),
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
    check_count(n_intruding, "n_intruding", ge=1, who=who)
    check_count(n_non_intruding, "n_non_intruding", ge=1, who=who)
    at = np.flatnonzero(np.isclose(c.threshold.to_numpy(float), threshold, rtol=0, atol=1e-9))
    if at.size != 1:
        raise ValueError(f"{who}: threshold: expected one of the curve's thresholds "
                         f"({c.threshold.min():g}..{c.threshold.max():g}, {len(c)} of them; both "
                         f"draws sweep warning.n_thresholds and tail_thresholds), "
                         f"found {threshold!r}")
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


def _block_counts(block, name: str) -> tuple[int, int]:
    if not isinstance(block, dict):
        raise TypeError(f"operating_blocks: {name}: expected a draw block (a dict of "
                        f"blindspot.safety.draws.draw_block), found {type(block).__name__}")
    missing = [k for k in ("seed", "n_intruding", "n_non_intruding") if k not in block]
    if missing:
        raise KeyError(f"operating_blocks: {name}: missing {missing} (a draw block of "
                       f"blindspot.safety.draws.draw_block?)")
    return block["n_intruding"], block["n_non_intruding"]


def operating_blocks(tuning: dict, held_out: dict, false_activation_target: float
                     ) -> tuple[dict, dict]:
    """The tuning and held-out draws' blocks for ``safety.json``: each predictor's AEB
    operating point chosen on the tuning draw (``operating_point``: :func:`choose_operating_point`
    on its curve, with the Wilson intervals of its rates there, which are optimistic: the
    threshold was chosen on them) and read on the held-out draw (``at_tuning_operating_point``:
    :func:`operating_point_at`, with ``target_met_on_tuning`` and
    ``false_activation_within_target``, the held-out rate at most the target). The blocks'
    curves (:func:`blindspot.safety.draws.draw_block`) are left out.

    Raises:
        TypeError, KeyError: a block that is not a draw block; blocks of different
            predictors; a predictor without a curve.
        ValueError: both blocks of one draw (the same seed), or the errors of
            :func:`choose_operating_point` and :func:`operating_point_at`.
    """
    n_tune, n_held = _block_counts(tuning, "tuning"), _block_counts(held_out, "held_out")
    if tuning["seed"] == held_out["seed"]:
        raise ValueError(f"operating_blocks: tuning and held_out are blocks of one draw (seed "
                         f"{tuning['seed']}): the operating point must be read on another draw")
    names = [k for k, v in held_out.items() if isinstance(v, dict)]
    other = sorted(set(k for k, v in tuning.items() if isinstance(v, dict)) ^ set(names))
    if other:
        raise KeyError(f"operating_blocks: the blocks' predictors differ ({other} in one only): "
                       "both draws must run warning.predictors of one config")
    tune_out = {k: v for k, v in tuning.items() if not isinstance(v, dict)}
    held_out_out = {k: v for k, v in held_out.items() if not isinstance(v, dict)}
    for name in names:
        m = held_out[name]
        curve = draw_curve(tuning, name)
        op = choose_operating_point(curve, false_activation_target)
        at_tuning = operating_point_at(curve, op["aeb_threshold"], *n_tune)
        tune_out[name] = {**{k: v for k, v in tuning[name].items() if k != "curve"},
                          "operating_point": {**op, **at_tuning}}
        at = operating_point_at(draw_curve(held_out, name), op["aeb_threshold"], *n_held)
        held_out_out[name] = {
            **{k: v for k, v in m.items() if k != "curve"},
            "at_tuning_operating_point": {
                **at, "false_activation_target": op["false_activation_target"],
                "target_met_on_tuning": op["target_met"],
                "false_activation_within_target":
                    bool(at["false_activation_rate"] <= op["false_activation_target"] + 1e-12)}}
    return tune_out, held_out_out
