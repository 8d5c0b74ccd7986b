"""blindspot.track.recordings.tracker_input: a recording's points made the tracker's input, and
what it refuses (no data needed)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from blindspot.track.recordings import tracker_input


def test_tracker_input_names_what_the_points_lack():
    """A recording's points without a position column, or without any radial speed when the
    Doppler is asked for, are refused naming the column; without Doppler they are enough."""
    pts = pd.DataFrame({"frame": [0, 0, 1], "time_s": [0.0, 0.0, 0.1], "x_m": [1.0, 2.0, np.nan],
                        "y_m": [3.0, 4.0, np.nan]})
    with pytest.raises(ValueError, match=r"tracker_input: points: missing columns \['y_m'\]"):
        tracker_input(pts.drop(columns="y_m"), doppler=False)
    with pytest.raises(ValueError, match="velocity_over_ground_mps' or 'velocity_mps'"):
        tracker_input(pts)
    out = tracker_input(pts, doppler=False)
    assert out.frame.tolist() == [0, 0, 1] and np.isnan(out.x_m.iloc[-1])
    moving = tracker_input(pts.assign(velocity_mps=[0.5, -0.5, np.nan]))
    assert moving.velocity_over_ground_mps.tolist()[:2] == [0.5, -0.5]
