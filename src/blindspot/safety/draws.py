"""The independent Monte-Carlo draws (issue 40): the tuning draw and the held-out draw, each a
set of the main draw's grid with its own seed and size (``scenario.monte_carlo.tuning_seed`` /
``tuning_scenes_per_cell``, ``held_out_seed`` / ``held_out_scenes_per_cell``) and its own
receiver noise (:func:`draw_noise`), run through the whole chain and scored the way the safety
stage scores. The AEB operating point is chosen on the tuning draw
(:mod:`blindspot.safety.operating_point`) and read on the held-out draw: the held-out numbers
are the only ones no setting was chosen on.

The main draw (``monte_carlo.seed``, ``scenes_per_cell``) stays the one the driving stages keep
per scene (points, tracks, risks) for the figures and the studies; the two independent draws are
run in memory (:func:`blindspot.synth.independent_draw.assess_draw`) and keep their metrics
only, so a fresh clone's repro reuses them.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from blindspot.radar.driving import describe_scenes, draw_scenarios, scene_truth

__all__ = ["DRAW_KEYS", "independent_scenes", "draw_truth", "draw_noise", "draw_block"]

#: Per predictor, the rates of a draw's block (``safety_tuning.json``, ``safety_held_out.json``).
DRAW_KEYS = ("avoided_after_visible_rate", "avoided_after_visible_rate_ci95",
             "avoided_rate", "avoided_rate_ci95", "false_activation_rate",
             "false_activation_rate_ci95")


def independent_scenes(group, named: dict, seed: int, per_cell: int) -> list:
    """An independent draw's scenes: :func:`~blindspot.radar.driving.draw_scenarios` of
    ``group`` (a :class:`~blindspot.radar.scenario.ScenarioGroup`) with its Monte-Carlo seed and
    scenes per cell replaced by ``seed`` and ``per_cell``, around the figure scene of ``named``
    (name -> scene). Raises KeyError naming a figure scene ``named`` lacks, ValueError for a
    ``seed`` equal to the main draw's or a ``per_cell`` below 1."""
    mc = group.monte_carlo
    if group.figure_scene not in named:
        raise KeyError(f"independent_scenes: figure scene {group.figure_scene!r} is not among "
                       f"the named scenes {sorted(named)}")
    if not (isinstance(seed, (int, np.integer)) and seed >= 0) or seed == mc.seed:
        raise ValueError(f"independent_scenes: seed: expected an integer >= 0 other than the main "
                         f"draw's monte_carlo.seed = {mc.seed}, found {seed!r}")
    if not (isinstance(per_cell, (int, np.integer)) and per_cell >= 1):
        raise ValueError(f"independent_scenes: per_cell: expected an integer >= 1, found "
                         f"{per_cell!r}")
    # draw_scenarios reads seed and scenes_per_cell; the other two seeds are set apart only so
    # that the config's own check (every draw's seed differs) holds for the replaced settings
    drawn = dataclasses.replace(mc, seed=int(seed), held_out_seed=mc.seed,
                                tuning_seed=mc.seed + int(seed) + 1,
                                scenes_per_cell=int(per_cell))
    return draw_scenarios(dataclasses.replace(group, monte_carlo=drawn),
                          named[group.figure_scene])


def draw_noise(ego, seed: int):
    """The ``ego_motion`` settings (:class:`~blindspot.dsp.config.EgoMotionConfig`) of an
    independent draw's measurement: its seed, which seeds the measurement's random draws (the
    receiver noise) batch by batch (:func:`~blindspot.synth.driving_measurement.measure_driving`),
    drawn from (``ego.seed``, ``seed``), so no draw reuses another's noise fields batch by
    batch. Raises ValueError for a negative ``seed``."""
    if not (isinstance(seed, (int, np.integer)) and seed >= 0):
        raise ValueError(f"draw_noise: seed: expected an integer >= 0, found {seed!r}")
    mixed = int(np.random.SeedSequence([int(ego.seed), int(seed)]).generate_state(
        1, np.uint64)[0] >> np.uint64(1))
    return dataclasses.replace(ego, seed=mixed)


def draw_truth(scenes: list, group, frame_period_s: float) -> tuple[pd.DataFrame, dict]:
    """(truth, scenes.json-like description) of ``scenes``, all in the set ``monte_carlo``
    (what :func:`~blindspot.safety.assess.assess` evaluates)."""
    if not scenes:
        raise ValueError("draw_truth: scenes: expected at least one scene, found none")
    truth = pd.concat([scene_truth(s, group, frame_period_s).assign(set="monte_carlo")
                       for s in scenes], ignore_index=True)
    return truth, describe_scenes([("monte_carlo", s) for s in scenes], truth)


def draw_block(metrics: dict, seed: int) -> dict:
    """A draw's block of ``safety.json`` from :func:`~blindspot.safety.assess.assess`'s metrics
    of the draw (tracker input): ``seed``, ``n_intruding``, ``n_non_intruding`` and per
    predictor :data:`DRAW_KEYS` plus the medians of first radar point -> first moving track and
    -> AEB request (s) and the per-speed avoided-after-visible rates. Raises ValueError for
    metrics without predictors."""
    preds = {k: v for k, v in metrics.items()
             if isinstance(v, dict) and "avoided_after_visible_rate" in v}
    if not preds:
        raise ValueError("draw_block: metrics: expected the per-predictor metrics of "
                         "assess(), found none")
    first = next(iter(preds.values()))
    out: dict = {"seed": int(seed), "n_intruding": int(first["n_intruding"]),
                 "n_non_intruding": int(first["n_non_intruding"])}
    for name, m in preds.items():
        out[name] = {**{k: m[k] for k in DRAW_KEYS},
                     "first_point_to_moving_s_median": m["first_point_to_moving_s"]["median"],
                     "first_point_to_aeb_s_median": m["first_point_to_aeb_s"]["median"],
                     "avoided_after_visible_rate_by_speed_kmh": {
                         k: v["avoided_after_visible_rate"]
                         for k, v in m["by_speed_kmh"].items()}}
    return out
