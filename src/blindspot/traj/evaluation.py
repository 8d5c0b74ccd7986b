"""Scoring filled and predicted paths: the paper's metric and the time-aligned errors beside it.

Interpolation (paper Fig. 8): :func:`score_interpolation` scores a filled track on the frames it
filled while the pedestrian was hidden; :func:`mean_over_scenes` adds the mean over scenes.

Prediction (paper Figs. 9 and 10):

For each scene and method the prediction ``pred`` (H, 2) covers the frames after the prediction
start. It is scored against
* the simulated truth of those frames, time-aligned (ADE/FDE at fixed horizons, error per step);
* the paper's metric (each predicted point's distance to the nearest point of the actual path),
  once against the truth path and once against the radar track of the same walk recorded without
  the car, which is what the paper could measure.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from blindspot.arrays import check_array
from blindspot.traj.metrics import displacement, path_error

PER_STEP_ARRAYS = ("per_step_m", "path_error_m", "path_error_radar_m")


class EvaluationError(ValueError):
    """An array or setting handed to a scoring function is malformed, or there is nothing to
    score (names the argument, what was expected and what was found)."""


def _check_dt(dt_s, horizons_s, who: str) -> tuple[float, tuple[float, ...]]:
    dt = check_array(dt_s, "dt_s", (), error=EvaluationError, who=who)
    hs = check_array(horizons_s, "horizons_s", ("K",), error=EvaluationError, who=who)
    if not dt > 0 or (hs <= 0).any():
        raise EvaluationError(f"{who}: expected dt_s > 0 and horizons_s > 0 (s), found "
                              f"{dt_s!r}, {list(horizons_s)!r}")
    return float(dt), tuple(float(h) for h in hs)


def errors_at_horizons(err_per_step: np.ndarray, dt_s: float,
                       horizons_s: tuple[float, ...]) -> dict[str, float]:
    """ADE and FDE up to each horizon: ``ade_<h>s`` = mean error over steps 1..n, ``fde_<h>s`` the
    error at step n, n = round(h / dt). Horizons longer than the prediction give NaN.

    err_per_step : (H,) errors in m (NaN allowed); dt_s : frame period in s; horizons_s in s.
    Raises EvaluationError for a malformed array, or dt_s / a horizon not > 0.
    """
    err_per_step = check_array(err_per_step, "err_per_step", ("H",), error=EvaluationError,
                               who="errors_at_horizons", allow_nan=True)
    dt_s, horizons_s = _check_dt(dt_s, horizons_s, "errors_at_horizons")
    out: dict[str, float] = {}
    for h in horizons_s:
        n = int(round(h / dt_s))
        key = f"{h:g}s"
        if 1 <= n <= len(err_per_step):
            out[f"ade_{key}"] = float(np.nanmean(err_per_step[:n]))
            out[f"fde_{key}"] = float(err_per_step[n - 1])
        else:
            out[f"ade_{key}"] = out[f"fde_{key}"] = float("nan")
    return out


def score_prediction(pred: np.ndarray, truth: np.ndarray, radar_track: np.ndarray | None,
                     dt_s: float, horizons_s: tuple[float, ...] = (0.5, 1.0, 2.0)) -> dict:
    """All errors of one predicted path.

    pred : (H, 2) predicted positions; truth : (H, 2) true positions at the same frames;
    radar_track : (M, 2) the radar's points of the same walk without the car (NaN rows allowed),
    or None. Returns a flat dict of floats plus ``per_step_m`` (H,) and ``path_error_m`` (H,).
    Raises EvaluationError: an array not real of its shape (H >= 1), pred and truth of
    different lengths, inf values (NaN rows allowed), or dt_s / a horizon not > 0.
    """
    who = "score_prediction"
    pred = check_array(pred, "pred", ("H", 2), error=EvaluationError, who=who, allow_nan=True)
    truth = check_array(truth, "truth", (len(pred), 2), error=EvaluationError, who=who,
                        allow_nan=True)
    if radar_track is not None:
        radar_track = check_array(radar_track, "radar_track", ("M", 2), error=EvaluationError,
                                  who=who, allow_nan=True)
    if len(pred) == 0:
        raise EvaluationError(f"{who}: pred: expected at least one predicted point, found none")
    _check_dt(dt_s, horizons_s, who)
    per_step = displacement(pred, truth)
    to_truth = path_error(pred, truth)
    out = {
        "path_error_mean_m": float(np.nanmean(to_truth)),
        "path_error_first_m": float(to_truth[0]),
        "ade_m": float(np.nanmean(per_step)),
        "fde_m": float(per_step[-1]),
        "horizon_steps": int(len(pred)),
        **errors_at_horizons(per_step, dt_s, horizons_s),
        "per_step_m": per_step,
        "path_error_m": to_truth,
    }
    if radar_track is not None:
        to_radar = path_error(pred, radar_track)
        out["path_error_radar_mean_m"] = float(np.nanmean(to_radar))
        out["path_error_radar_m"] = to_radar
    return out


# ---------------------------------------------------------------------------------------------
# interpolation


def gap_mask(observed: np.ndarray) -> np.ndarray:
    """(T,) bool: the frames inside the track's interior gaps (what interpolation fills).

    observed : (T,) bool, True where the track has a point. Frames missing before the first or
    after the last point are not a gap (nothing on both sides); the same frames as
    :func:`blindspot.traj.interpolation.find_gaps`, as a mask. Raises EvaluationError when
    ``observed`` is not a 1-D boolean array.
    """
    obs = check_array(observed, "observed", ("T",), error=EvaluationError, who="gap_mask",
                      dtype=bool)
    if not obs.any():
        return np.zeros(obs.shape, bool)
    seen = np.cumsum(obs)                       # observed frames up to and including each frame
    return ~obs & (seen > 0) & (seen < seen[-1])   # a point before and a point after


def score_interpolation(filled: np.ndarray, truth: np.ndarray, observed: np.ndarray,
                        hidden: np.ndarray) -> dict[str, float | int]:
    """Errors of one filled track against the truth.

    filled, truth : (T, 2) x, y in m per frame; observed : (T,) bool, frames with a radar point;
    hidden : (T,) bool, frames where the pedestrian was hidden behind the car.
    Returns ``hidden_mean_m``, ``hidden_median_m``, ``hidden_max_m`` (over the filled frames
    that were hidden), ``all_gaps_mean_m`` (over every filled frame), ``n_hidden_filled``,
    ``n_filled``. Raises :class:`EvaluationError` when no hidden frame was filled (nothing to
    score), or an array is not real / boolean of its shape (T, 2) / (T,) or holds inf.
    """
    who = "score_interpolation"
    filled = check_array(filled, "filled", ("T", 2), error=EvaluationError, who=who,
                         allow_nan=True)          # NaN before the first / after the last point
    T = len(filled)
    truth = check_array(truth, "truth", (T, 2), error=EvaluationError, who=who, allow_nan=True)
    observed = check_array(observed, "observed", (T,), error=EvaluationError, who=who, dtype=bool)
    hidden = check_array(hidden, "hidden", (T,), error=EvaluationError, who=who, dtype=bool)
    gap = gap_mask(observed)
    hidden_gap = gap & hidden
    if not hidden_gap.any():
        raise EvaluationError("score_interpolation: no hidden frame lies in a gap of the track "
                         f"({int(gap.sum())} filled frames, {int(np.sum(hidden))} hidden)")
    err = np.hypot(*(filled - truth).T)
    return {
        "hidden_mean_m": float(err[hidden_gap].mean()),
        "hidden_median_m": float(np.median(err[hidden_gap])),
        "hidden_max_m": float(err[hidden_gap].max()),
        "all_gaps_mean_m": float(err[gap].mean()),
        "n_hidden_filled": int(hidden_gap.sum()),
        "n_filled": int(gap.sum()),
    }


def mean_over_scenes(per_method: Mapping[str, Mapping[str, Mapping[str, float]]],
                     key: str = "hidden_mean_m") -> dict[str, dict]:
    """``{method: {scene: scores}}`` with ``{"all_scenes": {key: mean over the scenes}}`` added
    to each method (a new dict; the input is not changed)."""
    out = {}
    for method, per in per_method.items():
        out[method] = {**per, "all_scenes": {key: float(np.mean([m[key] for m in per.values()]))}}
    return out


# ---------------------------------------------------------------------------------------------
# prediction, over scenes and methods


def evaluate_predictions(predictions: pd.DataFrame, truth: pd.DataFrame,
                         radar_tracks: Mapping[str, np.ndarray | None], dt_s: float,
                         horizons_s: tuple[float, ...]) -> tuple[dict, pd.DataFrame]:
    """Score every (scene, method) prediction and average over scenes per method.

    predictions : rows ``scene``, ``method``, ``step`` (1..H), ``frame``, ``x_m``, ``y_m``.
    truth : rows ``scene``, ``frame``, ``x_m``, ``y_m`` covering the predicted frames.
    radar_tracks : scene -> (M, 2) the radar's points of the same walk without the car from the
        prediction start on; a scene missing or None has no radar-track metric (give tracks for
        all scenes or for none: the mean over scenes needs the same metrics in each).
    Returns ``metrics`` = ``{method: {metric: mean over scenes, ..., "per_scene": {scene:
    {metric: value}}}}`` (metrics of :func:`score_prediction` without its arrays) and the
    per-step table (method, scene, step, time_s, error_m, path_error_m, path_error_radar_m;
    NaN where there is no radar track), in the order of ``predictions``.
    """
    per_scene: dict[str, dict[str, dict]] = {}
    curves = []
    for (scene, method), pred in predictions.groupby(["scene", "method"], sort=False):
        pred = pred.sort_values("step")
        frames = pred.frame.to_numpy()
        tr = truth[truth.scene == scene].set_index("frame").loc[frames]
        s = score_prediction(pred[["x_m", "y_m"]].to_numpy(), tr[["x_m", "y_m"]].to_numpy(),
                             radar_tracks.get(scene), dt_s, horizons_s)
        per_scene.setdefault(method, {})[scene] = {k: v for k, v in s.items()
                                                   if k not in PER_STEP_ARRAYS}
        curves.append(pd.DataFrame({
            "method": method, "scene": scene, "step": pred.step.to_numpy(),
            "time_s": pred.step.to_numpy() * dt_s, "error_m": s["per_step_m"],
            "path_error_m": s["path_error_m"],
            "path_error_radar_m": s.get("path_error_radar_m", np.full(len(pred), np.nan)),
        }))
    metrics: dict[str, dict] = {}
    for method, scenes in per_scene.items():
        keys = next(iter(scenes.values())).keys()
        metrics[method] = {k: float(np.mean([m[k] for m in scenes.values()])) for k in keys}
        metrics[method]["per_scene"] = scenes
    return metrics, pd.concat(curves, ignore_index=True)


def mean_error_by_step(curve: pd.DataFrame, dt_s: float) -> pd.DataFrame:
    """Per method and step, the mean over scenes of ``error_m`` and ``path_error_m`` of the
    per-step table of :func:`evaluate_predictions`, with ``time_s`` = step * dt_s."""
    mean = (curve.groupby(["method", "step"], sort=False)[["error_m", "path_error_m"]]
            .mean().reset_index())
    mean["time_s"] = mean.step * dt_s
    return mean
