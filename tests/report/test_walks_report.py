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


def test_the_online_method_is_named_with_its_parameters():
    table = benchmark_table(metrics({"online_method": "aci_window", "online_gamma": 0.005,
                                     "online_window": 150}), "dvc repro benchmark")
    assert ("`calibration.online_method` aci_window: sliding-window ACI, "
            "blindspot.traj.conformal; gamma 0.005, window 150") in table
    assert benchmark_methods(metrics({"online_method": "aci_window"}))[0] == ["lstm"]


def test_without_a_recorded_setting_the_table_says_where_it_is_set():
    table = benchmark_table(metrics(), "dvc repro benchmark")
    assert "Online ellipses (`calibration.online_method`): the walks" in table
    assert "scale tracking" not in table and "sliding-window" not in table
