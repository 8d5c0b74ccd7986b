"""The safety evaluation of a set of driving scenes, end to end (what the ``safety`` stage runs):
tracks -> each predictor's risk -> warnings and AEB requests -> braked outcomes -> metrics.

Inputs are tables (the truth of :func:`blindspot.radar.driving.scene_truth`, a tracker's output
in the ``blindspot.track`` schema) and objects (probabilistic predictors, the typed
:class:`~blindspot.safety.config.WarningConfig`); the outputs are tables and one JSON-ready
dictionary. See :mod:`blindspot.safety.evaluation` for the definitions.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from blindspot.safety.bound import (BOUNDS, best_request_frame, bound_results,
                                    first_confirmed, first_frame, lead_observed)
from blindspot.safety.braking import BrakingModel
from blindspot.safety.config import WarningConfig
from blindspot.safety.evaluation import (KMH, SceneInfo, aeb_gate_s,
                                         aeb_thresholds, avoided_at_false_activation,
                                         delay_stats,
                                         first_track_times, ncap_grid, operating_curve,
                                         replicate_half, scene_frame_risk, scene_info,
                                         scene_results, summarise)
from blindspot.safety.ncap import ncap_band, nominal_cell
from blindspot.safety.outcome import NEVER_S, braked_impacts, pedestrian_boxes, scene_arrays
from blindspot.safety.predict import risk_table
from blindspot.safety.risk import EgoShape

__all__ = ["SafetyResult", "outcome_table", "frame_risks", "assess", "perception_bounds",
           "logged_metrics", "summary_lines", "METRIC_BLOCKS"]


@dataclass(frozen=True)
class SafetyResult:
    """risk: per input, predictor, track row (input, predictor, group, frame, track_id,
    p_collision, ttc_s); scenes: per input, predictor, scene (:func:`scene_results` + input,
    predictor); curves: operating characteristic per input and predictor; grid: Euro NCAP grid
    per input and predictor; timeline: the braked ego of ``figure_scene`` per input and
    predictor (time_s, ego_y_m, ego_speed_mps); metrics: the JSON dictionary."""

    risk: pd.DataFrame
    scenes: pd.DataFrame
    curves: pd.DataFrame
    grid: pd.DataFrame
    timeline: pd.DataFrame
    metrics: dict
    ncap: dict | None = None


def outcome_table(truth: pd.DataFrame, bodies: dict, shape: EgoShape, braking: BrakingModel,
                  cfg: WarningConfig, *, with_flank: bool = False) -> tuple[Any, ...]:
    """(scene arrays, trigger times (S, F + 1) s, impact speeds (S, F + 1) km/h, NaN avoided)
    for an AEB request at each frame's decision time (column F: never). Collisions are front
    contacts (:func:`~blindspot.safety.outcome.braked_impacts`); a first contact on the car's
    flank is not one (NaN) and, with ``with_flank``, is flagged in a fourth array (S, F + 1)
    bool, counted apart."""
    sa = scene_arrays(truth, bodies)
    t, lo, hi = pedestrian_boxes(sa, cfg.outcome_dt_s, cfg.extend_s)
    S = len(sa.scenes)
    trig = np.concatenate([np.broadcast_to(sa.time_s + cfg.decision_delay_s, (S, len(sa.time_s))),
                           np.full((S, 1), NEVER_S)], axis=1)
    _, v, front = braked_impacts(sa, t, lo, hi, trig, braking, shape, with_front=True)
    flank = np.isfinite(v) & ~front
    impact = np.where(front, v, np.nan) * KMH
    return (sa, trig, impact, flank) if with_flank else (sa, trig, impact)


def frame_risks(risk: pd.DataFrame, scenes: np.ndarray, speed_mps: np.ndarray, n_frames: int,
                braking: BrakingModel, *, gate: str, margin_s: float, decision_delay_s: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """(p_warning, p_aeb), each (S, F): one predictor's scene-frame risk for the warning (every
    row) and for the AEB (rows whose TTC passed the gate, :func:`aeb_gate_s`; the same array
    with ``gate = "none"``). ``risk``: rows (group, frame, p_collision, ttc_s); scenes (S,)
    with their ego speeds ``speed_mps`` (S,) m/s (the scenes' ego holds its test speed until
    the request, [V] in ``EURO_NCAP_PEDESTRIAN.md``)."""
    p = scene_frame_risk(risk, scenes, n_frames)
    if gate == "none":
        return p, p
    gi = pd.Index(scenes).get_indexer(risk.group)
    speed = np.where(gi >= 0, np.asarray(speed_mps, float)[gi], 0.0)   # unknown scene: unused
    g = aeb_gate_s(speed, braking, gate=gate, margin_s=margin_s,
                   decision_delay_s=decision_delay_s)
    return p, scene_frame_risk(risk, scenes, n_frames, gate_s=g)


def _evaluated(truth: pd.DataFrame, scenes: np.ndarray, evaluated_set: str) -> np.ndarray:
    """(S,) bool: the scenes of ``scenes`` whose truth ``set`` is ``evaluated_set``."""
    return truth.groupby("scene").set.first().reindex(scenes).to_numpy() == evaluated_set


def _straight(truth: pd.DataFrame, evaluated_set: str) -> tuple[pd.DataFrame, set[str]]:
    """(truth without the scenes of a turning ego, their names). The outcome model drives the
    ego straight along +y: a turning scene (a named scene of the ego-motion sweep) is left out;
    an evaluated one (``set == evaluated_set``) raises ValueError."""
    turning = truth.ego_yaw_deg.abs().groupby(truth.scene).max() > 1e-9
    turning = set(turning.index[turning.to_numpy()])
    if turning:
        bad = sorted(set(truth.scene[truth.set == evaluated_set]) & turning)
        if bad:
            raise ValueError(f"truth: evaluated ({evaluated_set!r}) scenes with a turning ego "
                             f"{bad[:5]}: the outcome model needs the ego straight along +y")
        truth = truth[~truth.scene.isin(turning)]
    return truth, turning


def _lead_observed(truth: pd.DataFrame, sa, points: pd.DataFrame, lead: str,
                   points_name: str) -> np.ndarray:
    """(S, F) bool: the frames of the outcome table's scenes (``sa.scenes``, the truth's sorted
    frames) holding a radar point of ``lead`` (:func:`~blindspot.safety.bound.lead_observed`)."""
    return lead_observed(points, sa.scenes, np.sort(truth.frame.unique()), lead,
                         where=points_name)


def _first_time(observed: np.ndarray, time_s: np.ndarray) -> np.ndarray:
    """(S,) s: the start time of each scene's first True frame of ``observed`` (S, F); NaN
    where none."""
    f = first_frame(observed)
    return np.where(f < len(time_s), np.asarray(time_s, float)[np.minimum(f, len(time_s) - 1)],
                    np.nan)


def perception_bounds(truth: pd.DataFrame, scenes_meta: dict, points: pd.DataFrame,
                      cfg: WarningConfig, *, bodies: dict, shape: EgoShape,
                      confirm: tuple[int, int], evaluated_set: str = "monte_carlo",
                      lead: str = "p0", points_name: str = "points") -> dict:
    """The perception-limited bounds of :mod:`blindspot.safety.bound` on the evaluated scenes:
    name (:data:`~blindspot.safety.bound.BOUNDS`) -> :func:`summarise` of its scene results
    (``by_speed_kmh``, ``goals``, ...; ``lead_time_s_median`` is the true TTC at the request),
    plus ``settings``.

    truth, scenes_meta, bodies, shape: as :func:`assess`; points: the driving radar points with
    their truth label (columns scene, frame, source), named ``points_name`` in errors;
    confirm: (M, N) of the M-of-N confirmation. Each bound requests at
    :func:`~blindspot.safety.bound.best_request_frame` from its first frame of information.
    Raises ValueError (and its subclasses) as :func:`assess` and
    :func:`~blindspot.safety.bound.lead_observed`."""
    truth, turning = _straight(truth, evaluated_set)
    braking = BrakingModel.from_config(cfg.aeb)
    sa, _, impact = outcome_table(truth, bodies, shape, braking, cfg)
    observed = _lead_observed(truth, sa, points, lead, points_name)
    info = scene_info(truth, scenes_meta, sa.scenes, lead, _first_time(observed, sa.time_s))
    ev = _evaluated(truth, sa.scenes, evaluated_set)
    F = len(sa.time_s)
    visible = np.isfinite(info.first_visible_s)
    requests = {
        "line_of_sight": np.where(visible, np.searchsorted(
            sa.time_s, np.where(visible, info.first_visible_s, 0.0) - 1e-9), F),
        "radar_point": first_frame(observed),
        "confirmed_track": first_confirmed(observed, *confirm),
    }
    out: dict = {}
    for name in BOUNDS:                              # three bounds
        request = best_request_frame(impact, requests[name])
        res = bound_results(info, impact, sa.time_s, request, cfg.decision_delay_s)
        out[name] = summarise(res[ev].reset_index(drop=True), n_bootstrap=cfg.n_bootstrap,
                              seed=cfg.seed)
    out["settings"] = {
        "evaluated_set": evaluated_set, "n_scenes": int(ev.sum()), "lead": lead,
        "request": "best frame from the first frame of the information (best_request_frame)",
        "confirm_m": int(confirm[0]), "confirm_n": int(confirm[1]),
        "decision_delay_s": cfg.decision_delay_s,
        "aeb": {"latency_s": braking.latency_s, "jerk_mps3": braking.jerk_mps3,
                "decel_mps2": braking.decel_mps2},
        "left_out_turning_scenes": sorted(turning),
    }
    return out


def _timeline(sa, trigger_s: float, braking: BrakingModel, i: int, dt: float) -> pd.DataFrame:
    t = np.arange(sa.time_s[0], sa.time_s[-1] + dt / 2, dt)
    v0 = sa.speed_mps[i]
    s, v = braking.motion(v0, np.maximum(t - trigger_s, 0.0))
    braked = t > trigger_s
    y = sa.ego_y0_m[i] + v0 * np.minimum(t, trigger_s) + np.where(braked, s, 0.0)
    return pd.DataFrame({"time_s": t, "ego_y_m": y, "ego_speed_mps": np.where(braked, v, v0)})


def assess(truth: pd.DataFrame, scenes_meta: dict, tracks: dict[str, pd.DataFrame],
           predictors: dict[str, Any], cfg: WarningConfig, *, bodies: dict,
           shape: EgoShape, frame_period_s: float, figure_scene: str,
           evaluated_set: str = "monte_carlo", headline: str | None = None,
           only: dict[str, tuple[str, ...]] | None = None,
           points: pd.DataFrame | None = None, points_name: str = "points",
           draw_seed: int | None = None, ncap_inputs: tuple[str, ...] = ("tracker", "true_state")
           ) -> SafetyResult:
    """Run the evaluation (module docstring).

    truth: every scene's truth (column ``set`` selects the evaluated scenes; the figure scene
    may be outside it); scenes_meta: ``scenes.json``; tracks: input name (e.g. ``oracle``,
    ``tracker``) -> tracker output; predictors: name -> probabilistic predictor; bodies: body
    name -> (length_m, width_m, ref_from_front_m). ``headline``: the input whose numbers fill
    the top level of the metrics (default: the first of ``tracks``); every input's numbers are
    under ``metrics[predictor]["by_input"]``. ``only``: input -> the predictors run on it
    (default: all). ``points``: the radar points with their truth label (columns scene, frame,
    source), named ``points_name`` in errors, read only to know when a radar point first showed
    the lead pedestrian (:func:`~blindspot.safety.evaluation.scene_info`; without them, its line
    of sight).

    Track rows after the collision without braking of their scene are not scored (a request
    then comes too late to change the outcome, and the warning lead time counts warnings before
    it only).
    """
    headline = headline or next(iter(tracks))
    truth, turning = _straight(truth, evaluated_set)
    tracks = {k: v[~v.group.isin(turning)] for k, v in tracks.items()}
    horizon = int(round(cfg.horizon_s / frame_period_s))
    max_len = int(round(cfg.max_history_s / frame_period_s))
    ego = (truth.groupby(["scene", "frame"], as_index=False)
           [["ego_x_m", "ego_y_m", "ego_yaw_deg", "ego_speed_mps"]].first()
           .rename(columns={"scene": "group"}))
    main = BrakingModel.from_config(cfg.aeb)
    weak = BrakingModel.from_config(cfg.aeb, cfg.sensitivity_decel_mps2)
    sa, trig, impact, flank = outcome_table(truth, bodies, shape, main, cfg, with_flank=True)
    _, _, impact_weak = outcome_table(truth, bodies, shape, weak, cfg)
    first_point_s = (None if points is None else
                     _first_time(_lead_observed(truth, sa, points, "p0", points_name), sa.time_s))
    info_all = scene_info(truth, scenes_meta, sa.scenes, first_point_s=first_point_s)
    ev = _evaluated(truth, sa.scenes, evaluated_set)
    info = SceneInfo(*(np.asarray(getattr(info_all, f))[ev] for f in SceneInfo.__dataclass_fields__))
    thresholds = aeb_thresholds(cfg.n_thresholds, cfg.tail_thresholds)
    fig_i = int(np.flatnonzero(sa.scenes == figure_scene)[0]) if figure_scene in sa.scenes else None
    F = len(sa.time_s)
    risks, scenes, curves, grids, lines = [], [], [], [], []
    metrics: dict = {}
    kw = dict(warning_threshold=cfg.warning_threshold, aeb_threshold=cfg.aeb_threshold,
              decision_delay_s=cfg.decision_delay_s)
    t_col = truth.groupby("scene").collision_time_s.min()
    nominal = [(i, nominal_cell(s)) for i, s in enumerate(sa.scenes) if nominal_cell(s)]
    ncap: dict = {}
    tuning = np.zeros(int(ev.sum()), bool)
    if ev.any():
        tuning = replicate_half(sa.scenes[ev])
    held: dict = {"seed": draw_seed, "split": "odd replicates of each Monte-Carlo cell (even "
                  "ones tune); one draw", "n_intruding": int((info.intruding & ~tuning).sum()),
                  "n_non_intruding": int((~info.intruding & ~tuning).sum())}
    tune: dict = {"n_intruding": int((info.intruding & tuning).sum()),
                  "n_non_intruding": int((~info.intruding & tuning).sum())}
    for inp, tr in tracks.items():                   # the inputs (oracle, tracker): a few
        late = tr.time_s.to_numpy() > t_col.reindex(tr.group).to_numpy()     # NaN: never late
        tr = tr[~late]
        use = {k: v for k, v in predictors.items() if only is None or inp not in only
               or k in only[inp]}
        risk = risk_table(tr, ego, use, horizon=horizon, dt_s=frame_period_s,
                          shape=shape, margin_m=cfg.pedestrian_radius_m,
                          method=cfg.probability, max_len=max_len,
                          max_coast_s=cfg.max_coast_s)
        risks.append(risk.assign(input=inp))
        first = first_track_times(tr, truth, sa.scenes, steps=("confirmed", "moving"))
        t_confirmed, t_moving = first["confirmed"][ev], first["moving"][ev]
        fp = (info.first_seen_s if first_point_s is None
              else np.asarray(first_point_s, float)[ev])
        for name in use:                             # the four predictors
            # the gate is the nominal brakes' (also for the weak-brake sensitivity: the system
            # is tuned for its brakes, which then deliver less)
            p_all, p_aeb = frame_risks(risk[risk.predictor == name], sa.scenes, sa.speed_mps, F,
                                       main, gate=cfg.aeb_gate, margin_s=cfg.aeb_gate_margin_s,
                                       decision_delay_s=cfg.decision_delay_s)
            res_all = scene_results(p_all, info_all, impact, sa.time_s, p_aeb=p_aeb, **kw)
            res = res_all[ev].reset_index(drop=True)
            weak_res = scene_results(p_all[ev], info, impact_weak[ev], sa.time_s,
                                     p_aeb=p_aeb[ev], **kw)
            m = summarise(res, n_bootstrap=cfg.n_bootstrap, seed=cfg.seed)
            col = np.where(res_all.aeb_frame.to_numpy() >= 0, res_all.aeb_frame.to_numpy(), F)
            fl = flank[np.arange(len(col)), col][ev]
            m["flank_contacts"] = {"n": int(fl.sum()), "n_scenes": int(len(fl)),
                                   "note": "first contact on the car's flank behind the bumper "
                                           "(the pedestrian walks into the side): not a "
                                           "collision in the rates above, counted apart"}
            m["braking_sensitivity"] = {
                "decel_mps2": cfg.sensitivity_decel_mps2,
                **{k: summarise(weak_res, n_bootstrap=cfg.n_bootstrap, seed=cfg.seed)[k]
                   for k in ("avoided_rate", "goals")}}
            curve = operating_curve(p_aeb[ev], info, impact[ev], thresholds, sa.time_s)
            m["avoided_rate_at_false_activation_le"] = avoided_at_false_activation(curve)
            it = info.intruding                      # delays of the intruding scenes only
            to_confirmed, to_moving = t_confirmed - fp, t_moving - fp
            to_aeb = res.aeb_s.to_numpy(float) - fp
            m["first_point_to_confirmed_s"] = delay_stats(to_confirmed[it], info.speed_kmh[it])
            m["first_point_to_moving_s"] = delay_stats(to_moving[it], info.speed_kmh[it])
            m["first_point_to_aeb_s"] = delay_stats(to_aeb[it], info.speed_kmh[it])
            for block, half in ((held, ~tuning & it), (tune, tuning & it)):
                if inp != headline or not half.any():
                    continue
                whole = tuning if block is tune else ~tuning     # intruding and not
                hm = summarise(res[whole].reset_index(drop=True), n_bootstrap=cfg.n_bootstrap,
                               seed=cfg.seed)
                block[name] = {
                    "avoided_after_visible_rate": hm["avoided_after_visible_rate"],
                    "avoided_after_visible_rate_ci95": hm["avoided_after_visible_rate_ci95"],
                    "avoided_rate": hm["avoided_rate"],
                    "false_activation_rate": hm["false_activation_rate"],
                    "false_activation_rate_ci95": hm["false_activation_rate_ci95"],
                    "first_point_to_confirmed_s_median": delay_stats(
                        to_confirmed[half], info.speed_kmh[half])["median"],
                    "first_point_to_moving_s_median": delay_stats(
                        to_moving[half], info.speed_kmh[half])["median"],
                    "first_point_to_aeb_s_median": delay_stats(
                        to_aeb[half], info.speed_kmh[half])["median"]}
            if inp in ncap_inputs:
                for i, (proto, kmh, pct) in nominal:
                    imp = float(res_all.impact_speed_kmh.iloc[i])
                    band, _ = ncap_band(float(kmh), imp)
                    (ncap.setdefault(proto, {}).setdefault(inp, {}).setdefault(name, {})
                     .setdefault(kmh, {}))[pct] = {"impact_speed_kmh": imp, "band": str(band)}
            grid = ncap_grid(res)
            m["ncap_score_mean"] = float(grid.score.mean()) if len(grid) else None
            tag = dict(input=inp, predictor=name)
            scenes.append(res_all.assign(**tag, evaluated=ev))
            curves.append(curve.assign(**tag))
            grids.append(grid.assign(**tag))
            if fig_i is not None:
                lines.append(_timeline(sa, float(trig[fig_i, res_all.aeb_frame[fig_i]])
                                       if res_all.aeb_frame[fig_i] >= 0 else NEVER_S, main,
                                       fig_i, cfg.outcome_dt_s * 4).assign(**tag))
            entry = metrics.setdefault(name, {"by_input": {}})
            entry["by_input"][inp] = m
            if inp == headline or "input" not in entry:
                entry.update({k: v for k, v in m.items()})
                entry["input"] = inp
    no_aeb = impact[ev][:, -1]
    settings = {
        "evaluated_set": evaluated_set, "n_scenes": int(ev.sum()), "headline_input": headline,
        "inputs": list(tracks), "warning_threshold": cfg.warning_threshold,
        "aeb_threshold": cfg.aeb_threshold, "aeb_gate": cfg.aeb_gate,
        "aeb_gate_margin_s": cfg.aeb_gate_margin_s, "aeb": {"latency_s": main.latency_s,
                                                    "jerk_mps3": main.jerk_mps3,
                                                    "decel_mps2": main.decel_mps2},
        "horizon_s": cfg.horizon_s, "probability": cfg.probability,
        "left_out_turning_scenes": sorted(turning),
        "collision_rate_without_aeb": float(np.isfinite(no_aeb[info.intruding]).mean())
        if info.intruding.any() else None,
    }
    for name in predictors:
        metrics[name]["settings"] = settings
    metrics["held_out_half"] = held
    metrics["tuning_half"] = tune
    return SafetyResult(pd.concat(risks, ignore_index=True), pd.concat(scenes, ignore_index=True),
                        pd.concat(curves, ignore_index=True), pd.concat(grids, ignore_index=True),
                        pd.concat(lines, ignore_index=True) if lines else pd.DataFrame(),
                        metrics, ncap)


#: Keys of the safety metrics that are blocks of numbers, not predictors: the main draw's
#: halves (``tuning_half``, ``held_out_half``) and the independent tuning and held-out draws
#: (``tuning_draw``, ``held_out``; :mod:`blindspot.safety.draws`).
METRIC_BLOCKS = ("held_out", "held_out_half", "tuning_half", "tuning_draw")


def logged_metrics(metrics: dict) -> dict:
    """The numbers of :func:`assess`'s metrics that the safety stage logs (MLflow logs numbers
    only: None leaves dropped): per predictor its rates by input and by speed, and the
    held-out and tuning blocks."""
    out: dict = {}
    for name, m in metrics.items():
        if name in METRIC_BLOCKS:
            out[name] = m
            continue
        out[name] = {
            "by_input": {inp: {k: v[k] for k in ("avoided_rate", "avoided_after_visible_rate",
                                                 "false_activation_rate")}
                         for inp, v in m["by_input"].items()},
            **{k: m[k] for k in ("false_activation_rate", "avoided_rate",
                                 "avoided_after_visible_rate")},
            "by_speed_kmh": {k: {kk: v[kk] for kk in ("avoided_rate",
                                                      "avoided_after_visible_rate",
                                                      "impact_speed_kmh_mean",
                                                      "lead_time_s_median")}
                             for k, v in m["by_speed_kmh"].items()}}
    return _numeric(out)


def _numeric(d):
    if isinstance(d, dict):
        return {k: _numeric(v) for k, v in d.items()
                if v is not None and not isinstance(v, (str, list))}
    return d


def summary_lines(metrics: dict) -> list[str]:
    """One printed line per predictor (headline input) and one per held-out predictor."""
    lines = []
    for name, m in metrics.items():
        if name in METRIC_BLOCKS:
            continue
        lines.append(f"safety {name}: avoided {m['avoided_rate']} "
                     f"({m['avoided_after_visible_rate']} with the AEB requested after the "
                     f"lead pedestrian was visible), false activations "
                     f"{m['false_activation_rate']}; first point to moving median "
                     f"{m['first_point_to_moving_s']['median']} s; impact km/h by speed "
                     + ", ".join(f"{k}: {v['impact_speed_kmh_mean']:.1f}"
                                 for k, v in m["by_speed_kmh"].items()))
    for name, h in metrics.get("held_out", {}).items():
        if isinstance(h, dict):
            lines.append(f"safety held-out {name}: {h}")
    return lines
