"""Euro NCAP 2026 bands of impact speeds per ego speed, as the scoring table of
../shared/scenarios/EURO_NCAP_PEDESTRIAN.md ([R] euroncap_rating_2026) gives them."""

import numpy as np
import pytest

from blindspot.safety.ncap import ncap_band

CASES = [  # ego km/h, impact km/h, band, score
    (10, 0, "green", 1.0), (10, 0.5, "red", 0.0), (20, 3, "red", 0.0),
    (30, 0, "green", 1.0), (30, 10, "brown", 0.25), (30, 10.5, "red", 0.0),
    (40, 10, "orange", 0.5), (40, 15, "brown", 0.25), (40, 21, "red", 0.0),
    (50, 5, "yellow", 0.75), (50, 20, "orange", 0.5), (50, 30, "brown", 0.25),
    (60, 31, "red", 0.0), (60, np.nan, "green", 1.0),
]


@pytest.mark.parametrize("ego,imp,band,score", CASES)
def test_band_per_table(ego, imp, band, score):
    names, scores = ncap_band(ego, imp)
    assert np.ravel(names)[0] == band and np.ravel(scores)[0] == score


def test_off_grid_speed_is_refused():
    with pytest.raises(ValueError, match="grid"):
        ncap_band(35.0, 0.0)
