"""Figure functions and the report page on small synthetic artifacts of the pipeline's formats."""

from __future__ import annotations

import io
import re

import matplotlib

matplotlib.use("Agg")

import matplotlib.colors as mcolors  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402

from blindspot.report import error_figures, path_figures, radar_figures, style  # noqa: E402
from blindspot.report.page import build_page, differences, summary_rows  # noqa: E402
from blindspot.report.paper_values import PATH_ERROR_MEAN_M  # noqa: E402

DT = 0.1
N = 40  # frames per synthetic scene
CAR = [[1.5, 4.8], [3.3, 4.8], [3.3, 9.3], [1.5, 9.3]]
PANEL = re.compile(r"^\(([a-z])\) \S")


@pytest.fixture(autouse=True)
def _render_and_close_figures():
    """Every figure a test made must also render to PNG (layout errors appear only at draw)."""
    yield
    try:
        for num in plt.get_fignums():
            buf = io.BytesIO()
            plt.figure(num).savefig(buf, format="png", dpi=30)
            assert buf.getvalue()[:4] == b"\x89PNG"
    finally:
        plt.close("all")


def panels(fig) -> list:
    """Axes titled "(a) ...", "(b) ..." that have both axis labels, in letter order."""
    out = [ax for ax in fig.axes if PANEL.match(ax.get_title(loc="left"))
           and ax.get_xlabel() and ax.get_ylabel()]
    return sorted(out, key=lambda ax: ax.get_title(loc="left"))


def letters(fig) -> str:
    return "".join(PANEL.match(ax.get_title(loc="left")).group(1) for ax in panels(fig))


def walk(turn_deg: float) -> np.ndarray:
    """(N, 2) a walk in -x at 1.25 m/s, turning by turn_deg half way."""
    t = np.arange(N) * DT
    xy = np.column_stack([7.9 - 1.25 * t, np.full(N, 10.2)])
    half = N // 2
    th = np.radians(180.0 + turn_deg)
    xy[half:] = xy[half - 1] + 1.25 * DT * np.arange(1, N - half + 1)[:, None] * [np.cos(th), -np.sin(th)]
    return xy


@pytest.fixture(scope="module")
def scenes() -> dict:
    out = {}
    for base, turn in (("straight", 0.0), ("approach", 45.0), ("recede", -45.0)):
        for car in (False, True):
            out[f"{base}_{'car' if car else 'nocar'}"] = {
                "with_car": car, "car_polygon_xy_m": CAR if car else None, "turn_deg": turn,
                "n_frames": N, "frame_period_s": DT}
    return out


@pytest.fixture(scope="module")
def truth(scenes) -> pd.DataFrame:
    rows = []
    for name, info in scenes.items():
        xy = walk(info["turn_deg"])
        hidden = np.zeros(N, bool)
        if info["with_car"]:
            hidden[8:18] = True
        rows.append(pd.DataFrame({"scene": name, "frame": np.arange(N), "time_s": np.arange(N) * DT,
                                  "x_m": xy[:, 0], "y_m": xy[:, 1], "occluded": hidden,
                                  "angle_deg": np.degrees(np.arctan2(xy[:, 0], xy[:, 1]))}))
    return pd.concat(rows, ignore_index=True)


@pytest.fixture(scope="module")
def points(truth) -> pd.DataFrame:
    rng = np.random.default_rng(0)
    seen = truth[~truth.occluded].copy()
    seen[["x_m", "y_m"]] += rng.normal(0, 0.1, (len(seen), 2))
    return seen[["scene", "frame", "time_s", "x_m", "y_m"]].reset_index(drop=True)


@pytest.fixture(scope="module")
def tracks(truth) -> pd.DataFrame:
    rows = []
    for name in ("straight_car", "approach_car", "recede_car"):
        tr = truth[truth.scene == name]
        for k, method in enumerate(("forward", "kalman", "bidirectional")):
            rows.append(pd.DataFrame({
                "scene": name, "method": method, "frame": tr.frame, "time_s": tr.time_s,
                "x_m": tr.x_m, "y_m": tr.y_m - 0.1 * k * tr.occluded, "observed": ~tr.occluded,
                "filled": tr.occluded, "hidden": tr.occluded}))
    return pd.concat(rows, ignore_index=True)


