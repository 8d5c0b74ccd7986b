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
                       "first_point_to_confirmed_s_median": 0.2,
                       "first_point_to_moving_s_median": 0.3, "first_point_to_aeb_s_median": 0.5,
                       "at_tuning_operating_point": op}}
    page = ncap_page({}, {"held_out": held, "tuning_half": {"n_intruding": 54, "n_non_intruding": 54},
                          "tuning_draw": {"seed": 2, "n_intruding": 306,
                                          "n_non_intruding": 306}})
    assert ("| kalman | 0.48 [0.43, 0.54] | 0.173 [0.130, 0.220] | 0.9999, 0.45 [0.40, 0.50], "
            "0.046 [0.027, 0.077] | 0.20 / 0.30 / 0.50 |") in page
    op["target_met_on_tuning"] = False                       # marked: the target was missed
    assert "| 0.9999*, 0.45" in ncap_page({}, {"held_out": held})
    assert "tuning draw of seed 2 (306 / 306" in page
    del held["kalman"]["at_tuning_operating_point"]            # an older block: a dash
    assert "| 0.173 [0.130, 0.220] | - | 0.20 / 0.30" in ncap_page({}, {"held_out": held})
    del held["kalman"]["first_point_to_confirmed_s_median"]    # a block before the confirmed
    assert "| - | - / 0.30 / 0.50 |" in ncap_page({}, {"held_out": held})


def _bound(avoided, lo, hi, by_speed):
    return {"avoided_after_visible_rate": avoided, "avoided_after_visible_rate_ci95": [lo, hi],
            "false_activation_rate": 0.0, "false_activation_rate_ci95": [0.0, 0.012],
            "n_intruding": 306, "n_non_intruding": 306,
            "by_speed_kmh": {k: {"avoided_after_visible_rate": v} for k, v in by_speed.items()}}


def test_the_held_out_ladder_puts_the_bounds_above_the_chain_on_one_draw():
    from blindspot.report.safety_tables import held_out_ladder, ncap_page

    bound = {"line_of_sight": _bound(0.9, 0.86, 0.93, {"10": 1.0, "60": 0.6}),
             "radar_point": _bound(0.74, 0.69, 0.79, {"10": 1.0, "60": 0.4}),
             "confirmed_track": _bound(0.63, 0.57, 0.68, {"10": 1.0, "60": 0.3}),
             "settings": {"confirm_m": 3, "confirm_n": 5, "seed": 3}}
    op = {"aeb_threshold": 0.98, "avoided_after_visible_rate": 0.48,
          "avoided_after_visible_rate_ci95": [0.43, 0.54], "false_activation_rate": 0.042,
          "false_activation_rate_ci95": [0.025, 0.071]}
    held = {"seed": 3, "track_state": {
        "avoided_after_visible_rate": 0.52, "avoided_after_visible_rate_ci95": [0.47, 0.58],
        "false_activation_rate": 0.092, "false_activation_rate_ci95": [0.064, 0.129],
        "avoided_after_visible_rate_by_speed_kmh": {"10": 0.9, "60": 0.1},
        "first_point_to_confirmed_s_median": 0.2, "first_point_to_moving_s_median": 0.2,
        "first_point_to_aeb_s_median": 0.5, "at_tuning_operating_point": op},
        "none": {"avoided_after_visible_rate": 0.26}}
    page = held_out_ladder(bound, held, 0.5)
    lines = [x for x in page.splitlines() if x.startswith("| ")]
    assert lines[0] == ("| information, decision | avoided after visible | false activations | "
                        "10 km/h | 60 km/h |")
    assert lines[1:] == [
        "| perfect decision from its first frame in line of sight | 0.90 [0.86, 0.93] | "
        "0.000 [0.000, 0.012] | 1.00 | 0.60 |",
        "| perfect decision from its first radar point | 0.74 [0.69, 0.79] | "
        "0.000 [0.000, 0.012] | 1.00 | 0.40 |",
        "| perfect decision from a track confirmed on 3 of 5 frames of its points | "
        "0.63 [0.57, 0.68] | 0.000 [0.000, 0.012] | 1.00 | 0.30 |",
        "| the chain, track_state, configured AEB threshold 0.5 | 0.52 [0.47, 0.58] | "
        "0.092 [0.064, 0.129] | 0.90 | 0.10 |",
        "| the chain, track_state, tuning draw's threshold 0.98 | 0.48 [0.43, 0.54] | "
        "0.042 [0.025, 0.071] | - | - |"]                  # "none" is not a chain's row
    assert held_out_ladder({"settings": {}}, held) == ""
    # bounds of another draw, or without a seed, never stand beside this draw's rows
    assert held_out_ladder({**bound, "settings": {**bound["settings"], "seed": 4}}, held) == ""
    assert held_out_ladder({**bound, "settings": {"confirm_m": 3, "confirm_n": 5}}, held) == ""
    assert held_out_ladder({"radar_point": {"avoided_after_visible_rate": None}}, held) == ""
    assert "Where the time goes" not in ncap_page({}, {"held_out": held})
    # the page labels the chain's rows with the configured threshold of safety.json
    metrics = {"held_out": held, "track_state": {"by_input": {}, "settings": {
        "aeb_threshold": 0.7, "headline_input": "tracker", "inputs": ["tracker"]}}}
    assert "| the chain, track_state, configured AEB threshold 0.7 | 0.52" in ncap_page(
        {}, metrics, bound)


def test_the_pages_name_every_bound_the_stages_write():
    from blindspot.report.bound_steps import BOUND_STEPS
    from blindspot.safety.bound import BOUNDS

    assert tuple(name for name, _ in BOUND_STEPS) == BOUNDS


def test_same_draw_needs_two_equal_integer_seeds():
    from blindspot.report.bound_steps import same_draw

    assert same_draw({"settings": {"seed": 3}}, {"seed": 3})
    assert not same_draw({"settings": {"seed": 3}}, {"seed": 4})
    assert not same_draw({"settings": {}}, {})                  # two missing seeds: not one draw
    assert not same_draw({"settings": {"seed": True}}, {"seed": True})
    assert not same_draw(None, {"seed": 3})
