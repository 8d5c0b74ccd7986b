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


def test_nominal_grids_are_one_scene_per_cell_on_the_named_geometry():
    """Issue 40: CPNCO 18 cells, CPNA 25/75 and CPFA 50 at 10-60 km/h, each the named scene
    with its speed and impact point replaced, named so the cell can be read back."""
    from pathlib import Path

    from omegaconf import OmegaConf

    from blindspot.radar.scenario import load_scenarios
    from blindspot.safety.ncap import nominal_cell, nominal_scenes

    conf = Path(__file__).resolve().parents[2] / "conf" / "scenario" / "euro_ncap.yaml"
    group, named = load_scenarios(OmegaConf.load(conf))
    scenes = nominal_scenes(named, [10.0, 20.0, 30.0, 40.0, 50.0, 60.0])
    cells = [nominal_cell(s.name) for s in scenes]
    assert sum(c[0] == "cpnco" for c in cells) == 18
    assert {c[2] for c in cells if c[0] == "cpna"} == {"25", "75"}
    assert {c[2] for c in cells if c[0] == "cpfa"} == {"50"} and len(cells) == 36
    s = scenes[cells.index(("cpnco", "40", "75"))]
    assert s.speed_kmh == 40.0 and s.pedestrians[0].impact_pct == 75.0
    assert s.parked_cars == named["cpnco"].parked_cars
    assert nominal_cell("mc_30kmh_50pct_int_3") is None
