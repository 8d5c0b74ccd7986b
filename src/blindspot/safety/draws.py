"""The independent Monte-Carlo draws (issue 40): the tuning draw and the held-out draw, each a
set of the main draw's grid with its own seed and size (``scenario.monte_carlo.tuning_seed`` /
``tuning_scenes_per_cell``, ``held_out_seed`` / ``held_out_scenes_per_cell``) and its own
receiver noise (:func:`draw_noise`), run through the whole chain and scored the way the safety
stage scores. The AEB operating point is chosen on the tuning draw
(:mod:`blindspot.safety.operating_point`) and read on the held-out draw: the held-out numbers
are the only ones no setting was chosen on.

The main draw (``monte_carlo.seed``, ``scenes_per_cell``) stays the one the driving stages keep
per scene (points, tracks, risks) for the figures and the studies (its even half tuned the
chain's settings); the two independent draws are run in memory
(:func:`blindspot.synth.independent_draw.assess_draw`) and keep their metrics and operating
characteristics only (:func:`draw_block`), git-tracked, so a fresh clone's repro reuses them.
Each block carries the digest of the chain settings it was made with (:func:`chain_digest`);
the safety stage reads a block only with the same settings (:func:`read_draw`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path

import numpy as np
import pandas as pd

from blindspot.arrays import check_count
from blindspot.radar.driving import describe_scenes, draw_scenarios, scene_truth

__all__ = ["DRAW_KEYS", "CURVE_COLUMNS", "CHAIN_KEYS", "DIGEST_EXCLUDED", "independent_scenes",
           "draw_truth", "draw_noise", "chain_digest", "draw_block", "draw_curve", "read_draw",
           "draw_summary"]

#: Per predictor, the rates of a draw's block (``safety_tuning.json``, ``safety_held_out.json``).
DRAW_KEYS = ("avoided_after_visible_rate", "avoided_after_visible_rate_ci95",
             "avoided_rate", "avoided_rate_ci95", "false_activation_rate",
             "false_activation_rate_ci95")
#: The operating characteristic a draw's block keeps per predictor
#: (:func:`blindspot.safety.evaluation.operating_curve`'s columns).
CURVE_COLUMNS = ("threshold", "avoided_rate", "avoided_after_visible_rate",
                 "false_activation_rate")
#: The config keys (groups or dotted keys) a draw's chain reads
#: (blindspot.synth.independent_draw.assess_draw and the predictors of
#: blindspot.safety.predict.stage_predictors): the draw stages' DVC params (less ``jobs``, which
#: changes no result) and what :func:`chain_digest` hashes.
CHAIN_KEYS = ("scenario", "driving_radar", "sim.adc_headroom_db", "driving_cfar", "doa",
              "detect", "ego_motion", "tracker", "warning", "calibration", "dataset.window",
              "eval.cv_fit_points", "eval.kalman", "eval.prediction_methods",
              "radar.frame_period_s")
#: Keys of :data:`CHAIN_KEYS` that no draw's numbers depend on, left out of the digest: the
#: false-activation budget is read by the safety stage's choice of the operating point only.
DIGEST_EXCLUDED = ("warning.false_activation_target",)


def independent_scenes(group, named: dict, seed: int, per_cell: int) -> list:
    """An independent draw's scenes: :func:`~blindspot.radar.driving.draw_scenarios` of
    ``group`` (a :class:`~blindspot.radar.scenario.ScenarioGroup`) with ``seed`` and
    ``per_cell`` scenes per cell, around the figure scene of ``named`` (name -> scene). Raises
    KeyError naming a figure scene ``named`` lacks, ValueError for a ``seed`` equal to the main
    draw's (``monte_carlo.seed``) or the errors of ``draw_scenarios``."""
    mc = group.monte_carlo
    if group.figure_scene not in named:
        raise KeyError(f"independent_scenes: figure scene {group.figure_scene!r} is not among "
                       f"the named scenes {sorted(named)}")
    if not isinstance(seed, (bool, np.bool_)) and seed == mc.seed:
        raise ValueError(f"independent_scenes: seed: expected a seed other than the main "
                         f"draw's monte_carlo.seed = {mc.seed}, found {seed!r}")
    return draw_scenarios(group, named[group.figure_scene], seed=seed, per_cell=per_cell)


def draw_noise(ego, seed: int):
    """The ``ego_motion`` settings (:class:`~blindspot.dsp.config.EgoMotionConfig`) of an
    independent draw's measurement: its seed, which seeds the measurement's random draws (the
    receiver noise) batch by batch (:func:`~blindspot.synth.driving_measurement.measure_driving`),
    drawn from (``ego.seed``, ``seed``), so no draw reuses another's noise fields batch by
    batch. Raises ValueError for a negative ``seed``."""
    check_count(seed, "seed", who="draw_noise")
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


