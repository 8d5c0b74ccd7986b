"""blindspot.traj.evaluation over scenes: interpolation scores and the prediction aggregate."""

import numpy as np
import pandas as pd
import pytest

from blindspot.traj.evaluation import (
    evaluate_predictions,
    gap_mask,
    mean_error_by_step,
    mean_over_scenes,
    score_interpolation,
)


def test_gap_mask_only_interior_gaps():
    observed = np.array([0, 1, 1, 0, 0, 1, 0], bool)
    assert gap_mask(observed).tolist() == [False, False, False, True, True, False, False]


def test_score_interpolation_on_hidden_and_all_filled_frames():
    truth = np.zeros((6, 2))
    filled = np.array([[0, 0], [3, 4], [0, 1], [0, 2], [0, 0], [0, 0]], float)
    observed = np.array([1, 0, 0, 0, 1, 1], bool)  # frames 1..3 filled
    hidden = np.array([0, 0, 1, 1, 1, 0], bool)    # 2, 3 hidden and filled; 4 hidden but seen
    s = score_interpolation(filled, truth, observed, hidden)
    assert s == {"hidden_mean_m": 1.5, "hidden_median_m": 1.5, "hidden_max_m": 2.0,
                 "all_gaps_mean_m": pytest.approx(8 / 3), "n_hidden_filled": 2, "n_filled": 3}
    with pytest.raises(ValueError, match="no hidden frame"):
        score_interpolation(filled, truth, observed, np.zeros(6, bool))


def test_mean_over_scenes_adds_all_scenes():
    per = {"lstm": {"a": {"hidden_mean_m": 1.0}, "b": {"hidden_mean_m": 3.0}}}
    out = mean_over_scenes(per)
    assert out["lstm"]["all_scenes"] == {"hidden_mean_m": 2.0}
    assert "all_scenes" not in per["lstm"]


def _prediction(scene, method, xs, start=10):
    n = len(xs)
    return pd.DataFrame({"scene": scene, "method": method, "step": np.arange(1, n + 1),
                         "frame": np.arange(start, start + n), "x_m": xs, "y_m": 0.0})


def test_evaluate_predictions_means_over_scenes_and_per_step_table():
    truth = pd.concat([pd.DataFrame({"scene": s, "frame": np.arange(20), "x_m": 0.0, "y_m": 0.0})
                       for s in ("a_car", "b_car")], ignore_index=True)
    predictions = pd.concat([_prediction("a_car", "cv", [1.0, 2.0]),
                             _prediction("b_car", "cv", [3.0, 4.0])], ignore_index=True)
    tracks = {"a_car": np.zeros((5, 2)), "b_car": np.full((5, 2), [3.0, 0.0])}
    metrics, curve = evaluate_predictions(predictions, truth, tracks, 0.1, (0.1,))
    cv = metrics["cv"]
    assert cv["ade_m"] == pytest.approx(2.5) and cv["fde_m"] == pytest.approx(3.0)
    assert cv["ade_0.1s"] == pytest.approx(2.0)
    assert cv["per_scene"]["a_car"]["path_error_radar_mean_m"] == pytest.approx(1.5)
    assert cv["per_scene"]["b_car"]["path_error_radar_mean_m"] == pytest.approx(0.5)
    assert cv["path_error_radar_mean_m"] == pytest.approx(1.0)
    assert "per_step_m" not in cv["per_scene"]["a_car"]
    assert curve.error_m.tolist() == [1.0, 2.0, 3.0, 4.0]
    assert curve.path_error_radar_m.tolist() == [1.0, 2.0, 0.0, 1.0]
    mean = mean_error_by_step(curve, 0.1)
    assert mean.error_m.tolist() == [2.0, 3.0] and mean.time_s.tolist() == pytest.approx([0.1, 0.2])


def test_without_radar_tracks_no_radar_metric():
    truth = pd.DataFrame({"scene": "a_car", "frame": np.arange(20), "x_m": 0.0, "y_m": 0.0})
    metrics, curve = evaluate_predictions(_prediction("a_car", "cv", [1.0]), truth, {}, 0.1, ())
    assert "path_error_radar_mean_m" not in metrics["cv"]
    assert np.isnan(curve.path_error_radar_m).all()
