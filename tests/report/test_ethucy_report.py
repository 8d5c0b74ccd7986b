"""The ETH/UCY page from plain dicts (no benchmark run): tables, verdicts, fitted values, settings."""

from __future__ import annotations

import json

import pytest

from blindspot.report.ethucy_report import (
    compare_to_cvm,
    format_calibration,
    format_report,
    format_table,
    off_nominal,
)
from blindspot.report.paper_values import ETHUCY_PUBLISHED

FOLDS = ("eth", "hotel")


def scores(eth, hotel) -> dict:
    rows = {"eth": {"ade": eth[0], "fde": eth[1], "n_windows": 181},
            "hotel": {"ade": hotel[0], "fde": hotel[1], "n_windows": 1053}}
    rows["avg"] = {"ade": (eth[0] + hotel[0]) / 2, "fde": (eth[1] + hotel[1]) / 2}
    return rows


RESULTS = {"cvm": scores((1.0, 2.2), (0.3, 0.6)), "kalman": scores((1.1, 2.4), (0.3, 0.6)),
           "lstm_rollout": scores((0.9, 2.1), (0.32, 0.5)), "best": "lstm_rollout"}
MODELS = ("cvm", "kalman", "lstm_rollout")
VALIDATION = {m: {"eth": {"ade": 0.45, "fde": 0.99}, "hotel": {"ade": 0.2, "fde": 0.4},
                  "avg": {"ade": 0.325, "fde": 0.695}} for m in MODELS}
LSTM = {"hidden_size": 64, "frame": "heading", "residual": True, "mirror": True,
        "speed_floor": None, "ensemble": 5}


def details() -> dict:
    out = {}
    for fold, n in (("eth", 181), ("hotel", 1053)):
        out[fold] = {m: {"ade": 0.0, "fde": 0.0, "n_windows": n, "seconds": 2.0, "fitted": {}}
                     for m in MODELS}
        out[fold]["kalman"]["fitted"] = {"process_psd_m2_s3": 2.61, "meas_std_m": 0.05}
        out[fold]["lstm_rollout"]["fitted"] = {"val_rmse_m": 0.0421, "val_ade_m": 0.45,
                                               "val_fde_m": 1.0}
    return out


def table_row(text: str, first: str) -> list[str]:
    line = next(ln for ln in text.splitlines() if ln.startswith(f"| {first} |"))
    return [c.strip() for c in line.strip("|").split("|")]


def test_table_ours_then_published():
    text = format_table(RESULTS, FOLDS)
    assert text.splitlines()[0] == "| model | eth | hotel | avg |"
    assert table_row(text, "lstm_rollout (ours)") == ["lstm_rollout (ours)", "0.90 / 2.10",
                                                      "0.32 / 0.50", "0.61 / 1.30"]
    assert "best" not in text
    cvm = ETHUCY_PUBLISHED["cvm (Schöller et al. 2020)"]
    assert table_row(text, "published: cvm (Schöller et al. 2020)")[1:] == [
        f"{cvm[f]['ade']:.2f} / {cvm[f]['fde']:.2f}" for f in (*FOLDS, "avg")]
    assert table_row(text, "published: linear")[1:3] == ["-", "-"]
    assert "published" not in format_table(RESULTS, FOLDS, published=False)


def test_verdicts_against_cvm():
    lines = compare_to_cvm(RESULTS)
    assert lines[0].startswith("- kalman does not beat CVM") and "ADE +0.050 m" in lines[0]
    assert lines[1].startswith("- lstm_rollout beats CVM") and len(lines) == 3
    assert compare_to_cvm({"lstm": RESULTS["lstm_rollout"]}) == []


