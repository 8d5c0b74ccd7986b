"""The held-out draw (issue 40, blindspot.safety.held_out): its own seed and size on the same
grid, scenes that differ from the tuning draw's, the config refusing a shared seed, and the
block that safety.json carries."""

from __future__ import annotations

import dataclasses

import pytest

from blindspot.radar.driving import draw_scenarios
from blindspot.radar.scenario import load_scenarios
from blindspot.safety.held_out import HELD_OUT_KEYS, held_out_block, held_out_scenes, held_out_truth
from blindspot.typed_config import ConfigError


@pytest.fixture(scope="module")
def scenario(composed_config):
    return load_scenarios(composed_config.scenario)


def test_the_held_out_draw_has_its_own_seed_and_size_on_the_same_grid(scenario):
    group, named = scenario
    mc = group.monte_carlo
    small = dataclasses.replace(group, monte_carlo=dataclasses.replace(
        mc, held_out_scenes_per_cell=2))
    held = held_out_scenes(small, named)
    tune = draw_scenarios(group, named[group.figure_scene])
    cells = len(mc.speeds_kmh) * len(mc.impact_pct) * 2
    assert len(held) == cells * 2 and len(tune) == cells * mc.scenes_per_cell
    assert {s.seed for s in held}.isdisjoint({s.seed for s in tune})   # another random stream
    assert {(s.speed_kmh) for s in held} == {(s.speed_kmh) for s in tune}
    truth, meta = held_out_truth(held[:2], small, 0.1)
    assert set(truth.set) == {"monte_carlo"} and set(meta) == {s.name for s in held[:2]}


def test_a_held_out_seed_equal_to_the_tuning_seed_is_refused(scenario):
    mc = scenario[0].monte_carlo
    with pytest.raises(ConfigError, match="held_out_seed.*other than monte_carlo.seed"):
        dataclasses.replace(mc, held_out_seed=mc.seed)


def test_the_block_has_the_issue_shape():
    by_speed = {"10": {"avoided_after_visible_rate": 1.0}, "60": {"avoided_after_visible_rate": 0.2}}
    m = {k: 0.5 for k in HELD_OUT_KEYS} | {"n_intruding": 306, "n_non_intruding": 306,
                                            "first_point_to_moving_s": {"median": 0.3},
                                            "first_point_to_aeb_s": {"median": 0.7},
                                            "by_speed_kmh": by_speed}
    block = held_out_block({"track_state": m, "held_out": {}, "tuning": {}}, seed=1)
    assert block["seed"] == 1 and block["n_intruding"] == 306 and block["n_non_intruding"] == 306
    t = block["track_state"]
    assert t["first_point_to_moving_s_median"] == 0.3 and t["first_point_to_aeb_s_median"] == 0.7
    assert t["avoided_after_visible_rate_by_speed_kmh"] == {"10": 1.0, "60": 0.2}
    assert set(block) == {"seed", "n_intruding", "n_non_intruding", "track_state"}


def test_the_held_out_measurement_has_its_own_noise_seed(composed_config):
    from blindspot.dsp.config import EgoMotionConfig
    from blindspot.safety.held_out import held_out_noise

    ego = EgoMotionConfig.from_cfg(composed_config)
    a, b = held_out_noise(ego, 1), held_out_noise(ego, 2)
    assert a.seed != ego.seed and a.seed != b.seed and a == held_out_noise(ego, 1)
    assert dataclasses.replace(a, seed=ego.seed) == ego                 # nothing else changes
    with pytest.raises(ValueError, match="held_out_noise: held_out_seed: expected an integer"):
        held_out_noise(ego, -1)


def test_bad_arguments_are_named():
    with pytest.raises(ValueError, match="held_out_block: metrics: expected the per-predictor"):
        held_out_block({"tuning": {}}, seed=1)
    with pytest.raises(ValueError, match="held_out_truth: scenes: expected at least one"):
        held_out_truth([], None, 0.1)