def chain_digest(cfg, keys: tuple[str, ...] = CHAIN_KEYS,
                 excluded: tuple[str, ...] = DIGEST_EXCLUDED) -> str:
    """A short digest (16 hex digits) of the composed config's ``keys`` (groups or dotted keys)
    less ``excluded``: two draw blocks, or a block and the config that reads it, that share it
    were made with the same settings (the code and the models are DVC's to track). Raises
    KeyError naming a key ``cfg`` lacks."""
    from omegaconf import OmegaConf

    def value(key: str):
        node = cfg
        for part in key.split("."):
            if part not in node:
                raise KeyError(f"chain_digest: cfg: missing config key {key!r}")
            node = node[part]
        return OmegaConf.to_container(node, resolve=True) if OmegaConf.is_config(node) else node

    plain = {k: value(k) for k in keys}
    for key in excluded:
        head, _, leaf = key.rpartition(".")
        parent = plain.get(head)
        if isinstance(parent, dict):
            parent.pop(leaf, None)
    text = json.dumps(plain, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def draw_block(metrics: dict, seed: int, curves: pd.DataFrame, digest: str) -> dict:
    """A draw's block (``safety_tuning.json``, ``safety_held_out.json``) from
    :func:`~blindspot.safety.assess.assess`'s metrics and curves of the draw (tracker input):
    ``seed``, ``n_intruding``, ``n_non_intruding``, ``chain_digest`` (:func:`chain_digest`) and
    per predictor :data:`DRAW_KEYS`, the medians of first radar point -> first confirmed track,
    -> first moving track and -> AEB request (s), the per-speed avoided-after-visible rates and
    ``curve``: its operating characteristic as lists (``threshold``, ``avoided_rate``,
    ``avoided_after_visible_rate``, ``false_activation_rate``; :func:`draw_curve` reads it
    back), so that an AEB operating point chosen on another draw can be read here without
    running the draw again.

    Raises:
        ValueError: metrics without predictors, a seed that is not an integer >= 0, or a
            predictor without a tracker-input curve in ``curves``.
    """
    check_count(seed, "seed", who="draw_block")
    if not (isinstance(digest, str) and digest):
        raise ValueError(f"draw_block: digest: expected chain_digest's string, found {digest!r}")
    preds = {k: v for k, v in metrics.items()
             if isinstance(v, dict) and "avoided_after_visible_rate" in v}
    if not preds:
        raise ValueError("draw_block: metrics: expected the per-predictor metrics of "
                         "assess(), found none")
    first = next(iter(preds.values()))
    out: dict = {"seed": int(seed), "chain_digest": str(digest),
                 "n_intruding": int(first["n_intruding"]),
                 "n_non_intruding": int(first["n_non_intruding"])}
    for name, m in preds.items():
        c = curves[(curves.input == "tracker") & (curves.predictor == name)]
        if c.empty:
            raise ValueError(f"draw_block: curves: no tracker-input curve of predictor {name!r}")
        out[name] = {**{k: m[k] for k in DRAW_KEYS},
                     "first_point_to_confirmed_s_median":
                         m["first_point_to_confirmed_s"]["median"],
                     "first_point_to_moving_s_median": m["first_point_to_moving_s"]["median"],
                     "first_point_to_aeb_s_median": m["first_point_to_aeb_s"]["median"],
                     "avoided_after_visible_rate_by_speed_kmh": {
                         k: v["avoided_after_visible_rate"]
                         for k, v in m["by_speed_kmh"].items()},
                     "curve": {k: [float(x) for x in c[k]] for k in CURVE_COLUMNS}}
    return out


def draw_curve(block: dict, predictor: str) -> pd.DataFrame:
    """A predictor's operating characteristic from a draw's block (:func:`draw_block`) as a
    DataFrame of :data:`CURVE_COLUMNS`. Raises KeyError naming a predictor or column the
    block lacks."""
    entry = block.get(predictor)
    if not isinstance(entry, dict) or not isinstance(entry.get("curve"), dict):
        raise KeyError(f"draw_curve: block of seed {block.get('seed')}: no curve of predictor "
                       f"{predictor!r} (a block of draw_block, with its curves?)")
    missing = [k for k in CURVE_COLUMNS if k not in entry["curve"]]
    if missing:
        raise KeyError(f"draw_curve: predictor {predictor!r}: curve lacks {missing}")
    return pd.DataFrame({k: entry["curve"][k] for k in CURVE_COLUMNS})


def read_draw(path: Path, digest: str) -> dict:
    """A draw's block written by its stage (``path``: safety_tuning.json or
    safety_held_out.json), checked to be of the same chain settings as the reader's
    (``digest``, :func:`chain_digest` of its config). Raises FileNotFoundError, ValueError
    naming the file (not a draw block, or other chain settings: rerun its stage)."""
    path = Path(path)
    if not (isinstance(digest, str) and digest):
        raise ValueError(f"read_draw: digest: expected chain_digest's string, found {digest!r}")
    try:
        block = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: expected a draw block in JSON, found invalid JSON "
                         f"({exc})") from exc
    if not isinstance(block, dict) or "chain_digest" not in block:
        raise ValueError(f"{path}: expected a draw block (draw_block's, with a chain_digest), "
                         f"found keys {sorted(block)[:6] if isinstance(block, dict) else block!r}")
    if block["chain_digest"] != digest:
        raise ValueError(f"{path}: made with other chain settings (chain_digest "
                         f"{block['chain_digest']}, this config's {digest}): rerun its stage "
                         f"(dvc repro) or read it with the config it was made with")
    return block


def draw_summary(stage: str, block: dict) -> list[str]:
    """One printed line per predictor of a draw's block (:func:`draw_block`): its rates at the
    configured thresholds and its delays (s, "-" where none), prefixed with the ``stage``
    name."""
    def s(x):
        return "-" if x is None else f"{x:.2f}"
    return [f"{stage} {name}: avoided after visible {m['avoided_after_visible_rate']:.3f} at "
            f"{m['false_activation_rate']:.3f} false activations; first point -> confirmed "
            f"{s(m.get('first_point_to_confirmed_s_median'))} s, -> moving "
            f"{s(m['first_point_to_moving_s_median'])} s, -> AEB "
            f"{s(m['first_point_to_aeb_s_median'])} s"
            for name, m in block.items() if isinstance(m, dict)]
