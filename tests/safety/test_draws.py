"""The independent draws (issue 40, blindspot.safety.draws): each with its own seed and size on
the main draw's grid, scenes that differ from the main draw's and from each other, the config
refusing a shared seed, and the block that safety.json carries."""

from __future__ import annotations

import dataclasses
import json

import pandas as pd
import pytest

from blindspot.radar.driving import draw_scenarios
from blindspot.radar.scenario import load_scenarios
from blindspot.safety.draws import (CHAIN_KEYS, CURVE_COLUMNS, DRAW_KEYS, chain_digest, draw_block,
                                    draw_curve, draw_noise, draw_summary, draw_truth,
                                    independent_scenes, read_draw)
from blindspot.typed_config import ConfigError


@pytest.fixture(scope="module")
def scenario(composed_config):
    return load_scenarios(composed_config.scenario)


def test_each_draw_has_its_own_seed_and_size_on_the_same_grid(scenario):
    group, named = scenario
    mc = group.monte_carlo
    held = independent_scenes(group, named, 1, 2)           # seed 1: held out until 2026-12-06
    tune = independent_scenes(group, named, mc.tuning_seed, 3)
    main = draw_scenarios(group, named[group.figure_scene])
    cells = len(mc.speeds_kmh) * len(mc.impact_pct) * 2
    assert len(held) == cells * 2 and len(tune) == cells * 3
    assert len(main) == cells * mc.scenes_per_cell
    for a, b in ((held, main), (tune, main), (held, tune)):      # other random streams
        assert {s.seed for s in a}.isdisjoint({s.seed for s in b})
    assert {s.speed_kmh for s in held} == {s.speed_kmh for s in tune} == {s.speed_kmh for s in main}
    # the draw of seed 1 is the one the held-out stage drew before there was a tuning draw
    # (blindspot.safety.held_out of commit 371bd37, tiny profile, two scenes per cell)
    assert [(s.name, s.seed) for s in held[:3] + held[-2:]] == [
        ("mc_10kmh_50pct_int_0", 5604234053417415), ("mc_10kmh_50pct_int_1", 3429966622256762451),
        ("mc_10kmh_50pct_non_0", 3949958476665750071),
        ("mc_60kmh_50pct_non_0", 1294774581593759387),
        ("mc_60kmh_50pct_non_1", 1226750386545864632)]
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
    with pytest.raises(ValueError, match="independent_scenes: seed: expected a seed other than "
                                         "the main draw's"):
        independent_scenes(group, named, mc.seed, 2)
    with pytest.raises(ValueError, match="draw_scenarios: per_cell: expected an integer >= 1"):
        independent_scenes(group, named, mc.tuning_seed, 0)
    with pytest.raises(ValueError, match="draw_scenarios: seed: expected an integer >= 0"):
        independent_scenes(group, named, True, 2)
    with pytest.raises(KeyError, match="independent_scenes: figure scene"):
        independent_scenes(group, {}, mc.tuning_seed, 1)


def _curves(*predictors):
    return pd.concat([pd.DataFrame({"threshold": [0.25, 0.5], "avoided_rate": [0.5, 0.4],
                                    "avoided_after_visible_rate": [0.4, 0.3],
                                    "false_activation_rate": [0.2, 0.1],
                                    "impact_speed_kmh_mean": [3.0, 4.0]})
                      .assign(input=i, predictor=p)
                      for p in predictors for i in ("tracker", "oracle")], ignore_index=True)


def test_the_block_has_the_issue_shape_and_its_curves():
    by_speed = {"10": {"avoided_after_visible_rate": 1.0}, "60": {"avoided_after_visible_rate": 0.2}}
    m = {k: 0.5 for k in DRAW_KEYS} | {"n_intruding": 306, "n_non_intruding": 306,
                                       "first_point_to_confirmed_s": {"median": 0.2},
                                       "first_point_to_moving_s": {"median": 0.3},
                                       "first_point_to_aeb_s": {"median": 0.7},
                                       "by_speed_kmh": by_speed}
    block = draw_block({"track_state": m, "held_out": {}, "tuning": {}}, 1,
                       _curves("track_state"), "abc")
    assert block["seed"] == 1 and block["n_intruding"] == 306 and block["n_non_intruding"] == 306
    t = block["track_state"]
    assert t["first_point_to_moving_s_median"] == 0.3 and t["first_point_to_aeb_s_median"] == 0.7
    assert t["first_point_to_confirmed_s_median"] == 0.2
    line = draw_summary("held", block)[0]
    assert "first point -> confirmed 0.20 s, -> moving 0.30 s, -> AEB 0.70 s" in line
    t["first_point_to_confirmed_s_median"] = None               # no child ever confirmed
    assert "-> confirmed - s" in draw_summary("held", block)[0]
    assert t["avoided_after_visible_rate_by_speed_kmh"] == {"10": 1.0, "60": 0.2}
    assert set(block) == {"seed", "chain_digest", "n_intruding", "n_non_intruding", "track_state"}
    curve = draw_curve(block, "track_state")                       # the tracker's, read back
    assert list(curve.columns) == list(CURVE_COLUMNS)
    assert curve.false_activation_rate.tolist() == [0.2, 0.1]
    with pytest.raises(ValueError, match="draw_block: curves: no tracker-input curve of "
                                         "predictor 'track_state'"):
        draw_block({"track_state": m}, 1, _curves("kalman"), "abc")
    with pytest.raises(KeyError, match="draw_curve: block of seed 1: no curve of predictor 'x'"):
        draw_curve(block, "x")


