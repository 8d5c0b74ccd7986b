"""One independent Monte-Carlo draw (the tuning or the held-out draw of issue 40;
:mod:`blindspot.safety.draws`) through the whole chain in memory, with the settings of the
composed config: scene truth (:func:`blindspot.safety.draws.draw_truth`), the radar measurement
with the draw's own receiver noise (:func:`blindspot.synth.driving_measurement.measure_driving`,
:func:`blindspot.safety.draws.draw_noise`), the tracker with its moving test
(:func:`blindspot.synth.driving_tracks.driving_tracks`) and the decision's assessment
(:func:`blindspot.safety.assess.assess`, tracker input only), and on request the perception
bounds of the draw (:func:`blindspot.safety.assess.perception_bounds`, the safety_bound stage's
on the main draw). The driving stages' own functions: the draws differ from the main draw by
their scenes and noise only.
"""

from __future__ import annotations

from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig, EgoMotionConfig
from blindspot.radar.config import RadarConfig, SimConfig
from blindspot.radar.scenario import load_scenarios
from blindspot.safety.assess import SafetyResult, assess, perception_bounds
from blindspot.safety.config import WarningConfig
from blindspot.safety.draws import (chain_digest, draw_block, draw_noise, draw_truth,
                                    independent_scenes)
from blindspot.safety.outcome import body_boxes
from blindspot.safety.risk import EgoShape
from blindspot.synth.driving_measurement import measure_driving
from blindspot.synth.driving_tracks import driving_tracks
from blindspot.track.config import TrackerConfig

__all__ = ["assess_draw", "draw_stage_block"]


def assess_draw(cfg, predictors: dict, *, seed: int, per_cell: int, jobs: int = 1,
                progress: bool = False, where: str = "draw", with_bounds: bool = False
                ) -> tuple[SafetyResult, dict | None]:
    """The draw of ``seed`` with ``per_cell`` scenes per cell of the main draw's grid, assessed
    with ``predictors`` (name -> calibrated predictor,
    :func:`blindspot.safety.predict.stage_predictors`) on the tracker's tracks.

    ``cfg`` is the composed config (groups scenario, driving_radar, sim, driving_cfar, doa,
    detect, ego_motion, tracker, warning); ``where`` names the draw in the tracker's errors.
    Returns :func:`~blindspot.safety.assess.assess`'s result: its ``metrics`` (the halves of
    the draw under ``held_out`` / ``tuning`` mean nothing here: the whole draw is the set) and
    ``curves`` (the operating characteristic per predictor) are what the draw stages keep
    (:func:`~blindspot.safety.draws.draw_block`); and with ``with_bounds`` the draw's
    :func:`~blindspot.safety.assess.perception_bounds` (its settings with the draw's ``seed``),
    else None. Raises ValueError for an empty ``where`` or a ``with_bounds`` that is not a
    bool, and the errors of :func:`~blindspot.safety.draws.independent_scenes` for a bad seed
    or size."""
    if not (isinstance(where, str) and where):
        raise ValueError(f"assess_draw: where: expected the draw's name (a non-empty string), "
                         f"found {where!r}")
    if not isinstance(with_bounds, bool):
        raise ValueError(f"assess_draw: with_bounds: expected True or False, found "
                         f"{with_bounds!r}")
    group, named = load_scenarios(cfg.scenario)
    radar, w = RadarConfig.from_cfg(cfg, "driving_radar"), WarningConfig.from_cfg(cfg)
    tracker = TrackerConfig.from_cfg(cfg)
    dt = float(radar.frame_period_s)
    scenes = independent_scenes(group, named, seed, per_cell)
    truth, meta = draw_truth(scenes, group, dt)
    points = measure_driving(scenes, group, radar, CfarConfig.from_cfg(cfg, "driving_cfar"),
                             DoaConfig.from_cfg(cfg), DetectConfig.from_cfg(cfg),
                             draw_noise(EgoMotionConfig.from_cfg(cfg), seed),
                             adc_headroom_db=SimConfig.from_cfg(cfg).adc_headroom_db,
                             jobs=jobs, progress=progress).points
    tables, _ = driving_tracks(truth, points, tracker, w.oracle, seed=w.seed,
                               frame_period_s=dt, jobs=jobs, where=f"{where} points")
    labelled = points[["scene", "frame", "source"]]
    bodies, shape = body_boxes(group), EgoShape(group.ego.width_m, group.ego.length_m)
    res = assess(truth, meta, {"tracker": tables["tracks"]}, predictors, w, bodies=bodies,
                 shape=shape, points=labelled, frame_period_s=dt, figure_scene=scenes[0].name,
                 draw_seed=seed, ncap_inputs=())
    if not with_bounds:
        return res, None
    bounds = perception_bounds(truth, meta, labelled, w, bodies=bodies, shape=shape,
                               confirm=(tracker.confirm_m, tracker.confirm_n),
                               points_name=f"{where} points")
    bounds["settings"]["seed"] = int(seed)
    return res, bounds


def draw_stage_block(cfg, predictors: dict, *, seed: int, per_cell: int, jobs: int = 1,
                     progress: bool = False, where: str = "draw", with_bounds: bool = False
                     ) -> tuple[dict, dict | None]:
    """What a draw stage writes: the block (safety_tuning.json, safety_held_out.json;
    :func:`blindspot.safety.draws.draw_block`: rates, operating characteristics and the digest
    of ``cfg``'s chain settings) of :func:`assess_draw` with these arguments, and the draw's
    perception bounds (safety_held_out_bound.json) with ``with_bounds``, else None."""
    res, bounds = assess_draw(cfg, predictors, seed=seed, per_cell=per_cell, jobs=jobs,
                              progress=progress, where=where, with_bounds=with_bounds)
    return draw_block(res.metrics, seed, res.curves, chain_digest(cfg)), bounds
