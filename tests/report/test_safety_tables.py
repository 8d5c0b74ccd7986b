"""The safety pages' verdict on the learned predictors (issue 40: the LSTM earns its place
against constant velocity and Kalman on the held-out numbers, or the report says it does not)."""

from __future__ import annotations

from blindspot.report.safety_tables import PREDICTOR_BLOCKS, lstm_verdict, predictor_names


def _held(direct_avoided, direct_ci, direct_fa):
    return {"seed": 1, "n_intruding": 306,
            "lstm_direct": {"avoided_after_visible_rate": direct_avoided,
                            "avoided_after_visible_rate_ci95": direct_ci,
                            "false_activation_rate": direct_fa},
            "constant_velocity": {"avoided_after_visible_rate": 0.42,
                                  "avoided_after_visible_rate_ci95": [0.36, 0.48],
                                  "false_activation_rate": 0.10},
            "kalman": {"avoided_after_visible_rate": 0.40, "false_activation_rate": 0.08}}


def test_it_earns_its_place_only_above_the_best_baseline_at_no_more_false_activations():
    assert "lstm_direct earns its place" in lstm_verdict(_held(0.55, [0.49, 0.61], 0.10))
    assert "do not earn" in lstm_verdict(_held(0.46, [0.40, 0.52], 0.10))   # inside CV's reach
    assert "do not earn" in lstm_verdict(_held(0.55, [0.49, 0.61], 0.12))   # more false AEB
    assert "constant_velocity 0.42 at 0.100" in lstm_verdict(_held(0.46, [0.40, 0.52], 0.1))


def test_no_verdict_without_both_kinds_and_blocks_are_not_predictors():
    assert lstm_verdict({"kalman": {"avoided_after_visible_rate": 0.4,
                                    "false_activation_rate": 0.1}}) == ""
    assert lstm_verdict({}) == ""
    metrics = {"lstm": {}, **{b: {} for b in PREDICTOR_BLOCKS}}
    assert predictor_names(metrics) == ["lstm"]
