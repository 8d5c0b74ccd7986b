"""The many-walk benchmark's table from a plain dict: the online ellipses' method is named from
what the walks stage recorded, and the recorded setting is not taken for a method."""

from __future__ import annotations

from blindspot.report.walks_report import benchmark_methods, benchmark_table


def metrics(setting=None) -> dict:
    cell = {"mean": 0.5, "ci95": [0.4, 0.6]}
    m = {"n_walks": 3, "lstm": {"path_error_mean_m": cell, "online_coverage_50": cell,
                                "online_coverage_90": cell, "online_coverage_95": cell}}
    if setting is not None:
        m["online_setting"] = setting
    return m


def test_each_method_s_online_setting_is_named_in_its_row():
    table = benchmark_table(metrics({"lstm": {"online_method": "scale_tracker", "online_eta": 0.02,
                                              "online_kappa": 100.0,
                                              "online_prior_outcomes": 50}}),
                            "dvc repro benchmark")
    assert "| LSTM (paper) | scale 0.02 / 100 | 0.500 [0.400, 0.600]" in table
    assert "chose among `calibration.online_*` on validation streams" in table
    aci = {"online_method": "aci_window", "online_gamma": 0.005, "online_window": 150,
           "online_rescale_after": 3}
    assert "| ACI 0.005 / 150 / 3 |" in benchmark_table(metrics({"lstm": aci}), "dvc repro x")
    assert benchmark_methods(metrics({"lstm": aci}))[0] == ["lstm"]


def test_without_a_recorded_setting_the_row_says_so():
    table = benchmark_table(metrics(), "dvc repro benchmark")
    assert "| LSTM (paper) | - | 0.500 [0.400, 0.600]" in table
