"""The operating characteristic draws every input x predictor curve, its configured point and
the perception bounds at 0 % false activations, where a perfect decider sits; the Euro NCAP
grid's Markdown says how many scenes braked before the lead pedestrian was visible."""

import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from blindspot.report.safety_figures import fig_operating_characteristic  # noqa: E402


def test_operating_characteristic_draws_curves_points_and_bounds():
    thr = np.linspace(0.1, 0.9, 5)
    curves = pd.concat([pd.DataFrame({"threshold": thr, "avoided_rate": 1 - thr / 2,
                                      "false_activation_rate": 1 - thr, "predictor": p,
                                      "input": "tracker"})
                        for p in ("constant_velocity", "kalman")], ignore_index=True)
    operating = {"tracker": {"kalman": {"avoided_rate": 0.6, "false_activation_rate": 0.1}}}
    bounds = {"line_of_sight": 0.94, "radar_point": 0.63}
    fig = fig_operating_characteristic(curves, operating, bounds)
    ax = fig.axes[0]
    labels = [line.get_label() for line in ax.get_lines()]
    stars = [line for line in ax.get_lines() if line.get_label().startswith("bound:")]
    assert len(stars) == 2
    assert [(line.get_xdata()[0], line.get_ydata()[0]) for line in stars] == [(0.0, 94.0),
                                                                              (0.0, 63.0)]
    assert sum(label.endswith("(tracker)") for label in labels) == 2
    dots = [line for line in ax.get_lines() if line.get_marker() == "o"]
    assert [(d.get_xdata()[0], d.get_ydata()[0]) for d in dots] == [(10.0, 60.0)]
    without = fig_operating_characteristic(curves, operating)
    assert not [line for line in without.axes[0].get_lines()
                if line.get_label().startswith("bound:")]


def test_ncap_grid_markdown_says_where_the_aeb_fired_before_the_lead_was_visible():
    """A cell whose scenes braked before the lead pedestrian was visible says how many; one
    without such scenes (and a grid without the column, as before it existed) says nothing."""
    from blindspot.report.safety_figures import ncap_grid_markdown

    grid = pd.DataFrame({"predictor": "kalman", "speed_kmh": [60.0, 60.0],
                         "impact_pct": [25.0, 50.0], "n": 6, "n_avoided": [3, 1],
                         "n_aeb_before_visible": [2, 0], "impact_speed_kmh_mean": [20.0, 40.0],
                         "band": ["brown", "red"]})
    row = ncap_grid_markdown(grid, "kalman").splitlines()[2]
    assert row == ("| 60 km/h | 3/6 avoided, 20.0 km/h (brown); 2 braked before the lead "
                   "pedestrian was visible | 1/6 avoided, 40.0 km/h (red) |")
    old = ncap_grid_markdown(grid.drop(columns="n_aeb_before_visible"), "kalman")
    assert "braked" not in old