def test_report_page():
    page = format_report(RESULTS, VALIDATION, details(), FOLDS, LSTM, "python -m blindspot ethucy",
                         61.0)
    assert page.startswith("# ETH/UCY benchmark\n")
    assert "Test windows per fold: eth 181, hotel 1053." in page
    assert "Fitted process noise q (m^2/s^3), meas_std 0.05 m: eth 2.61, hotel 2.61." in page
    assert "in each window's heading frame" in page and "the mean of 5 LSTMs" in page
    assert f"Settings: `{json.dumps(LSTM)}`." in page
    assert "One-step val RMSE per coordinate (m) eth 0.0421, hotel 0.0421" in page
    assert "chosen without the test scenes): **lstm_rollout**" in page
    validation = page.split("## Validation splits")[1]
    assert table_row(validation, "cvm (ours)")[1:] == ["0.45 / 0.99", "0.20 / 0.40", "0.33 / 0.69"]
    assert "published" not in validation.split("## Run")[0]
    assert "Command: `python -m blindspot ethucy`" in page
    assert "Wall time 61 s (cvm 4 s, kalman 4 s, lstm_rollout 4 s)." in page
    # the pipeline's page leaves the wall time out, so its bytes repeat on a rerun
    timeless = format_report(RESULTS, VALIDATION, details(), FOLDS, LSTM,
                             "python -m blindspot ethucy", None)
    assert "Wall time" not in timeless and "Command: `python -m blindspot ethucy`" in timeless


def test_report_without_lstm_settings():
    page = format_report({"cvm": RESULTS["cvm"]}, {"cvm": VALIDATION["cvm"]}, details(), FOLDS,
                         None, "cmd", 1.0)
    assert "**lstm" not in page and "**kalman**" not in page and "**cvm**" in page
    assert "## Calibration" not in page


def test_calibration_table_marks_cells_off_nominal():
    cal = {"cvm": {"eth": {"coverage_50": 0.51, "coverage_90": 0.85, "coverage_95": 0.95,
                           "nll": 1.234}}}
    text = format_calibration(cal, FOLDS)
    assert table_row(text, "cvm") == ["cvm", "0.510 / 0.850* / 0.950; NLL 1.23", "-"]
    page = format_report({"cvm": RESULTS["cvm"]}, {"cvm": VALIDATION["cvm"]}, details(), FOLDS,
                         None, "cmd", 1.0, calibration=cal, calibration_method="quantile")
    assert "## Calibration (test scenes)" in page and "method `quantile`" in page
    assert "online" not in table_row(text, "cvm")[0] and len(text.splitlines()) == 3


def test_online_coverage_gets_its_own_row():
    cal = {"kalman": {"eth": {"coverage_50": 0.25, "coverage_90": 0.66, "coverage_95": 0.75,
                              "nll": 1.7, "online_coverage_50": 0.384,
                              "online_coverage_90": 0.894, "online_coverage_95": 0.951}}}
    text = format_calibration(cal, FOLDS)
    assert table_row(text, "kalman, online") == ["kalman, online", "0.384* / 0.894 / 0.951", "-"]
    cal["kalman"]["eth"]["online_unbounded_95"] = 0.041
    assert table_row(format_calibration(cal, FOLDS), "kalman, online")[1] == \
        "0.384* / 0.894 / 0.951; unbounded 4.1 %"
    cal["kalman"]["eth"]["online_coverage_90_ci95"] = [0.8512, 0.9349]
    assert table_row(format_calibration(cal, FOLDS), "kalman, online")[1] == \
        "0.384* / 0.894 / 0.951; 90 %: [0.85, 0.93]; unbounded 4.1 %"
    assert table_row(text, "kalman")[1] == "0.250* / 0.660* / 0.750*; NLL 1.70"


def test_reliability_figure_draws_one_panel_per_fold_and_one_line_per_method():
    from blindspot.report.calibration_figures import reliability_figure

    curve = {"levels": [0.5, 0.9, 0.95], "coverage": [0.55, 0.88, 0.93]}
    data = {m: {f: {"reliability": curve} for f in FOLDS} for m in ("cvm", "lstm")}
    fig = reliability_figure(data, FOLDS)
    axes = fig.axes
    assert len(axes) == len(FOLDS)
    labels = [ln.get_label() for ln in axes[0].get_lines()]
    assert "cvm" in labels and "lstm" in labels
    xs, ys = axes[1].get_lines()[1].get_data()       # [0] is the diagonal
    assert list(xs) == curve["levels"] and list(ys) == curve["coverage"]


