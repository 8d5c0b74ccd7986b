"""The safety pages' verdict on the learned predictors (issue 40: the LSTM earns its place
against constant velocity and Kalman on the held-out numbers, or the report says it does not)."""

from __future__ import annotations

from blindspot.report.safety_tables import lstm_verdict, predictor_names


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
    blocks = ("held_out", "held_out_half", "tuning_half", "tuning_draw")
    metrics = {"lstm": {"by_input": {}}, **{b: {"seed": 1, "lstm": {}} for b in blocks}}
    assert predictor_names(metrics) == ["lstm"]


def test_the_held_out_table_reads_the_tuning_draws_operating_point():
    from blindspot.report.safety_tables import ncap_page

    op = {"aeb_threshold": 0.9999, "false_activation_target": 0.03, "target_met_on_tuning": True,
          "avoided_after_visible_rate": 0.45, "avoided_after_visible_rate_ci95": [0.4, 0.5],
          "false_activation_rate": 0.046, "false_activation_rate_ci95": [0.027, 0.077]}
    held = {"seed": 1, "n_intruding": 306, "n_non_intruding": 306,
            "kalman": {"avoided_after_visible_rate": 0.48,
                       "avoided_after_visible_rate_ci95": [0.43, 0.54],
                       "false_activation_rate": 0.173, "false_activation_rate_ci95": [0.13, 0.22],
                       "first_point_to_moving_s_median": 0.3, "first_point_to_aeb_s_median": 0.5,
                       "at_tuning_operating_point": op}}
    page = ncap_page({}, {"held_out": held, "tuning_half": {"n_intruding": 54, "n_non_intruding": 54},
                          "tuning_draw": {"seed": 2, "n_intruding": 306,
                                          "n_non_intruding": 306}})
    assert ("| kalman | 0.48 [0.43, 0.54] | 0.173 [0.130, 0.220] | 0.9999, 0.45 [0.40, 0.50], "
            "0.046 [0.027, 0.077] | 0.30 | 0.50 |") in page
    op["target_met_on_tuning"] = False                       # marked: the target was missed
    assert "| 0.9999*, 0.45" in ncap_page({}, {"held_out": held})
    assert "tuning draw of seed 2 (306 / 306" in page
    del held["kalman"]["at_tuning_operating_point"]            # an older block: a dash
    assert "| 0.173 [0.130, 0.220] | - | 0.30" in ncap_page({}, {"held_out": held})