def test_a_block_is_read_only_with_the_chain_settings_it_was_made_with(composed_config,
                                                                       tmp_path):
    digest = chain_digest(composed_config)
    assert digest == chain_digest(composed_config) and len(digest) == 16
    other = composed_config.copy()
    other.tracker.process_noise_m2ps3 = 2 * composed_config.tracker.process_noise_m2ps3
    assert chain_digest(other) != digest
    # what no draw's numbers depend on leaves it: the budget the safety stage chooses for, a
    # figure's setting, the worker count
    same = composed_config.copy()
    same.warning.false_activation_target = 0.05
    same.eval.fig06_frame = composed_config.eval.fig06_frame + 1
    same.jobs = 7
    assert chain_digest(same) == digest
    path = tmp_path / "safety_tuning.json"
    path.write_text(json.dumps({"seed": 2, "chain_digest": digest}))
    assert read_draw(path, digest)["seed"] == 2
    with pytest.raises(ValueError, match="safety_tuning.json: made with other chain settings"):
        read_draw(path, chain_digest(other))
    path.write_text(json.dumps({"seed": 2}))
    with pytest.raises(ValueError, match="safety_tuning.json: expected a draw block"):
        read_draw(path, digest)
    path.write_text("{")
    with pytest.raises(ValueError, match="safety_tuning.json: expected a draw block in JSON, "
                                         "found invalid JSON"):
        read_draw(path, digest)
    with pytest.raises(ValueError, match="read_draw: digest: expected chain_digest's string"):
        read_draw(path, None)
    with pytest.raises(KeyError, match="chain_digest: cfg: missing config key 'tracker'"):
        chain_digest({k: composed_config[k] for k in composed_config if k != "tracker"})


def test_the_digest_hashes_what_the_draw_stages_declare():
    """The draw stages' DVC params (less jobs) are the keys the digest hashes: a key DVC reruns
    the draws for and the digest ignores (or the reverse) would let the safety stage refuse
    up-to-date draws, or read stale ones."""
    import yaml

    from ..conftest import REPO_ROOT

    stages = yaml.safe_load((REPO_ROOT / "dvc.yaml").read_text())["stages"]
    for name in ("safety_tuning", "safety_held_out"):
        assert [k for k in stages[name]["params"] if k != "jobs"] == list(CHAIN_KEYS), name


def test_each_draw_measures_with_its_own_noise_seed(composed_config):
    from blindspot.dsp.config import EgoMotionConfig

    ego = EgoMotionConfig.from_cfg(composed_config)
    a, b = draw_noise(ego, 1), draw_noise(ego, 2)
    assert a.seed != ego.seed and a.seed != b.seed and a == draw_noise(ego, 1)
    assert dataclasses.replace(a, seed=ego.seed) == ego                 # nothing else changes
    assert a.seed == 2918264622725855778          # the held-out noise of commit 371bd37
    with pytest.raises(ValueError, match="draw_noise: seed: expected an integer"):
        draw_noise(ego, -1)


def test_bad_arguments_are_named():
    with pytest.raises(ValueError, match="draw_block: metrics: expected the per-predictor"):
        draw_block({"tuning": {}}, 1, _curves("a"), "abc")
    with pytest.raises(ValueError, match="draw_block: seed: expected an integer >= 0"):
        draw_block({"tuning": {}}, -1, _curves("a"), "abc")
    with pytest.raises(ValueError, match="draw_truth: scenes: expected at least one"):
        draw_truth([], None, 0.1)


def test_assess_draw_refuses_a_with_bounds_that_is_not_a_bool():
    from blindspot.synth.independent_draw import assess_draw

    # checked before the config is read: no draw runs
    with pytest.raises(ValueError, match="with_bounds: expected True or False, found 'yes'"):
        assess_draw(None, {}, seed=3, per_cell=1, with_bounds="yes")