@pytest.fixture(scope="module")
def predictions(truth) -> pd.DataFrame:
    rows = []
    for name in ("straight_car", "approach_car", "recede_car"):
        tr = truth[(truth.scene == name) & (truth.frame >= 30)]
        for k, method in enumerate(("lstm", "constant_velocity", "kalman")):
            rows.append(pd.DataFrame({
                "scene": name, "method": method, "step": np.arange(1, len(tr) + 1), "frame": tr.frame,
                "time_s": tr.time_s, "x_m": tr.x_m + 0.05 * k, "y_m": tr.y_m}))
    return pd.concat(rows, ignore_index=True)


def evaluate_metrics(lstm=0.2, cv=0.5, kalman=0.4) -> dict:
    def m(v):
        scenes = {s: {"path_error_mean_m": v, "ade_m": v} for s in ("straight_car", "approach_car", "recede_car")}
        return {"path_error_mean_m": v, "path_error_radar_mean_m": v * 0.9, "path_error_first_m": v / 4,
                "ade_m": v, "fde_m": 2 * v, "ade_0.5s": v / 2, "fde_0.5s": v, "per_scene": scenes}
    return {"lstm": m(lstm), "constant_velocity": m(cv), "kalman": m(kalman),
            "paper": {"path_error_mean_m": 0.09}}


def interpolate_metrics(forward=1.0, kalman=0.45, bidirectional=0.3) -> dict:
    out = {}
    for method, v in (("forward", forward), ("kalman", kalman), ("bidirectional", bidirectional)):
        out[method] = {s: {"hidden_mean_m": v} for s in ("straight_car", "approach_car", "recede_car")}
        out[method]["all_scenes"] = {"hidden_mean_m": v}
    return out


def line_colours(fig, prefix: str) -> set[str]:
    """Hex colours of the lines whose label starts with ``prefix`` (any axes)."""
    return {mcolors.to_hex(line.get_color()) for ax in fig.axes for line in ax.get_lines()
            if line.get_label().startswith(prefix)}


# ----------------------------------------------------------------------------- figures


def test_fig04_five_labelled_panels():
    rng = np.random.default_rng(1)
    cases = []
    for motion in ("approaching", "approaching", "receding", "receding", "perpendicular"):
        true = np.column_stack([np.linspace(5, 0, 80), np.linspace(15, 8, 80)])
        hist = true[:50] + rng.normal(0, 0.1, (50, 2))
        hist[[3, 7]] = np.nan  # missed detections
        cases.append(path_figures.PathCase(motion, 3, 0, hist, true[:50], true[50:] + 0.2, true[50:], 0.2))
    fig = path_figures.fig04_lstm_paths(cases, dt_s=DT, val_rmse_m=0.066)
    assert letters(fig) == "abcde"
    assert [ax.get_title(loc="left").split(":")[0] for ax in panels(fig)] == [
        "(a) approaching", "(b) approaching", "(c) receding", "(d) receding", "(e) perpendicular"]
    assert "paper 0.07" in fig._suptitle.get_text()
    assert line_colours(fig, "LSTM") == {style.METHOD_COLOURS["lstm"]}


def test_fig04_rejects_no_cases():
    with pytest.raises(ValueError, match="no cases"):
        path_figures.fig04_lstm_paths([])


