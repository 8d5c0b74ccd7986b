"""The held-out draw (issue 40): an independent Monte-Carlo set of the same grid, drawn with its
own seed (``scenario.monte_carlo.held_out_seed``, ``held_out_scenes_per_cell`` scenes per cell),
run through the whole chain with the settings chosen on the tuning draw (the main draw of the
driving stages) and its own receiver noise (:func:`held_out_noise`), and scored the way the safety stage scores: the only numbers here that no
setting was chosen on.

The chain is the driving stages' own functions, in memory: scene truth
(:func:`blindspot.radar.driving.scene_truth`), the radar measurement
(:func:`blindspot.synth.driving_measurement.measure_driving`), the tracker with its moving test
(:func:`blindspot.synth.driving_tracks.driving_tracks`) and the decision's assessment
(:func:`blindspot.safety.assess.assess`, tracker input).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from blindspot.radar.driving import describe_scenes, draw_scenarios, scene_truth

__all__ = ["HELD_OUT_KEYS", "held_out_scenes", "held_out_truth", "held_out_noise",
           "held_out_block"]

#: Per predictor, the numbers of the held-out block (``safety.json["held_out"]``).
HELD_OUT_KEYS = ("avoided_after_visible_rate", "avoided_after_visible_rate_ci95",
                 "avoided_rate", "avoided_rate_ci95", "false_activation_rate",
                 "false_activation_rate_ci95")


def held_out_scenes(group, named: dict) -> list:
    """The held-out draw's scenes: :func:`~blindspot.radar.driving.draw_scenarios` of ``group``
    (a :class:`~blindspot.radar.scenario.ScenarioGroup`) with its Monte-Carlo seed and scenes
    per cell replaced by ``held_out_seed`` and ``held_out_scenes_per_cell``, around the figure
    scene of ``named`` (name -> scene). Raises KeyError naming a figure scene ``named`` lacks."""
    mc = group.monte_carlo
    if group.figure_scene not in named:
        raise KeyError(f"held_out_scenes: figure scene {group.figure_scene!r} is not among the "
                       f"named scenes {sorted(named)}")
    held = dataclasses.replace(mc, seed=mc.held_out_seed, held_out_seed=mc.seed,
                               scenes_per_cell=mc.held_out_scenes_per_cell)
    return draw_scenarios(dataclasses.replace(group, monte_carlo=held),
                          named[group.figure_scene])


def held_out_noise(ego, held_out_seed: int):
    """The ``ego_motion`` settings (:class:`~blindspot.dsp.config.EgoMotionConfig`) of the
    held-out measurement: its seed, which seeds the measurement's random draws (the receiver
    noise) batch by batch (:func:`~blindspot.synth.driving_measurement.measure_driving`), drawn from
    (``ego.seed``, ``held_out_seed``), so the held-out scenes do not reuse the tuning draw's
    noise fields batch by batch. Raises ValueError for a negative ``held_out_seed``."""
    if not (isinstance(held_out_seed, (int, np.integer)) and held_out_seed >= 0):
        raise ValueError(f"held_out_noise: held_out_seed: expected an integer >= 0, found "
                         f"{held_out_seed!r}")
    seed = int(np.random.SeedSequence([int(ego.seed), int(held_out_seed)]).generate_state(
        1, np.uint64)[0] >> np.uint64(1))
    return dataclasses.replace(ego, seed=seed)


def held_out_truth(scenes: list, group, frame_period_s: float) -> tuple[pd.DataFrame, dict]:
    """(truth, scenes.json-like description) of ``scenes``, all in the set ``monte_carlo``
    (what :func:`~blindspot.safety.assess.assess` evaluates)."""
    if not scenes:
        raise ValueError("held_out_truth: scenes: expected at least one scene, found none")
    truth = pd.concat([scene_truth(s, group, frame_period_s).assign(set="monte_carlo")
                       for s in scenes], ignore_index=True)
    return truth, describe_scenes([("monte_carlo", s) for s in scenes], truth)


def held_out_block(metrics: dict, seed: int) -> dict:
    """The held-out block of ``safety.json`` from :func:`~blindspot.safety.assess.assess`'s
    metrics of the held-out draw (tracker input): ``seed``, ``n_intruding``,
    ``n_non_intruding`` and per predictor :data:`HELD_OUT_KEYS` plus the medians of first radar
    point -> first moving track and -> AEB request (s) and the per-speed avoided-after-visible
    rates. Raises ValueError for metrics without predictors."""
    preds = {k: v for k, v in metrics.items()
             if isinstance(v, dict) and "avoided_after_visible_rate" in v}
    if not preds:
        raise ValueError("held_out_block: metrics: expected the per-predictor metrics of "
                         "assess(), found none")
    first = next(iter(preds.values()))
    out: dict = {"seed": int(seed), "n_intruding": int(first["n_intruding"]),
                 "n_non_intruding": int(first["n_non_intruding"])}
    for name, m in preds.items():
        out[name] = {**{k: m[k] for k in HELD_OUT_KEYS},
                     "first_point_to_moving_s_median": m["first_point_to_moving_s"]["median"],
                     "first_point_to_aeb_s_median": m["first_point_to_aeb_s"]["median"],
                     "avoided_after_visible_rate_by_speed_kmh": {
                         k: v["avoided_after_visible_rate"]
                         for k, v in m["by_speed_kmh"].items()}}
    return out
