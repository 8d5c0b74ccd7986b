"""The independent draws (issue 40, blindspot.safety.draws): each with its own seed and size on
the main draw's grid, scenes that differ from the main draw's and from each other, the config
refusing a shared seed, and the block that safety.json carries."""

from __future__ import annotations

import dataclasses

import pytest

from blindspot.radar.driving import draw_scenarios
from blindspot.radar.scenario import load_scenarios
from blindspot.safety.draws import DRAW_KEYS, draw_block, draw_noise, draw_truth, independent_scenes
from blindspot.typed_config import ConfigError


@pytest.fixture(scope="module")
def scenario(composed_config):
    return load_scenarios(composed_config.scenario)


def test_each_draw_has_its_own_seed_and_size_on_the_same_grid(scenario):
    group, named = scenario
    mc = group.monte_carlo
    held = independent_scenes(group, named, mc.held_out_seed, 2)
    tune = independent_scenes(group, named, mc.tuning_seed, 3)
    main = draw_scenarios(group, named[group.figure_scene])
    cells = len(mc.speeds_kmh) * len(mc.impact_pct) * 2
    assert len(held) == cells * 2 and len(tune) == cells * 3
    assert len(main) == cells * mc.scenes_per_cell
    for a, b in ((held, main), (tune, main), (held, tune)):      # other random streams
        assert {s.seed for s in a}.isdisjoint({s.seed for s in b})
    assert {s.speed_kmh for s in held} == {s.speed_kmh for s in tune} == {s.speed_kmh for s in main}
    # the held-out draw is the one the held-out stage drew before there was a tuning draw:
    # draw_scenarios with its seed and size, nothing else changed
    before = draw_scenarios(dataclasses.replace(group, monte_carlo=dataclasses.replace(
        mc, seed=mc.held_out_seed, held_out_seed=mc.seed, tuning_seed=mc.held_out_seed + 7,
        scenes_per_cell=2)), named[group.figure_scene])
    assert [(s.name, s.seed) for s in before] == [(s.name, s.seed) for s in held]
    truth, meta = draw_truth(held[:2], group, 0.1)
    assert set(truth.set) == {"monte_carlo"} and set(meta) == {s.name for s in held[:2]}


def test_a_seed_shared_by_two_draws_is_refused(scenario):
    group, named = scenario
    mc = group.monte_carlo
    with pytest.raises(ConfigError, match="held_out_seed.*other than monte_carlo.seed"):
        dataclasses.replace(mc, held_out_seed=mc.seed)
    for shared in (mc.seed, mc.held_out_seed):
        with pytest.raises(ConfigError, match="tuning_seed.*other than monte_carlo.seed"):
            dataclasses.replace(mc, tuning_seed=shared)
    with pytest.raises(ValueError, match="independent_scenes: seed: expected .* other than the "
                                         "main draw's"):
        independent_scenes(group, named, mc.seed, 2)
    with pytest.raises(ValueError, match="independent_scenes: per_cell: expected an integer"):
        independent_scenes(group, named, mc.tuning_seed, 0)
    with pytest.raises(KeyError, match="independent_scenes: figure scene"):
        independent_scenes(group, {}, mc.tuning_seed, 1)


def test_the_block_has_the_issue_shape():
    by_speed = {"10": {"avoided_after_visible_rate": 1.0}, "60": {"avoided_after_visible_rate": 0.2}}
    m = {k: 0.5 for k in DRAW_KEYS} | {"n_intruding": 306, "n_non_intruding": 306,
                                            "first_point_to_moving_s": {"median": 0.3},
                                            "first_point_to_aeb_s": {"median": 0.7},
                                            "by_speed_kmh": by_speed}
    block = draw_block({"track_state": m, "held_out": {}, "tuning": {}}, seed=1)
    assert block["seed"] == 1 and block["n_intruding"] == 306 and block["n_non_intruding"] == 306
    t = block["track_state"]
    assert t["first_point_to_moving_s_median"] == 0.3 and t["first_point_to_aeb_s_median"] == 0.7
    assert t["avoided_after_visible_rate_by_speed_kmh"] == {"10": 1.0, "60": 0.2}
    assert set(block) == {"seed", "n_intruding", "n_non_intruding", "track_state"}


def test_each_draw_measures_with_its_own_noise_seed(composed_config):
    from blindspot.dsp.config import EgoMotionConfig

    ego = EgoMotionConfig.from_cfg(composed_config)
    a, b = draw_noise(ego, 1), draw_noise(ego, 2)
    assert a.seed != ego.seed and a.seed != b.seed and a == draw_noise(ego, 1)
    assert dataclasses.replace(a, seed=ego.seed) == ego                 # nothing else changes
    with pytest.raises(ValueError, match="draw_noise: seed: expected an integer"):
        draw_noise(ego, -1)


def test_bad_arguments_are_named():
    with pytest.raises(ValueError, match="draw_block: metrics: expected the per-predictor"):
        draw_block({"tuning": {}}, seed=1)
    with pytest.raises(ValueError, match="draw_truth: scenes: expected at least one"):
        draw_truth([], None, 0.1)