def test_the_online_choice_table_names_each_folds_setting():
    from blindspot.report.ethucy_report import format_online_choice

    cal = {"kalman": {"eth": {"online_gamma": 0.002, "online_window": 100,
                              "online_rescale_after": 3, "online_val_distance": 0.0146}}}
    text = format_online_choice(cal, FOLDS)
    assert table_row(text, "kalman")[:3] == ["kalman", "ACI 0.002 / 100 / 3 (1.46 pp)", "-"]
    cal["kalman"]["hotel"] = {"online_method": "scale_tracker", "online_eta": 0.05,
                              "online_kappa": 10.0, "online_val_distance": 0.0071}
    assert table_row(format_online_choice(cal, FOLDS), "kalman")[2] == "scale 0.05 / 10 (0.71 pp)"
    assert format_online_choice({"kalman": {"eth": {"coverage_50": 0.5}}}, FOLDS) == ""


def test_seeds_and_multi_modal_blocks_are_tables_not_model_rows():
    """Issue 43: "seeds" and "best_of_20" are blocks of ethucy.json, not models: the main table
    and the CVM verdicts leave them out; the page prints each seed, the mean +- sd and the
    best-of-20 and mixture scores from the values given."""
    from blindspot.report.ethucy_report import format_multimodal, format_seeds

    results = {**RESULTS, "mix": scores((0.8, 1.8), (0.3, 0.55)),
               "seeds": {"mix": {"n": 3, "ade": [0.55, 0.56, 0.57], "fde": [1.2, 1.1, 1.15],
                                 "ade_mean": 0.56, "ade_sd": 0.01, "fde_mean": 1.15,
                                 "fde_sd": 0.05}},
               "best_of_20": {"mix": {"eth": {"ade": 0.41, "fde": 0.72},
                                      "hotel": {"ade": 0.13, "fde": 0.21},
                                      "avg": {"ade": 0.27, "fde": 0.465},
                                      "sd": {"ade": 0.004, "fde": 0.008}}}}
    table = format_table(results, FOLDS, published=False)
    assert "seeds" not in table and "best_of" not in table and "| mix (ours) |" in table
    assert not any("seeds" in line or "best_of" in line for line in compare_to_cvm(results))
    seeds = format_seeds(results)
    assert "| mix | 3 | 0.550, 0.560, 0.570 | 1.200, 1.100, 1.150 | 0.560 +- 0.010 | " \
           "1.150 +- 0.050 |" in seeds
    row = {"mixture_nll": 1.0, "mixture_coverage_50": 0.4, "mixture_coverage_90": 0.8,
           "mixture_coverage_95": 0.9}
    det = {f: {"mix": {"fitted": {"seed_scores": [{**row, "point": "mean"},
                                                  {**row, "mixture_nll": 3.0, "point": "mode"}]}}}
           for f in FOLDS}
    multi = format_multimodal(results, det, FOLDS)
    assert "| mix | 0.41 / 0.72 | 0.13 / 0.21 | 0.27 / 0.47 | 0.004 / 0.008 |" in multi
    assert "NLL 2.00; 0.400 / 0.800 / 0.900; point mean,mode" in multi
    assert format_seeds(RESULTS) == "" and format_multimodal(RESULTS, det, FOLDS) == ""


def test_exactly_the_tolerance_is_within_and_anything_beyond_is_off():
    """The README's count of calibrated scenes and the page's stars share one rule: 2 points
    off is within (0.52 - 0.50 is 0.020000000000000018 in floats), 2.01 points is not."""
    assert not off_nominal(0.52, 0.50) and not off_nominal(0.88, 0.90)
    assert off_nominal(0.5201, 0.50) and off_nominal(0.8799, 0.90)
    for bad in (float("nan"), 1.2, None):
        with pytest.raises(ValueError, match="coverage: expected a share"):
            off_nominal(bad, 0.5)
