"""blindspot.dsp.localisation: points against the simulated truth, per scene."""

import math

import numpy as np
import pandas as pd
import pytest

from blindspot.dsp.localisation import localisation_errors


def _truth():
    return pd.DataFrame({
        "scene": ["a"] * 4 + ["b"] * 2,
        "frame": [0, 1, 2, 3, 0, 1],
        "x_m": [0.0, 1.0, 2.0, 3.0, 5.0, 5.0],
        "y_m": [10.0] * 6,
        "occluded": [False, True, True, False, False, False],
    })


def test_errors_counts_and_order_per_scene():
    points = pd.DataFrame({"scene": ["a", "a", "a"], "frame": [0, 1, 3],
                           "x_m": [0.3, 1.0, 3.0], "y_m": [10.4, 10.0, 11.0]})
    out = localisation_errors(points, _truth())
    assert list(out) == ["a", "b"]
    a = out["a"]
    assert (a["n_frames"], a["n_points"], a["n_hidden_frames"], a["n_points_while_hidden"]) == (4, 3, 2, 1)
    errors = np.array([0.5, 0.0, 1.0])  # 3-4-5 triangle, exact hit, 1 m off in y
    assert a["error_median_m"] == pytest.approx(0.5)
    assert a["error_mean_m"] == pytest.approx(errors.mean())
    assert a["error_p90_m"] == pytest.approx(np.percentile(errors, 90))
    b = out["b"]
    assert b["n_points"] == 0 and b["n_frames"] == 2
    assert all(math.isnan(b[k]) for k in ("error_median_m", "error_p90_m", "error_mean_m"))


def test_points_of_unknown_frames_are_ignored():
    points = pd.DataFrame({"scene": ["a", "a"], "frame": [0, 9], "x_m": [0.0, 50.0],
                           "y_m": [10.0, 10.0]})
    a = localisation_errors(points, _truth())["a"]
    assert a["n_points"] == 1 and a["error_mean_m"] == 0.0
