"""The AEB operating point chosen on the tuning draw and read on the held-out draw (issue 40,
blindspot.safety.operating_point): the Neyman-Pearson choice against a brute-force search, the
fallback where no threshold keeps to the target, the held-out reading with Wilson intervals
(scipy's binomtest), and the errors that name what is wrong."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from blindspot.safety.operating_point import (choose_operating_point, operating_blocks,
                                              operating_point_at)


def _curve(avoided_after, fa, avoided=None, thresholds=None):
    n = len(fa)
    return pd.DataFrame({
        "threshold": np.linspace(0.1, 0.9, n) if thresholds is None else thresholds,
        "avoided_rate": avoided_after if avoided is None else avoided,
        "avoided_after_visible_rate": avoided_after, "false_activation_rate": fa})


def test_the_choice_is_the_most_avoided_within_the_false_activation_budget():
    """Against every threshold of random curves: no threshold within the budget avoids more,
    and among those that avoid as much none has fewer false activations (then: the largest)."""
    rng = np.random.default_rng(0)
    for _ in range(200):
        n = int(rng.integers(1, 12))
        c = _curve(rng.integers(0, 5, n) / 4, rng.integers(0, 9, n) / 100)
        got = choose_operating_point(c, 0.03)
        ok = c[c.false_activation_rate <= 0.03]
        assert got["target_met"] == (not ok.empty)
        pool = ok if not ok.empty else c[c.false_activation_rate == c.false_activation_rate.min()]
        best = pool[pool.avoided_after_visible_rate == pool.avoided_after_visible_rate.max()]
        best = best[best.false_activation_rate == best.false_activation_rate.min()]
        assert got["aeb_threshold"] == best.threshold.max()
        row = c[c.threshold == got["aeb_threshold"]].iloc[0]
        assert got["false_activation_rate"] == row.false_activation_rate
        assert got["avoided_after_visible_rate"] == row.avoided_after_visible_rate


def test_a_budget_no_threshold_meets_takes_the_fewest_false_activations():
    c = _curve([0.9, 0.8, 0.5, 0.4], [0.20, 0.10, 0.05, 0.05])
    got = choose_operating_point(c, 0.03)
    assert not got["target_met"] and got["false_activation_rate"] == 0.05
    assert got["avoided_after_visible_rate"] == 0.5 and got["aeb_threshold"] == c.threshold[2]
    assert choose_operating_point(c, 0.10)["avoided_after_visible_rate"] == 0.8


def test_the_held_out_reading_carries_wilson_intervals_of_its_counts():
    c = _curve([0.5, 0.25], [0.1, 0.0], avoided=[0.75, 0.5], thresholds=[0.3, 0.6])
    got = operating_point_at(c, 0.3, 4, 10)
    assert got["aeb_threshold"] == 0.3 and got["avoided_rate"] == 0.75
    for key, k, n in (("avoided_rate", 3, 4), ("avoided_after_visible_rate", 2, 4),
                      ("false_activation_rate", 1, 10)):
        ci = stats.binomtest(k, n).proportion_ci(0.95, method="wilson")
        assert got[f"{key}_ci95"] == pytest.approx([ci.low, ci.high])


def _block(seed, curve_a, curve_b, n_int=4, n_non=10):
    as_lists = lambda c: {k: c[k].tolist() for k in c.columns}            # noqa: E731
    return {"seed": seed, "chain_digest": "x", "n_intruding": n_int, "n_non_intruding": n_non,
            "a": {"avoided_after_visible_rate": 0.1, "curve": as_lists(curve_a)},
            "b": {"avoided_after_visible_rate": 0.2, "curve": as_lists(curve_b)}}


def test_blocks_choose_on_the_tuning_draw_and_read_the_held_out_draw_there():
    tune_a = _curve([0.5, 0.25], [0.1, 0.0], thresholds=[0.3, 0.6])
    tune_b = _curve([0.5, 0.25], [0.2, 0.1], thresholds=[0.3, 0.6])    # never within 3 %
    held_a = _curve([0.75, 0.5], [0.2, 0.1], thresholds=[0.3, 0.6])
    tuning, held = operating_blocks(_block(2, tune_a, tune_b), _block(1, held_a, held_a), 0.03)
    assert tuning["seed"] == 2 and held["seed"] == 1 and held["chain_digest"] == "x"
    assert "curve" not in tuning["a"] and "curve" not in held["a"]
    op = tuning["a"]["operating_point"]
    assert op["aeb_threshold"] == 0.6 and op["target_met"] and op["top_of_grid"]
    assert op["avoided_after_visible_rate_ci95"] == pytest.approx(
        list(stats.binomtest(1, 4).proportion_ci(0.95, method="wilson")))
    at = held["a"]["at_tuning_operating_point"]
    assert held["a"]["avoided_after_visible_rate"] == 0.1          # the block's own rates stay
    assert at["aeb_threshold"] == 0.6 and at["avoided_after_visible_rate"] == 0.5
    assert at["false_activation_rate"] == 0.1 and at["target_met_on_tuning"]
    assert not at["false_activation_within_target"]                # 10 % held out > 3 %
    assert not held["b"]["at_tuning_operating_point"]["target_met_on_tuning"]


def test_blocks_of_one_draw_or_not_of_a_draw_are_refused():
    c = _curve([0.5, 0.25], [0.1, 0.0], thresholds=[0.3, 0.6])
    with pytest.raises(ValueError, match="blocks of one draw \\(seed 1\\)"):
        operating_blocks(_block(1, c, c), _block(1, c, c), 0.03)
    with pytest.raises(TypeError, match="operating_blocks: tuning: expected a draw block"):
        operating_blocks([], _block(1, c, c), 0.03)
    with pytest.raises(KeyError, match="operating_blocks: held_out: missing \\['n_intruding'\\]"):
        operating_blocks(_block(2, c, c), {"seed": 1, "n_non_intruding": 3}, 0.03)
    fewer = _block(2, c, c)
    del fewer["b"]
    with pytest.raises(KeyError, match="the blocks' predictors differ \\(\\['b'\\] in one only\\)"):
        operating_blocks(fewer, _block(1, c, c), 0.03)
    tuning = _block(2, c, c)
    del tuning["b"]["curve"]
    with pytest.raises(KeyError, match="draw_curve: block of seed 2: no curve of predictor 'b'"):
        operating_blocks(tuning, _block(1, c, c), 0.03)


def test_bad_arguments_are_named():
    c = _curve([0.5, 0.25], [0.1, 0.0], thresholds=[0.3, 0.6])
    with pytest.raises(ValueError, match="false_activation_target: expected a number in"):
        choose_operating_point(c, 1.0)
    with pytest.raises(ValueError, match="false_activation_target"):
        choose_operating_point(c, 0.0)
    with pytest.raises(TypeError, match="curve: expected a DataFrame"):
        choose_operating_point(c.to_dict(), 0.03)
    with pytest.raises(KeyError, match="missing columns \\['avoided_after_visible_rate'\\]"):
        choose_operating_point(c.drop(columns="avoided_after_visible_rate"), 0.03)
    with pytest.raises(ValueError, match="no missing rate"):
        choose_operating_point(c.assign(false_activation_rate=np.nan), 0.03)
    with pytest.raises(ValueError, match="one row per threshold"):
        choose_operating_point(pd.concat([c, c]), 0.03)
    with pytest.raises(ValueError, match="threshold: expected one of the curve's thresholds"):
        operating_point_at(c, 0.45, 4, 10)
    with pytest.raises(ValueError, match="n_intruding: expected an integer >= 1"):
        operating_point_at(c, 0.3, 0, 10)
    with pytest.raises(ValueError, match="not a whole count of 3 scenes"):
        operating_point_at(c, 0.3, 3, 10)
