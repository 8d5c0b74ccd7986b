"""Scene-level decisions and the safety metrics of a Monte-Carlo driving set.

Per scene, the risk of a frame is the largest P(collision) of its confirmed tracks (0 without
one). A warning is issued at the first frame whose risk reaches ``warning_threshold``, the AEB
request at the first reaching ``aeb_threshold``, each ``decision_delay_s`` after that frame's
start. The AEB risk may be gated by the time the brakes need (``warning.aeb_gate``,
:func:`aeb_gate_s`): a track row's P(collision) then counts for the AEB only when its predicted
TTC has fallen to the last point to brake plus a margin (Brännström, Coelingh & Sjöberg 2010);
the warning is not gated.

Once requested, braking is committed: the scene's outcome is the braked ego against the true
paths (:mod:`blindspot.safety.outcome`), looked up in an outcome table computed once per
braking model for a request at every frame (and for none), so sweeping the threshold (the
operating characteristic) is a lookup, vectorised over scenes and thresholds.

Scenes: *intruding* = the lead pedestrian (``p0``) crosses and would be hit without braking;
*non-intruding* = it does not (stops at the kerb, walks along it, turns back, crosses after the
car): any AEB request there is a false activation.

Metrics per ego speed (intruding scenes): the avoided rate (Wilson 95 % interval), the impact
speed (km/h, 0 when avoided; mean with a percentile-bootstrap 95 % interval), the warning lead
time (the true TTC when the warning is issued: collision time without braking minus the warning
time; median over warned scenes), the time from the pedestrian's first visibility (first frame
not occluded) to the warning; on non-intruding scenes the false-activation rate (Wilson).

The decisions are the scene's, not the lead pedestrian's: most intruding scenes hold one or
two other pedestrians too (78 of the 108 of the Monte-Carlo set; they stop at the kerb, walk
along it, turn back or cross after the car; ``scenes.json``), often in line of sight before the
lead steps out, and a track of one of them (or of clutter) can request the AEB before the lead
pedestrian is seen at all. Such a scene then ends avoided by braking for someone or something
else, the same braking that counts as a false activation in a non-intruding scene. So each
intruding scene also says whether its AEB request (and its warning) came from a frame before
anything showed the lead pedestrian, line of sight or a radar point of it (``aeb_before_visible``, ``warned_before_visible``), and the metrics give
the share of such requests and the avoided rate without them (``avoided_after_visible_rate``:
avoided, the AEB requested from a frame at or after the first that showed the lead). It is a
count of this run, not a bound: a later request may still have come from someone else's track,
and an early-braked scene might have been avoided by a later response to the lead too. The
perfect deciders of :mod:`blindspot.safety.bound` respond to the lead pedestrian alone, so it is
this rate, rather than ``avoided_rate``, that compares with them. The flags are written for the
non-intruding scenes too, where they mean nothing (every request there is a false activation).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import stats

from blindspot.arrays import check_array, check_count, check_number
from blindspot.safety.ncap import ncap_band
from blindspot.tables import check_columns
from blindspot.track.moving import confirmed_moving

__all__ = ["SceneInfo", "line_of_sight_onset", "TRACK_STEPS", "first_track_s",
           "first_track_times", "delay_stats",
           "scene_info", "replicate_half", "aeb_gate_s", "scene_frame_risk",
           "trigger_frames", "scene_results",
           "summarise", "aeb_thresholds", "operating_curve", "avoided_at_false_activation", "ncap_grid", "wilson",
           "KMH"]

KMH = 3.6


@dataclass(frozen=True)
class SceneInfo:
    """Per scene (S,): names, ego speed (km/h), intruding flag, nominal impact point (%),
    collision time without braking (s, NaN none), first time the lead pedestrian is visible
    (in line of sight; s, NaN never) and first time anything showed it (line of sight or a
    radar point of it, whichever came first; the line of sight where no points were given).
    A radar point can come first: the body's near edge clears the car a frame or two before
    its centre (40 of the 108 intruding Monte-Carlo scenes)."""

    scenes: np.ndarray
    speed_kmh: np.ndarray
    intruding: np.ndarray
    impact_pct: np.ndarray
    collision_s: np.ndarray
    first_visible_s: np.ndarray
    first_seen_s: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.first_seen_s is None:
            object.__setattr__(self, "first_seen_s", np.asarray(self.first_visible_s, float))


def line_of_sight_onset(p0: pd.DataFrame) -> pd.Series:
    """Per scene (index), the time (s) of the first frame of the visible stretch that leads to
    the crossing: the first frame not ``occluded`` after the last occluded frame at or before
    the collision time without braking (``collision_time_s``; NaN: the scene's end). A child
    glimpsed standing far ahead and then hidden again is seen from its last emergence, not
    from the glimpse (issue 40). NaN where the pedestrian is occluded up to then. ``p0``: one
    pedestrian's truth rows (columns scene, time_s, occluded, collision_time_s)."""
    t_end = p0.collision_time_s.astype(float).fillna(np.inf)
    before = p0[p0.time_s.to_numpy(float) <= t_end.to_numpy() + 1e-9]
    occ = before[before.occluded.astype(bool)]
    last_occ = occ.groupby("scene").time_s.max()
    lo = last_occ.reindex(before.scene).to_numpy(float)
    clear = before[~before.occluded.astype(bool).to_numpy()
                   & ~(before.time_s.to_numpy(float) <= np.nan_to_num(lo, nan=-np.inf))]
    return clear.groupby("scene").time_s.min().reindex(pd.Index(p0.scene.unique()))


#: The steps :func:`first_track_s` times: the first track row near the lead pedestrian
#: (``born``), the first confirmed one, the first one classed a moving object.
TRACK_STEPS = ("born", "confirmed", "moving")


def first_track_s(tracks: pd.DataFrame, truth: pd.DataFrame, scenes: np.ndarray, *,
                  step: str = "moving", lead: str = "p0", radius_m: float = 1.0) -> np.ndarray:
    """(S,) s per scene of ``scenes``: the time of the first track row of ``step``
    (:data:`TRACK_STEPS`: any row; a confirmed row; a row classed a moving object, confirmed
    and, with a ``moving`` column, moving; the decision's coasting limit does not apply: a
    first moving row is a measured one) lying within ``radius_m`` of the lead pedestrian's
    true position at that frame (truth scores, it never feeds the chain); NaN where none. The
    row may be any track's, not only the one that follows the pedestrian longest. Several
    steps at once: :func:`first_track_times`.

    tracks: columns group, frame, time_s, x_m, y_m (and confirmed, unless ``step`` is
    ``born``; moving counts where present); truth: columns scene, frame, pedestrian, x_m, y_m;
    scenes (S,): scene names; lead: the pedestrian's name in ``truth``.

    Raises:
        ValueError: an unknown ``step``, a ``radius_m`` that is not a number > 0, a ``lead``
            that is not a non-empty string, ``scenes`` that are not a 1-D array of names, or a
            table without its columns (naming them).
    """
    if not isinstance(step, str) or step not in TRACK_STEPS:
        raise ValueError(f"first_track_s: step: expected one of {TRACK_STEPS}, found {step!r}")
    return _first_track_times(tracks, truth, scenes, (step,), lead, radius_m,
                              "first_track_s")[step]


def first_track_times(tracks: pd.DataFrame, truth: pd.DataFrame, scenes: np.ndarray, *,
                      steps: tuple[str, ...] = TRACK_STEPS, lead: str = "p0",
                      radius_m: float = 1.0) -> dict[str, np.ndarray]:
    """``{step: (S,) s}``: :func:`first_track_s` for each of ``steps`` (distinct names of
    :data:`TRACK_STEPS`), the track rows matched to the lead pedestrian once for all of them.

    Raises:
        ValueError: ``steps`` not a non-empty tuple of distinct names of :data:`TRACK_STEPS`,
            a ``radius_m`` that is not a number > 0, a ``lead`` that is not a non-empty string,
            ``scenes`` that are not a 1-D array of names, or a table without its columns
            (naming them: ``confirmed`` unless ``steps`` is ``("born",)``).
    """
    if not isinstance(steps, tuple) or not steps or len(set(steps)) != len(steps) \
            or not all(isinstance(x, str) and x in TRACK_STEPS for x in steps):
        raise ValueError(f"first_track_times: steps: expected a non-empty tuple of distinct "
                         f"names of {TRACK_STEPS}, found {steps!r}")
    return _first_track_times(tracks, truth, scenes, steps, lead, radius_m, "first_track_times")


def _first_track_times(tracks: pd.DataFrame, truth: pd.DataFrame, scenes: np.ndarray,
                       steps: tuple[str, ...], lead: str, radius_m: float, who: str
                       ) -> dict[str, np.ndarray]:
    """:func:`first_track_times` with ``steps`` checked; errors name the public ``who``."""
    check_number(radius_m, "radius_m", gt=0.0, unit="m", who=who)
    if not (isinstance(lead, str) and lead):
        raise ValueError(f"{who}: lead: expected a pedestrian's name (a non-empty string), "
                         f"found {lead!r}")
    names = np.asarray(scenes)
    if names.ndim != 1:
        raise ValueError(f"{who}: scenes: expected a 1-D array of scene names, found "
                         f"{type(scenes).__name__} of shape {names.shape}")
    bad = [x for x in names.tolist() if not isinstance(x, str)]
    if bad:
        raise ValueError(f"{who}: scenes: expected scene names (strings), found "
                         f"{bad[0]!r} ({type(bad[0]).__name__})")
    need = {"group", "frame", "time_s", "x_m", "y_m"} | (
        {"confirmed"} if set(steps) != {"born"} else set())
    check_columns(tracks, need, "tracks", who=who, note="the blindspot.track schema")
    check_columns(truth, {"scene", "frame", "pedestrian", "x_m", "y_m"}, "truth", who=who)
    keep = {"born": lambda: np.ones(len(tracks), bool),
            "confirmed": lambda: tracks.confirmed.to_numpy(bool),
            "moving": lambda: confirmed_moving(tracks)}
    t = tracks[["group", "frame", "time_s", "x_m", "y_m"]].assign(
        **{f"_{x}": keep[x]() for x in steps})
    p = truth.loc[truth.pedestrian == lead, ["scene", "frame", "x_m", "y_m"]].rename(
        columns={"scene": "group", "x_m": "px", "y_m": "py"})
    j = t.merge(p, on=["group", "frame"])
    j = j[np.hypot(j.x_m - j.px, j.y_m - j.py) <= radius_m]
    return {x: j[j[f"_{x}"]].groupby("group").time_s.min().reindex(pd.Index(names))
            .to_numpy(float) for x in steps}


def delay_stats(delay_s: np.ndarray, speed_kmh: np.ndarray) -> dict:
    """Median and p90 (s) of the finite ``delay_s`` (S,) overall and per speed (km/h keys as
    strings of integers), with their counts and the count of scenes without one."""
    d = np.asarray(delay_s, float)
    v = np.asarray(speed_kmh, float)

    def one(x):
        x = x[np.isfinite(x)]
        return {"median": float(np.median(x)) if len(x) else None,
                "p90": float(np.percentile(x, 90)) if len(x) else None, "n": int(len(x))}
    out = {**one(d), "n_never": int((~np.isfinite(d)).sum())}
    out["by_speed_kmh"] = {f"{s:.0f}": {**one(d[v == s]), "n_never": int(
        (~np.isfinite(d[v == s])).sum())} for s in np.unique(v)}
    return out


def scene_info(truth: pd.DataFrame, scenes_meta: dict, scenes: np.ndarray,
               lead: str = "p0", first_point_s: np.ndarray | None = None) -> SceneInfo:
    """From the truth table and ``scenes.json`` (name -> {"pedestrians": [{"name",
    "impact_pct", ...}]}), in the order of ``scenes``; ``first_point_s`` (S,) s, the time of
    the lead pedestrian's first radar point per scene (NaN none; from
    :func:`blindspot.safety.bound.lead_observed`), counts for ``first_seen_s``. Raises KeyError
    naming a missing scene, ValueError for a ``first_point_s`` of another shape."""
    p0 = truth[truth.pedestrian == lead]
    g = p0.groupby("scene")
    first = g.first().reindex(scenes)
    if first.frame.isna().any():
        raise KeyError(f"truth: scenes without pedestrian {lead!r}: "
                       f"{list(first.index[first.frame.isna()])[:5]}")
    vis = line_of_sight_onset(p0).reindex(scenes)
    pct = []
    for s in scenes:
        if s not in scenes_meta:
            raise KeyError(f"scenes.json: no scene {s!r}")
        peds = {p["name"]: p for p in scenes_meta[s]["pedestrians"]}
        pct.append(float(peds[lead]["impact_pct"]))
    seen = vis.to_numpy(float)
    if first_point_s is not None:
        first_point_s = np.asarray(first_point_s, float)
        if first_point_s.shape != seen.shape:
            raise ValueError(f"scene_info: first_point_s must be one time per scene, shape "
                             f"{seen.shape}; found {first_point_s.shape}")
        seen = np.fmin(seen, first_point_s)
    return SceneInfo(np.asarray(scenes), (first.ego_speed_mps * KMH).round(6).to_numpy(),
                     ((first.behaviour == "cross") & first.collision.astype(bool)).to_numpy(),
                     np.array(pct), first.collision_time_s.to_numpy(float), vis.to_numpy(float),
                     seen)


def replicate_half(scenes: np.ndarray) -> np.ndarray:
    """(S,) bool: True for the tuning half of Monte-Carlo scenes, False for the held-out half.

    Names ``mc_<speed>kmh_<p>pct_<int|non>_<k>`` (:func:`blindspot.radar.driving
    .draw_scenarios`): replicate k of a cell has its own seed, drawn from the set's generator;
    even k tune, odd k are held out, so each speed x impact point x intruding cell is split in
    half. Raises ValueError naming a scene without a replicate suffix."""
    names = pd.Series(np.asarray(scenes, str))
    k = names.str.extract(r"^mc_.+_(?:int|non)_(\d+)$")[0]
    if k.isna().any():
        raise ValueError(f"replicate_half: scene {names[k.isna()].iloc[0]!r} is not a "
                         "Monte-Carlo scene named mc_<speed>kmh_<p>pct_<int|non>_<k>")
    return (k.astype(int) % 2 == 0).to_numpy()


def aeb_gate_s(speed_mps: np.ndarray, braking, *, gate: str, margin_s: float,
               decision_delay_s: float) -> np.ndarray:
    """The AEB gate (...) s: the largest predicted TTC (at the frame's start, ego at constant
    speed; :mod:`blindspot.safety.risk`) at which a track row may request AEB, for ego speeds
    ``speed_mps`` (...) m/s.

    ``gate = "none"``: +inf (every row counts). ``"stopping_time"``: the last point to brake,
    ``braking.stop_ttc(v)`` (:class:`~blindspot.safety.braking.BrakingModel`: the TTC of a
    stationary obstacle at which a request still stops the car at it; Brännström, Coelingh &
    Sjöberg 2010, IEEE T-ITS 11(3); ISO 22839:2013), plus ``decision_delay_s`` (the request
    leaves that long after the frame whose TTC it reads) plus ``margin_s`` (chosen on held-out
    scenes, ``conf/warning/default.yaml``). A standing ego (v <= 0) takes the limit of the
    last point to brake as v -> 0, the braking latency (a pedestrian walking into a standing
    car: only rows about to touch it may request, as for a creeping ego). Raises ValueError
    for an unknown gate, a non-finite speed, a ``decision_delay_s`` not finite and >= 0 or a
    non-finite ``margin_s``."""
    v = check_array(speed_mps, "speed_mps", ("...",), who="aeb_gate_s")
    check_number(decision_delay_s, "decision_delay_s", ge=0.0, unit="s", who="aeb_gate_s")
    check_number(margin_s, "margin_s", unit="s", who="aeb_gate_s")
    if gate == "none":
        return np.full(v.shape, np.inf)
    if gate != "stopping_time":
        raise ValueError(f"config key 'warning.aeb_gate': expected 'none' or 'stopping_time', "
                         f"found {gate!r}")
    moving = v > 0
    stop = np.where(moving, braking.stop_ttc(np.where(moving, v, 1.0)), braking.latency_s)
    return stop + decision_delay_s + margin_s


def scene_frame_risk(risk: pd.DataFrame, scenes: np.ndarray, n_frames: int,
                     gate_s: np.ndarray | None = None) -> np.ndarray:
    """(S, F) the largest p_collision of each scene's confirmed tracks per frame (0: none).
    ``risk``: one predictor's rows (group, frame, p_collision, and ttc_s with a gate).

    ``gate_s`` (R,) s per row of ``risk`` (:func:`aeb_gate_s`): a row counts only when its
    predicted TTC is at most its gate; a row without a predicted TTC (NaN: the mean path never
    enters the footprint within the horizon) then never counts, unless its gate is +inf."""
    out = np.zeros((len(scenes), n_frames))
    if len(risk):
        s = pd.Index(scenes).get_indexer(risk.group)
        ok = (s >= 0) & (risk.frame.to_numpy() < n_frames)
        if gate_s is not None:
            gate_s = np.asarray(gate_s, float)
            if gate_s.shape != (len(risk),):
                raise ValueError(f"scene_frame_risk: gate_s must be ({len(risk)},), found "
                                 f"{gate_s.shape}")
            ttc = risk.ttc_s.to_numpy(float)
            ok &= np.isposinf(gate_s) | (ttc <= gate_s)
        np.maximum.at(out, (s[ok], risk.frame.to_numpy()[ok]), risk.p_collision.to_numpy()[ok])
    return out


def trigger_frames(p: np.ndarray, thresholds: np.ndarray) -> np.ndarray:
    """(S, N) first frame whose risk reaches each threshold (F = never), p (S, F)."""
    cm = np.maximum.accumulate(p, axis=1)                                 # (S, F)
    reach = cm[:, None, :] >= np.asarray(thresholds)[None, :, None]       # (S, N, F)
    return np.where(reach.any(-1), np.argmax(reach, -1), p.shape[1])


def wilson(k: int, n: int) -> list[float] | None:
    """Wilson 95 % interval of k successes in n (scipy's binomtest); None for n = 0."""
    if n == 0:
        return None
    ci = stats.binomtest(int(k), int(n)).proportion_ci(0.95, method="wilson")
    return [float(ci.low), float(ci.high)]


def _boot_mean(x: np.ndarray, n: int, rng: np.random.Generator) -> list[float] | None:
    """Percentile-bootstrap 95 % interval of the mean (vectorised resampling)."""
    if len(x) == 0:
        return None
    means = x[rng.integers(0, len(x), (n, len(x)))].mean(axis=1)
    return [float(np.percentile(means, 2.5)), float(np.percentile(means, 97.5))]


def scene_results(p: np.ndarray, info: SceneInfo, impact_kmh: np.ndarray,
                  frame_times: np.ndarray, *, warning_threshold: float, aeb_threshold: float,
                  decision_delay_s: float, p_aeb: np.ndarray | None = None) -> pd.DataFrame:
    """One row per scene: warn_frame / aeb_frame (-1 none), warning_s, aeb_s (NaN none),
    impact_speed_kmh (0 avoided), avoided, lead_time_s (true TTC at the warning; NaN without a
    warning before the collision), aeb_lead_time_s, visible_to_warning_s (negative: warned
    before the lead pedestrian was in line of sight), warned_before_visible /
    aeb_before_visible (the warning / the AEB request made from a frame that starts before
    anything showed the lead pedestrian, ``info.first_seen_s``, or in a scene where nothing
    ever does; False without a request).

    p (S, F) scene-frame risk (the warning's, and the AEB's unless ``p_aeb`` (S, F), the gated
    AEB risk, is given); impact_kmh (S, F + 1) the outcome table (column F = no AEB; NaN =
    avoided); frame_times (F,) s."""
    F = p.shape[1]
    warn = trigger_frames(p, np.array([warning_threshold]))[:, 0]
    aeb = trigger_frames(p if p_aeb is None else p_aeb, np.array([aeb_threshold]))[:, 0]
    t_dec = np.r_[frame_times + decision_delay_s, np.nan]
    warn_s, aeb_s = t_dec[warn], t_dec[aeb]
    imp = impact_kmh[np.arange(len(aeb)), aeb]
    with np.errstate(invalid="ignore"):
        lead = np.where(warn_s < info.collision_s, info.collision_s - warn_s, np.nan)
        aeb_lead = np.where(aeb_s < info.collision_s, info.collision_s - aeb_s, np.nan)
    # the frame each decision was made from starts decision_delay_s before the decision
    seen = _seen_before(info)
    with np.errstate(invalid="ignore"):
        warned_early = np.isfinite(warn_s) & (warn_s - decision_delay_s < seen)
        aeb_early = np.isfinite(aeb_s) & (aeb_s - decision_delay_s < seen)
    return pd.DataFrame({
        "scene": info.scenes, "speed_kmh": info.speed_kmh, "impact_pct": info.impact_pct,
        "intruding": info.intruding, "warn_frame": np.where(warn < F, warn, -1),
        "aeb_frame": np.where(aeb < F, aeb, -1), "warning_s": warn_s, "aeb_s": aeb_s,
        "impact_speed_kmh": np.nan_to_num(imp, nan=0.0), "avoided": np.isnan(imp),
        "lead_time_s": lead, "aeb_lead_time_s": aeb_lead,
        "visible_to_warning_s": warn_s - info.first_visible_s,
        "warned_before_visible": warned_early, "aeb_before_visible": aeb_early,
    })


def _median(x) -> float | None:
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return float(np.median(x)) if len(x) else None


def _before_visible(it: pd.DataFrame) -> dict:
    """Of intruding scenes (:func:`scene_results` rows): the shares warned and AEB-requested
    from a frame before anything showed the lead pedestrian, and the avoided rate without the
    latter (with its Wilson 95 % interval); None for no scene."""
    if not len(it):
        return {"warned_before_visible_rate": None, "aeb_before_visible_rate": None,
                "avoided_after_visible_rate": None, "avoided_after_visible_rate_ci95": None}
    early, warned = it.aeb_before_visible.astype(bool), it.warned_before_visible.astype(bool)
    later = it.avoided.astype(bool) & ~early
    return {"warned_before_visible_rate": float(warned.mean()),
            "aeb_before_visible_rate": float(early.mean()),
            "avoided_after_visible_rate": float(later.mean()),
            "avoided_after_visible_rate_ci95": wilson(int(later.sum()), len(it))}


def summarise(res: pd.DataFrame, *, n_bootstrap: int, seed: int) -> dict:
    """The metrics of one predictor's :func:`scene_results` (module docstring): ``by_speed_kmh``
    {speed: {...}}, ``false_activation_rate`` (+ interval), ``false_warning_rate`` and the
    issue's goals."""
    rng = np.random.default_rng(seed)
    by = {}
    for v, g in res.groupby("speed_kmh"):                 # six speeds: one entry each
        it, non = g[g.intruding], g[~g.intruding]
        imp = it.impact_speed_kmh.to_numpy()
        n_fa = int((non.aeb_frame >= 0).sum())
        by[f"{v:g}"] = {
            "n_intruding": int(len(it)), "n_non_intruding": int(len(non)),
            "avoided_rate": float(it.avoided.mean()) if len(it) else None,
            "avoided_rate_ci95": wilson(int(it.avoided.sum()), len(it)),
            "impact_speed_kmh_mean": float(imp.mean()) if len(it) else None,
            "impact_speed_kmh_ci95": _boot_mean(imp, n_bootstrap, rng),
            "impact_speed_kmh_no_aeb": float(v),
            "impact_speed_reduction_kmh": float(v - imp.mean()) if len(it) else None,
            "warned_rate": float(it.lead_time_s.notna().mean()) if len(it) else None,
            "lead_time_s_median": _median(it.lead_time_s),
            "aeb_lead_time_s_median": _median(it.aeb_lead_time_s),
            "visible_to_warning_s_median": _median(it.visible_to_warning_s),
            **_before_visible(it),
            "false_activation_rate": n_fa / len(non) if len(non) else None,
        }
    it, non = res[res.intruding], res[~res.intruding]
    n_fa, n_fw = int((non.aeb_frame >= 0).sum()), int((non.warn_frame >= 0).sum())
    low = it[it.speed_kmh <= 40]
    high = [by[k]["impact_speed_reduction_kmh"] for k in by if float(k) >= 50
            and by[k]["impact_speed_reduction_kmh"] is not None]
    far = n_fa / len(non) if len(non) else None
    return {
        "by_speed_kmh": by,
        "n_intruding": int(len(it)), "n_non_intruding": int(len(non)),
        "avoided_rate": float(it.avoided.mean()) if len(it) else None,
        "avoided_rate_ci95": wilson(int(it.avoided.sum()), len(it)),
        **_before_visible(it),
        "false_activation_rate": far,
        "false_activation_rate_ci95": wilson(n_fa, len(non)),
        "false_warning_rate": n_fw / len(non) if len(non) else None,
        "lead_time_s_median": _median(it.lead_time_s),
        "goals": {
            "no_collision_up_to_40kmh": bool(len(low) and low.avoided.all()),
            "avoided_rate_up_to_40kmh": float(low.avoided.mean()) if len(low) else None,
            "impact_speed_reduction_50_60_kmh_min": min(high) if high else None,
            "impact_speed_reduction_ge_20kmh_at_50_60": bool(high and min(high) >= 20.0),
            "false_activation_le_1pct": bool(far is not None and far <= 0.01),
        },
    }


def aeb_thresholds(n: int, tail=()) -> np.ndarray:
    """The AEB thresholds of the operating characteristic, ascending: ``n`` evenly spaced in
    (0, 1) (``k / (n + 1)``) and the ``tail`` ones (a threshold within 1e-9 of one already there
    is not added again). The calibrated probabilities of collision saturate near 1 on the
    tracker's rows, so thresholds such as 0.999 or 0.9999 still separate scenes that 0.99 does
    not. Raises ValueError for ``n`` below 1 or a tail threshold outside (0, 1)."""
    check_count(n, "n", ge=1, who="aeb_thresholds")
    t = np.atleast_1d(np.asarray(tail, float)).ravel()
    if not np.all((t > 0) & (t < 1)):
        raise ValueError(f"aeb_thresholds: tail: expected thresholds in (0, 1), found "
                         f"{t.tolist()!r}")
    out = list(np.linspace(0, 1, n + 2)[1:-1])
    for x in np.sort(t):
        if not np.any(np.abs(np.asarray(out) - x) <= 1e-9):
            out.append(float(x))
    return np.sort(np.asarray(out))


def _seen_before(info: SceneInfo) -> np.ndarray:
    """(S,) the time (s) a decision's frame must start before to come before anything showed
    the lead pedestrian (``info.first_seen_s`` less 1e-9 for rounding; inf where nothing ever
    did: every request there is early)."""
    return np.where(np.isnan(info.first_seen_s), np.inf, info.first_seen_s) - 1e-9


def operating_curve(p: np.ndarray, info: SceneInfo, impact_kmh: np.ndarray,
                    thresholds: np.ndarray, frame_times: np.ndarray) -> pd.DataFrame:
    """AEB threshold swept: per threshold the avoided rate, the avoided-after-visible rate (the
    request made from a frame at or after the first that showed the lead pedestrian, as
    :func:`scene_results` counts it) and the mean impact speed (intruding scenes), and the
    false-activation rate (non-intruding). p (S, F) the AEB risk, impact_kmh (S, F + 1) the
    outcome table, thresholds (N,), frame_times (F,) s. Vectorised over scenes and
    thresholds."""
    n_frames = p.shape[1]
    check_array(frame_times, "frame_times", (n_frames,), who="operating_curve")
    trig = trigger_frames(p, thresholds)                                   # (S, N)
    imp = np.take_along_axis(impact_kmh, trig, axis=1)                     # (S, N)
    seen = _seen_before(info)
    start = np.r_[np.asarray(frame_times, float), np.inf][trig]           # (S, N), inf: never
    early = np.isfinite(start) & (start < seen[:, None])
    it, non = info.intruding, ~info.intruding
    return pd.DataFrame({
        "threshold": thresholds,
        "avoided_rate": np.isnan(imp[it]).mean(0) if it.any() else np.nan,
        "avoided_after_visible_rate": (np.isnan(imp[it]) & ~early[it]).mean(0)
        if it.any() else np.nan,
        "impact_speed_kmh_mean": np.nan_to_num(imp[it], nan=0.0).mean(0) if it.any() else np.nan,
        "false_activation_rate": (trig[non] < n_frames).mean(0) if non.any() else np.nan,
    })


def avoided_at_false_activation(curve: pd.DataFrame, levels=(0.01, 0.05, 0.1)) -> dict:
    """Points of an operating characteristic (``curve``: :func:`operating_curve`'s columns
    ``avoided_rate`` and ``false_activation_rate``, one row per threshold): per false-activation
    level, the largest avoided rate of a threshold whose false-activation rate is at most it,
    keyed by the level (``"0.01"``: issue 12's goal, one scene in 108); None where no threshold
    gets there. Raises KeyError naming a missing column."""
    fa = curve.false_activation_rate.to_numpy(float)
    av = curve.avoided_rate.to_numpy(float)
    out = {}
    for f in levels:
        ok = fa <= f + 1e-12
        out[f"{f:g}"] = float(av[ok].max()) if ok.any() else None
    return out


def ncap_grid(res: pd.DataFrame) -> pd.DataFrame:
    """Euro NCAP-shaped grid of the intruding scenes: per (speed, impact point) the scenes,
    those avoided, those whose AEB request came before the lead pedestrian was visible
    (``n_aeb_before_visible``: braking for another pedestrian or clutter), the mean impact
    speed, its colour band and the mean cell score of the scenes
    (:func:`blindspot.safety.ncap.ncap_band`)."""
    it = res[res.intruding].copy()
    names, score = ncap_band(it.speed_kmh.to_numpy(), it.impact_speed_kmh.to_numpy())
    it["score"] = score
    g = it.groupby(["speed_kmh", "impact_pct"])
    out = g.agg(n=("scene", "size"), n_avoided=("avoided", "sum"),
                n_aeb_before_visible=("aeb_before_visible", "sum"),
                impact_speed_kmh_mean=("impact_speed_kmh", "mean"),
                score=("score", "mean")).reset_index()
    out["band"] = ncap_band(out.speed_kmh.to_numpy(), out.impact_speed_kmh_mean.to_numpy())[0]
    return out
