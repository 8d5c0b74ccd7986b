"""Perception-limited bounds of the AEB outcome: what any decision logic could reach on the
driving scenes, given when the information about the pedestrian first exists.

A bound decides perfectly: on an intruding scene it warns and requests AEB once its information
about the lead pedestrian exists (from the first frame that has it, at the best such frame; see
below); on a non-intruding scene it never does (it knows intent, so its false-activation rate is
0 by construction). The request leaves ``decision_delay_s`` after that frame's start, and the
braked outcome is looked up in the same outcome table as the predictors'
(:func:`blindspot.safety.assess.outcome_table`: the committed AEB of ``warning.aeb``, the true
paths), so a bound's row compares one to one with a predictor's row of ``safety.json``.

Information sources, earliest first (:data:`BOUNDS`):

- ``line_of_sight``: the first frame the lead pedestrian is not occluded (truth column
  ``occluded``), what a sensor that recognises a pedestrian the moment any of them is in line of
  sight would have;
- ``radar_point``: the first frame with a radar point of the lead pedestrian (the points' truth
  label ``source``), a decision on a single point;
- ``confirmed_track``: the first frame at which those points would confirm an M-of-N track
  (``confirm_m`` frames with a point among the last ``confirm_n``; ``tracker.confirm_m`` /
  ``tracker.confirm_n``, the classic 3-of-5 of Blackman & Popoli 1999, sec. 6.3), before any
  test of whether the track moves.

For the crossing lead pedestrian alone, braking earlier never hurts (the ego only slows: if a
later request stops short of its path, an earlier one does too). For the scene it can: an early
request may stop the ego in the path of a pedestrian who crosses later and walks into the
standing car, a contact at 0 km/h that :mod:`blindspot.safety.outcome` counts as not avoided. So
each bound requests at the best frame from its first frame on (:func:`best_request_frame`: the
first frame that avoids the collision, else the one of the lowest impact speed), and is an upper
bound of every decision logic that has only that information. A gap between a bound and a
predictor's row is the cost of the decision logic (motion classification, prediction,
thresholds, the AEB gate); a goal that a bound misses cannot be met by any decision logic on this
sensor and with this braking model.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from blindspot.safety.evaluation import SceneInfo, scene_results
from blindspot.tables import check_columns

__all__ = ["BOUNDS", "BoundError", "lead_observed", "first_frame", "first_confirmed",
           "best_request_frame", "bound_results", "logged_bounds", "bound_summary"]

BOUNDS = ("line_of_sight", "radar_point", "confirmed_track")


class BoundError(ValueError):
    """Malformed points or arguments of a bound; the message names them."""


def lead_observed(points: pd.DataFrame, scenes: np.ndarray, frames: np.ndarray,
                  lead: str = "p0", where: str = "points") -> np.ndarray:
    """(S, F) bool: True where frame ``frames[f]`` of scene ``scenes[s]`` holds at least one
    radar point whose truth label ``source`` is ``lead``.

    points: columns scene, frame, source (one row per radar point); points of other scenes or
    frames are ignored. Raises BoundError naming ``where`` for missing columns."""
    check_columns(points, {"scene", "frame", "source"}, where, error=BoundError,
                  note="expected scene, frame, source: the radar points' truth label")
    own = points[points.source.to_numpy() == lead]
    si = pd.Index(scenes).get_indexer(own.scene)
    fi = pd.Index(frames).get_indexer(own.frame)
    ok = (si >= 0) & (fi >= 0)
    seen = np.zeros((len(scenes), len(frames)), bool)
    seen[si[ok], fi[ok]] = True
    return seen


def first_frame(mask: np.ndarray) -> np.ndarray:
    """(S,) index of the first True frame of each row of ``mask`` (S, F); F where none."""
    mask = np.asarray(mask, bool)
    return np.where(mask.any(axis=1), mask.argmax(axis=1), mask.shape[1])


def first_confirmed(observed: np.ndarray, m: int, n: int) -> np.ndarray:
    """(S,) first frame at which ``m`` of the last ``n`` frames (that frame included) hold an
    observation, from ``observed`` (S, F) bool; F where never. Raises BoundError unless
    1 <= m <= n."""
    if not (isinstance(m, (int, np.integer)) and isinstance(n, (int, np.integer))
            and 1 <= m <= n):
        raise BoundError(f"first_confirmed: expected integers 1 <= confirm_m <= confirm_n, "
                         f"found m={m!r}, n={n!r}")
    c = np.concatenate([np.zeros((observed.shape[0], 1), np.int64),
                        np.cumsum(observed, axis=1)], axis=1)           # (S, F + 1)
    F = observed.shape[1]
    k = np.arange(F)
    in_window = c[:, k + 1] - c[:, np.maximum(k + 1 - n, 0)]          # (S, F)
    return first_frame(in_window >= m)


def best_request_frame(impact_kmh: np.ndarray, first: np.ndarray) -> np.ndarray:
    """(S,) the best AEB request frame at or after ``first`` (S,) (F = never): the first frame
    whose request avoids the collision, else the first of the lowest impact speed; F where
    ``first`` is F. impact_kmh (S, F + 1): the outcome table (NaN = avoided; column F: no
    request). Raises BoundError for shapes that disagree."""
    impact_kmh = np.asarray(impact_kmh, float)
    first = np.asarray(first)
    if impact_kmh.ndim != 2 or first.shape != (impact_kmh.shape[0],):
        raise BoundError(f"best_request_frame: expected an outcome table (S, F + 1) and first "
                         f"frames (S,); found {impact_kmh.shape}, {first.shape}")
    F = impact_kmh.shape[1] - 1
    cost = np.where(np.isnan(impact_kmh[:, :F]), -1.0, impact_kmh[:, :F])   # avoided: best
    cost = np.where(np.arange(F)[None, :] >= first[:, None], cost, np.inf)
    return np.where(first < F, np.argmin(cost, axis=1), F)


def bound_results(info: SceneInfo, impact_kmh: np.ndarray, frame_times: np.ndarray,
                  request_frame: np.ndarray, decision_delay_s: float) -> pd.DataFrame:
    """:func:`blindspot.safety.evaluation.scene_results` of a bound: warning and AEB request
    at ``request_frame`` (S,) (F = never) on the intruding scenes of ``info``, never on the
    others. impact_kmh (S, F + 1) the outcome table (column F: no AEB); frame_times (F,) s.
    Raises BoundError for shapes that disagree."""
    impact_kmh = np.asarray(impact_kmh, float)
    S, F = len(info.scenes), len(frame_times)
    request_frame = np.asarray(request_frame)
    if impact_kmh.shape != (S, F + 1) or request_frame.shape != (S,):
        raise BoundError(f"bound_results: expected an outcome table (S={S}, F + 1={F + 1}) "
                         f"and request frames ({S},); found {impact_kmh.shape}, "
                         f"{request_frame.shape}")
    p = ((np.arange(F)[None, :] >= request_frame[:, None])
         & np.asarray(info.intruding, bool)[:, None]).astype(float)
    return scene_results(p, info, impact_kmh, np.asarray(frame_times, float),
                         warning_threshold=0.5, aeb_threshold=0.5,
                         decision_delay_s=decision_delay_s)


def logged_bounds(bounds: dict) -> dict:
    """What a stage logs of :func:`blindspot.safety.assess.perception_bounds`' output
    (``bounds``): per bound its avoided rate and, per speed, its avoided rate, mean impact speed
    and median lead time (those that exist). Raises BoundError for ``bounds`` that is not a
    dict or a bound without its avoided rate and per-speed table."""
    if not isinstance(bounds, dict):
        raise BoundError(f"logged_bounds: bounds: expected perception_bounds' output (a dict), "
                         f"found {type(bounds).__name__}")
    out = {}
    for name, m in bounds.items():
        if name == "settings":
            continue
        if not (isinstance(m, dict) and "avoided_rate" in m
                and isinstance(m.get("by_speed_kmh"), dict)):
            raise BoundError(f"logged_bounds: bound {name!r}: expected perception_bounds' "
                             f"summary (avoided_rate, by_speed_kmh), found {m!r:.80}")
        out[name] = {"avoided_rate": m["avoided_rate"],
                     "by_speed_kmh": {k: {kk: v[kk] for kk in ("avoided_rate",
                                                               "impact_speed_kmh_mean",
                                                               "lead_time_s_median")
                                          if v.get(kk) is not None}
                                      for k, v in m["by_speed_kmh"].items()}}
    return out


def bound_summary(stage: str, bounds: dict) -> list[str]:
    """One printed line per bound of :func:`blindspot.safety.assess.perception_bounds`'
    output, prefixed with the ``stage`` name: its avoided rate, and per speed its avoided rate
    and mean impact speed (km/h; "-" where none). Raises BoundError for an empty ``stage`` and
    the errors of :func:`logged_bounds` for a bound without its rates."""
    if not (isinstance(stage, str) and stage):
        raise BoundError(f"bound_summary: stage: expected the stage's name (a non-empty string), "
                         f"found {stage!r}")

    def num(x, fmt):
        return "-" if x is None else format(x, fmt)
    return [f"{stage} {name}: avoided {num(m['avoided_rate'], '.3f')}; by speed "
            + ", ".join(f"{k}: {num(v.get('avoided_rate'), '.2f')} avoided, "
                        f"{num(v.get('impact_speed_kmh_mean'), '.1f')} km/h"
                        for k, v in m["by_speed_kmh"].items())
            for name, m in logged_bounds(bounds).items()]
