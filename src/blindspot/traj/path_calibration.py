"""The calibration stage's steps on the simulated paths: the validation and held-out pairs,
every scene predictor calibrated on the first (:mod:`blindspot.traj.calibration`) and scored on
the second, beside the online ellipses each predictor chose among the config's candidates on
validation streams (:func:`online_scores`), and the ETH/UCY folds' scores merged in.

The online ellipses' choice is made as the ETH/UCY stage makes it per fold
(:func:`blindspot.traj.conformal.select_on_held_out_streams`): each validation stream is met as
a new scene whose prior is the other streams' scores. Here a stream is a run of consecutive
validation paths (:func:`path_streams`), met one path after another as the held-out paths are
(:func:`pair_times`)."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from blindspot.arrays import check_array
from blindspot.traj.calibration import (CalibrationError, calibrate, calibration_scores,
                                        forecast_scores, path_pairs)
from blindspot.traj.conformal import check_candidates, held_out_choice_coverage
from blindspot.traj.distribution import mahalanobis_sq

__all__ = ["ETHUCY_FILE", "ETHUCY_NAMES", "held_out_pairs", "pair_times", "path_streams",
           "online_scores", "calibrate_on_paths", "merge_ethucy_folds", "coverage_line"]

# The ETH/UCY folds' calibration (same shape, written by the ethucy work): merged into
# calibration.json when the calibration stage declares it as a dep.
ETHUCY_FILE = "calibration_ethucy.json"
# Its model names that are the scene predictors' under another name (ethucy's "cvm").
ETHUCY_NAMES = {"cvm": "constant_velocity"}


def held_out_pairs(measured: np.ndarray, truth: np.ndarray, ids: dict, window: int,
                   horizon: int, stride: int) -> dict:
    """{"val": ..., "test": ...}: :func:`path_pairs` (history, future, path, start; ``path`` the
    row of ``measured[ids[split]]``, an index within the split) of the validation paths and of
    the held-out ones (``ids``: path ids by split)."""
    return {split: path_pairs(measured[ids[split]], truth[ids[split]], window, horizon, stride,
                              with_index=True) for split in ("val", "test")}


def calibrate_on_paths(predictors: dict, pairs: dict, candidates, *, scale_method: str,
                       scale_level: float, cv_fit_points: int, n_test_paths: int,
                       val_streams: int):
    """(calibrated predictors, validation scores, metrics, online settings): each predictor
    calibrated on the validation pairs (:func:`calibrate`), its scores there (where the online
    ellipses start, here and in the walks), its coverage / NLL on the held-out pairs beside
    the online coverage of the setting it chose among ``candidates`` on ``val_streams``
    validation streams (:func:`online_scores`): ``{name: {"sim_paths": {...}}}``, and each
    predictor's chosen setting ``{name: setting}`` (the walks' online ellipses)."""
    who = "calibrate_on_paths"
    if not isinstance(pairs, dict) or not {"val", "test"} <= set(pairs):
        found = sorted(pairs) if isinstance(pairs, dict) else type(pairs).__name__
        raise CalibrationError(f"{who}: pairs: expected held_out_pairs' keys 'val' and 'test', "
                               f"found {found}")
    val, test = (_indexed_pairs(pairs[k], f"pairs[{k!r}]", who) for k in ("val", "test"))
    check_candidates(candidates, who, CalibrationError)
    path_streams(val[2], val_streams)   # a bad stream count is named before minutes of work
    calibrated = calibrate(predictors, *val[:2], scale_method=scale_method,
                           scale_level=scale_level, cv_fit_points=cv_fit_points)
    prior = {n: forecast_scores(p, *val[:2]) for n, p in calibrated.items()}
    metrics, settings = {}, {}
    for name, p in calibrated.items():
        fc = p.predict_distribution(test[0], test[1].shape[1])    # one forecast, two scores
        online, chosen = online_scores(candidates, val, prior[name], test,
                                       mahalanobis_sq(fc, test[1]), val_streams)
        metrics[name] = {"sim_paths": {**calibration_scores(p, *test[:2], forecast=fc),
                                       **online, "n_paths": int(n_test_paths)}}
        settings[name] = chosen.setting
    return calibrated, prior, metrics, settings


def pair_times(history: np.ndarray, future: np.ndarray, path: np.ndarray, start: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """``(t_predicted (N,), t_revealed (N, H))`` of :func:`path_pairs` met as one stream (their
    ``path`` and ``start`` from ``with_index``), the paths one after another as one radar meets
    walkers (path k's outcomes known before path k + 1 starts; a single walk of a few seconds
    is too short to learn from its own outcomes): within a path a pair is predicted at its last
    history frame and each future point known at its own frame."""
    h, f, path, start = _indexed_pairs((history, future, path, start), "pairs", "pair_times")
    span = int(start.max(initial=0)) + h.shape[1] + f.shape[1] + 1   # a path's frames, and more
    t_pred = path * span + start + h.shape[1] - 1
    return t_pred, t_pred[:, None] + 1 + np.arange(f.shape[1])


def path_streams(path: np.ndarray, n_streams: int) -> np.ndarray:
    """(N,) stream of each pair: the distinct ``path`` ids (N,) in order, cut into
    ``n_streams`` runs of consecutive paths as equal as they come.

    Raises:
        CalibrationError: fewer distinct paths than streams, or ``n_streams`` < 2.
    """
    path = check_array(path, "path", ("N",), error=CalibrationError, who="path_streams", dtype=int)
    ids = np.unique(path)
    if isinstance(n_streams, bool) or not isinstance(n_streams, (int, np.integer)) \
            or not 2 <= n_streams <= ids.size:
        raise CalibrationError(f"path_streams: n_streams (calibration.online_val_streams): "
                               f"expected an integer in [2, {ids.size}] (the distinct paths; "
                               f"at least 2 are needed), found {n_streams!r}")
    runs = np.array_split(ids, n_streams)
    return np.searchsorted(np.array([r[0] for r in runs]), path, side="right") - 1


def online_scores(candidates: Sequence, val: tuple[np.ndarray, ...], val_scores: np.ndarray,
                  test: tuple[np.ndarray, ...], test_scores: np.ndarray, n_streams: int
                  ) -> tuple[dict[str, Any], Any]:
    """``({"online_coverage_50", ...}, the online ellipses chosen)`` of one calibrated
    predictor: the setting chosen among ``candidates``
    (:class:`~blindspot.traj.conformal.OnlineEllipses`) on the validation pairs alone
    (:func:`~blindspot.traj.conformal.held_out_choice_coverage`: the validation paths cut
    into ``n_streams`` runs (:func:`path_streams`), each met as a new stream with the other
    runs' scores as its prior; with one candidate, that one), then its coverage on the test
    pairs met as one stream (:func:`pair_times`) with every validation score as the prior.
    The predictor was calibrated on all the validation paths, the held-out run's included, so
    the validation distances are somewhat optimistic for every predictor (as constant
    velocity's are on the ETH/UCY folds).

    ``val`` / ``test`` are (history, future, path, start) of :func:`path_pairs` with
    ``with_index``; ``val_scores`` / ``test_scores`` (N, H) the predictor's
    :func:`forecast_scores` on them. Beside the coverage: ``online_coverage_<p>_ci95`` (a
    bootstrap over the test paths), the chosen ``setting`` and, when there was a choice, its
    mean distance from nominal on the validation streams (``online_val_distance``)."""
    who = "online_scores"
    val, test = _indexed_pairs(val, "val", who), _indexed_pairs(test, "test", who)
    check_candidates(candidates, who, CalibrationError)
    for name, scores, pairs in (("val_scores", val_scores, val), ("test_scores", test_scores,
                                                                   test)):
        check_array(scores, name, (len(pairs[0]), pairs[1].shape[1]), error=CalibrationError,
                    who=who, allow_nan=True)
    return held_out_choice_coverage(
        candidates, (val_scores, *pair_times(*val), path_streams(val[2], n_streams)),
        (test_scores, *pair_times(*test), np.zeros(len(test_scores), np.int64)),
        clusters=np.asarray(test[2]))


def merge_ethucy_folds(metrics: dict, paths) -> dict:
    """``metrics`` with the ETH/UCY folds of every path ending in :data:`ETHUCY_FILE` merged in
    (same shape; names mapped by :data:`ETHUCY_NAMES`)."""
    for path in paths:
        if str(path).endswith(ETHUCY_FILE):
            for name, folds in json.loads(Path(path).read_text()).items():
                metrics.setdefault(ETHUCY_NAMES.get(name, name), {}).update(folds)
    return metrics


def coverage_line(name: str, m: dict) -> str | None:
    """One log line of a predictor's ``sim_paths`` scores (None without them)."""
    s = m.get("sim_paths")
    if not s:
        return None
    return (f"calibration {name}: coverage 50/90/95 {s['coverage_50']:.3f} / "
            f"{s['coverage_90']:.3f} / {s['coverage_95']:.3f}, NLL {s['nll']:.3f} "
            f"({s['n_points']} points of {s['n_paths']} held-out paths); online "
            f"{s['online_coverage_50']:.3f} / {s['online_coverage_90']:.3f} / "
            f"{s['online_coverage_95']:.3f}")


def _indexed_pairs(pairs, name: str, who: str) -> tuple[np.ndarray, ...]:
    """(history (N, W, 2), future (N, H, 2), path (N,) int, start (N,) int): :func:`path_pairs`
    with ``with_index``, checked."""
    if not isinstance(pairs, (tuple, list)) or len(pairs) != 4:
        found = (f"{len(pairs)} items" if isinstance(pairs, (tuple, list))
                 else type(pairs).__name__)
        raise CalibrationError(f"{who}: {name}: expected (history, future, path, start) of "
                               f"path_pairs(..., with_index=True), found {found}")
    h = check_array(pairs[0], f"{name} history", ("N", "W", 2), error=CalibrationError, who=who)
    f = check_array(pairs[1], f"{name} future", (h.shape[0], "H", 2), error=CalibrationError,
                    who=who, allow_nan=True)
    path, start = (check_array(a, f"{name} {what}", (h.shape[0],), error=CalibrationError,
                               who=who, dtype=int) for a, what in ((pairs[2], "path"),
                                                                    (pairs[3], "start")))
    for a, what in ((path, "path"), (start, "start")):
        if a.size and a.min() < 0:
            raise CalibrationError(f"{who}: {name} {what}: expected indices >= 0, found "
                                   f"{int(a.min())}")
    return h, f, path, start