def fig06_inputs(truth, points):
    R, D = 24, 16
    rng = np.random.default_rng(2)
    power = rng.exponential(1.0, (R, D))
    power[10, 8] = power[17, 8] = 1e4       # car at zero velocity
    power[18, 3] = 1e3                       # pedestrian
    threshold = np.full((R, D), 12.0)
    frame = {"power": power, "threshold": threshold, "mask": power > threshold,
             "range_axis_m": np.arange(R) * 0.5, "velocity_axis_mps": (np.arange(D) - D // 2) * 0.3,
             "spectrum": 1.0 / (1e-3 + (np.linspace(-90, 90, 181) + 6.5) ** 2),
             "angles_deg": np.linspace(-90, 90, 181), "spectrum_detection": np.array(0),
             "scene": np.array("approach_car"), "frame": np.array(30), "time_s": np.array(3.0)}
    det = pd.DataFrame({"range_m": [9.0, 5.0, 8.5], "velocity_mps": [-1.5, 0.0, 0.0],
                        "angle_deg": [-6.5, 17.0, 10.0], "moving": [True, False, False],
                        "snr_db": [20.0, 30.0, 10.0]})
    return frame, det


def test_fig06_five_labelled_panels(truth, points):
    frame, det = fig06_inputs(truth, points)
    tr = truth[truth.scene == "approach_car"]
    fig = radar_figures.fig06_detection(frame, det, true_angle_deg=-6.6, true_xy_m=(-1.0, 9.0),
                            point={"x_m": -1.02, "y_m": 8.95, "range_m": 9.0, "angle_deg": -6.5},
                            static_xy_m=np.array([[1.5, 4.8], [1.5, 8.4]]),
                            scene_points=points[points.scene == "approach_car"], scene_truth=tr,
                            car_polygon=CAR, scene_name="approach_car")
    assert letters(fig) == "abcde"
    c = panels(fig)[2]
    assert c.get_xlim() == (-90, 90)
    legend = " ".join(t.get_text() for t in c.get_legend().get_texts())
    assert "estimated -6.5°" in legend and "true -6.6°" in legend


def test_fig06_without_music_spectrum_still_draws(truth, points):
    frame, det = fig06_inputs(truth, points)
    frame = {**frame, "spectrum": np.zeros(0), "spectrum_detection": np.array(-1)}
    fig = radar_figures.fig06_detection(frame, det, true_angle_deg=None, true_xy_m=None, point=None,
                            static_xy_m=None, scene_points=points[points.scene == "approach_car"])
    assert letters(fig) == "abcde"


def test_fig06_rejects_mismatched_map(truth, points):
    frame, det = fig06_inputs(truth, points)
    with pytest.raises(ValueError, match="must all be"):
        radar_figures.fig06_detection({**frame, "threshold": frame["threshold"][:-1]}, det, true_angle_deg=None,
                          true_xy_m=None, point=None, static_xy_m=None, scene_points=points)


def test_fig07_six_panels_gap_counts(points, truth, scenes):
    pairs = [("straight_nocar", "straight_car"), ("approach_nocar", "approach_car"),
             ("recede_nocar", "recede_car")]
    fig = path_figures.fig07_scenes(points, truth, scenes, pairs)
    assert letters(fig) == "abcdef"
    titles = [ax.get_title(loc="left") for ax in panels(fig)]
    assert all("no car" in t for t in titles[:3]) and all("with car" in t for t in titles[3:])
    # the car scenes' note counts the hidden frames; the no-car scenes see every frame
    notes = [ax.artists[0].get_title().get_text() for ax in panels(fig)]
    assert f"{N}/{N} frames" in notes[0] and "hidden behind the car: 10 frames" in notes[3]


def test_fig08_errors_from_metrics_and_colours(tracks, truth, scenes):
    fig = path_figures.fig08_interpolation(tracks, truth, scenes, interpolate_metrics(forward=1.234))
    assert letters(fig) == "abc"
    labels = [t.get_text() for t in panels(fig)[0].get_legend().get_texts()]
    assert "forward LSTM (paper): 1.23 m" in labels
    assert line_colours(fig, "forward LSTM (paper):") == {style.METHOD_COLOURS["forward"]}
    assert line_colours(fig, "Kalman") == {style.METHOD_COLOURS["kalman"]}


def test_fig09_same_method_colours_as_fig10(tracks, predictions, truth, scenes):
    inputs = tracks[tracks.method == "forward"]
    metrics = evaluate_metrics()
    fig9 = path_figures.fig09_prediction(inputs, predictions, truth, scenes, metrics)
    assert letters(fig9) == "abc"
    curves = (predictions.assign(error_m=0.1 * predictions.step, path_error_m=0.05 * predictions.step,
                                 path_error_radar_m=0.04 * predictions.step))
    fig10 = error_figures.fig10_error(curves, metrics, dt_s=DT)
    assert letters(fig10) == "ab"
    for method, label in (("lstm", "LSTM"), ("constant_velocity", "constant velocity"), ("kalman", "Kalman")):
        assert line_colours(fig9, label) == line_colours(fig10, label) == {style.METHOD_COLOURS[method]}
    legend = [t.get_text() for t in panels(fig10)[0].get_legend().get_texts()]
    assert "paper mean 0.09 m" in legend
    assert any(t.startswith("LSTM (paper) vs truth: mean 0.20 m") for t in legend)


def test_fig10_averages_scenes(predictions):
    """The drawn curve is the mean over scenes of each step's error."""
    curves = predictions.assign(error_m=np.where(predictions.scene == "straight_car", 1.0, 4.0),
                                path_error_m=0.0)
    fig = error_figures.fig10_error(curves, evaluate_metrics(), dt_s=DT)
    lstm = [ln for ln in panels(fig)[1].get_lines() if ln.get_label().startswith("LSTM")][0]
    np.testing.assert_allclose(lstm.get_ydata(), 3.0)


@pytest.mark.parametrize("as_frame", [False, True])
def test_fig_recording(as_frame):
    power = np.random.default_rng(3).exponential(1.0, (32, 16))
    power[5, 8] = 1e4
    mask = power > 100
    det = pd.DataFrame({"range_m": [2.5], "velocity_mps": [0.0], "moving": [False]}) if as_frame else mask
    fig = radar_figures.fig_recording(power, det, np.arange(32) * 0.5, np.linspace(-4, 4, 16), "capture_1 (dca1000)")
    (ax,) = fig.axes[:1]
    assert ax.get_title() == "capture_1 (dca1000)" and ax.get_xlabel() and ax.get_ylabel()
    with pytest.raises(ValueError, match="must match"):
        radar_figures.fig_recording(power, mask[:-1], np.arange(32) * 0.5, np.linspace(-4, 4, 16), "x")


def test_scene_title():
    assert style.scene_title("approach_car", {"turn_deg": 45.0, "with_car": True}) == "approach (turn +45°), with car"
    assert style.scene_title("straight_nocar", {"turn_deg": 0.0, "with_car": False}) == "straight (no turn), no car"


# ----------------------------------------------------------------------------- page


def page_metrics(**over) -> dict:
    train = {"lstm": {"val": {"rmse_m": 0.0664}, "test": {"rmse_m": 0.05}},
             "constant_velocity": {"val": {"rmse_m": 0.19}, "test": {"rmse_m": 0.18}},
             "kalman": {"val": {"rmse_m": 0.094}, "test": {"rmse_m": 0.08}},
             "n_windows": {"train": 20000, "val": 4000, "test": 500}, "paper": {"val_rmse": 0.07}}
    loc = {"straight_car": {"error_median_m": 0.17, "error_p90_m": 0.26, "n_hidden_frames": 43,
                            "n_points_while_hidden": 2}}
    base = {"localise": loc, "train": train, "interpolate": interpolate_metrics(),
            "evaluate": evaluate_metrics(), "ethucy": None}
    return {**base, **over}


def table_row(page: str, quantity: str) -> list[str]:
    line = next(ln for ln in page.splitlines() if ln.startswith(f"| {quantity} |"))
    return [c.strip() for c in line.strip("|").split("|")]


def test_page_without_ethucy_has_paper_values_and_figures():
    page = build_page(page_metrics(), {"table1": "## Table 1: x\n\n| a |\n", "table2": None})
    row = table_row(page, "One-step validation RMSE (Table 1)")
    assert row[1].startswith("0.07") and row[2] == "LSTM 0.0664 m" and "Kalman (CV) 0.0940 m" in row[3]
    assert row[4] == "`dvc repro train`"
    row = table_row(page, "Paper's metric, mean over the prediction (vs simulated truth), three paper walks")
    assert row[1] == f"{PATH_ERROR_MEAN_M.value} m" and row[2] == "LSTM 0.200 m"
    row = table_row(page, "ETH/UCY average ADE / FDE (observe 8, predict 12)")
    assert row[1] == "CVM 0.52 / 1.14 m (published)" and row[2].startswith("not run yet")
    for fig in ("fig04", "fig06", "fig07", "fig08", "fig09", "fig10"):
        assert f"](figures/{fig}.png)" in page and f"`python -m blindspot {fig}`" in page
    assert "### Table 1: x" in page and "not built yet" in page


def test_page_with_ethucy_reports_averages_and_verdict():
    eth = {m: {"eth": {"ade": 1.0, "fde": 2.0, "n_windows": 10}, "avg": {"ade": a, "fde": f}}
           for m, a, f in (("cvm", 0.52, 1.14), ("kalman", 0.54, 1.17), ("lstm", 0.50, 1.20))}
    eth["best"] = "lstm"                     # the model chosen on val (ethucy.json's "best")
    page = build_page(page_metrics(ethucy=eth), {})
    row = table_row(page, "ETH/UCY average ADE / FDE (observe 8, predict 12)")
    assert row[2] == "LSTM encoder 0.50 / 1.20 m (best on val)" and "CVM 0.52 / 1.14 m" in row[3]
    assert "best" not in row[3]
    eth["best"] = "kalman"                   # whichever val chose leads; the others beside it
    kalman_page = build_page(page_metrics(ethucy=eth), {})
    row = table_row(kalman_page, "ETH/UCY average ADE / FDE (observe 8, predict 12)")
    assert row[2] == "Kalman (CV) 0.54 / 1.17 m (best on val)"
    assert row[3] == "CVM 0.52 / 1.14 m; LSTM encoder 0.50 / 1.20 m"
    assert "ETH/UCY: Kalman (CV) (best on val) 0.54 / 1.17 m vs CVM" in kalman_page
    assert "does not beat CVM on ADE and FDE." in kalman_page
    assert "does not beat CVM on FDE (it does on ADE)" in page
    # issue 43: the "seeds" and "best_of_20" blocks are not models; the spread and the
    # best-of-20 are shown beside them
    eth["best"] = "lstm"
    eth["seeds"] = {"lstm": {"n": 3, "ade_sd": 0.004, "fde_sd": 0.011, "ade_mean": 0.5,
                             "fde_mean": 1.2}}
    eth["best_of_20"] = {"mix": {"avg": {"ade": 0.21, "fde": 0.35}}}
    row = table_row(build_page(page_metrics(ethucy=eth), {}),
                    "ETH/UCY average ADE / FDE (observe 8, predict 12)")
    assert row[2] == "LSTM encoder 0.50 / 1.20 m (best on val), mean of 3 seeds (sd 0.004 / 0.011 m)"
    assert row[3] == ("CVM 0.52 / 1.14 m; Kalman (CV) 0.54 / 1.17 m; "
                      "multi-modal MLP encoder best-of-20 0.21 / 0.35 m")


def test_differences_name_the_baseline_that_wins():
    text = " ".join(differences(page_metrics(evaluate=evaluate_metrics(lstm=0.5, cv=0.6, kalman=0.3))))
    assert "Kalman (CV) beats the LSTM (0.30 m vs 0.50 m)" in text
    text = " ".join(differences(page_metrics()))
    assert "the LSTM beats every baseline" in text
    assert "2.2x the paper's 0.09 m" in text  # 0.2 / 0.09


def test_benchmark_and_calibration_rows_carry_their_intervals():
    bench = {"n_walks": 300, "paired": {},
             **{m: {"path_error_mean_m": {"mean": v, "ci95": [v - 0.05, v + 0.05]},
                    "ade_1s": {"mean": v / 2, "ci95": [v / 2 - 0.02, v / 2 + 0.02]}}
                for m, v in (("lstm", 0.6), ("kalman", 0.35))},
             "fill_kalman": {"hidden_mean_m": {"mean": 0.25, "ci95": [0.22, 0.28]}},
             # the seed-ensemble members and their summary have a table of their own
             "lstm_member0": {"path_error_mean_m": {"mean": 0.7, "ci95": [0.6, 0.8]}},
             "lstm_members": {"n_members": 1, "path_error_mean_m": {"min": 0.7, "max": 0.7}}}
    cal = {"lstm": {"sim_paths": {"coverage_50": 0.6, "coverage_90": 0.85, "coverage_95": 0.87,
                                  "nll": 0.7}}}
    page = build_page(page_metrics(benchmark=bench, calibration=cal),
                      {"benchmark": "| method | x |\n|---|---|\n| LSTM | 1 |\n"})
    row = table_row(page, "Paper's metric, mean over the prediction, 300-walk benchmark (95 % interval)")
    assert row[2] == "LSTM (paper) 0.600 [0.550, 0.650] m"
    assert row[3] == "Kalman (CV) 0.350 [0.300, 0.400] m"
    row = table_row(page, "ADE up to 1 s, 300-walk benchmark (95 % interval)")
    assert row[2] == "LSTM (paper) 0.300 [0.280, 0.320] m"
    row = table_row(page, "Coverage of the 50/90/95 % ellipses and NLL (nats), sim_paths")
    assert row[2] == "LSTM (paper) 0.600 / 0.850 / 0.870, NLL 0.70"
    # on an ETH/UCY fold the key "lstm" is the direct predictor with an LSTM encoder
    cal["lstm"]["eth"] = cal["lstm"]["sim_paths"]
    row = table_row(build_page(page_metrics(calibration=cal), {}),
                    "Coverage of the 50/90/95 % ellipses and NLL (nats), eth")
    assert row[2] == "LSTM encoder 0.600 / 0.850 / 0.870, NLL 0.70"
    # ... and the "ours" cell of a fold is the model val chose there
    cal["mlp"] = {"eth": {"coverage_50": 0.5, "coverage_90": 0.9, "coverage_95": 0.95, "nll": 0.1}}
    eth = {m: {"eth": {"ade": 1.0, "fde": 2.0, "n_windows": 10}, "avg": {"ade": 0.5, "fde": 1.0}}
           for m in ("cvm", "lstm", "mlp")}
    eth["best"] = "mlp"
    row = table_row(build_page(page_metrics(calibration=cal, ethucy=eth), {}),
                    "Coverage of the 50/90/95 % ellipses and NLL (nats), eth")
    assert row[2] == "MLP encoder 0.500 / 0.900 / 0.950, NLL 0.10"
    assert row[3] == "LSTM encoder 0.600 / 0.850 / 0.870, NLL 0.70"
    assert "](figures/benchmark.png)" in page and "| LSTM | 1 |" in page


def test_summary_rows_when_nothing_has_run():
    rows = summary_rows({})
    assert all(len(r) == 5 for r in rows)
    assert sum("not run yet" in r[2] for r in rows) == 8   # + benchmark, calibration, direct


def test_direct_rows_put_the_direct_lstm_beside_the_paper_lstm_and_cv():
    from blindspot.report.page import direct_rows

    per = {"ade_10": 0.05, "fde_10": 0.08, "ade_30": 0.15, "fde_30": 0.31, "n_pairs": 929}
    worse = {k: (2 * v if k != "n_pairs" else v) for k, v in per.items()}
    rows = direct_rows({"lstm_direct": {"test": per}, "lstm": {"test": worse},
                        "constant_velocity": {"test": worse}, "steps_frames": [10, 30],
                        "frame_period_s": 0.1})
    assert [r[0] for r in rows] == ["ADE / FDE up to 1 s, held-out radar paths (929 pairs)",
                                    "ADE / FDE up to 3 s, held-out radar paths (929 pairs)"]
    assert rows[1][2] == "direct LSTM (ours) 0.150 m / 0.310 m"
    assert rows[1][3] == ("LSTM (paper) 0.300 m / 0.620 m; "
                          "constant velocity 0.300 m / 0.620 m")
