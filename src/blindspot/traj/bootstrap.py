"""Per-walk scores of many walks, their means with bootstrap intervals, paired differences.

A benchmark scores every method on the same N walks, so each metric is a (N,) vector per
method. :func:`bootstrap_means` gives each vector's mean with a percentile bootstrap interval
(Efron & Tibshirani 1993, ch. 13: resample the walks with replacement, take the mean, report the
(1 - level)/2 and (1 + level)/2 quantiles of the resampled means), with ONE set of resampled walk
indices shared by every method and metric: a difference between two methods is then resampled
walk by walk (:func:`paired_differences`, the bootstrap of per-walk differences), which is
narrower than comparing two independent intervals whenever the methods' errors on a walk are
correlated (they are: a hard walk is hard for every predictor).

Vectorised over resamples: the (n_boot, N) index matrix is drawn once; a mean over walks is one
matrix product with the (N,) values. A NaN value (a walk a metric does not apply to, e.g. no
hidden frame inside a gap) is left out of that metric's means.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from blindspot.arrays import check_array
from blindspot.traj.metrics import displacement, path_error

__all__ = ["BenchmarkError", "prediction_scores", "hidden_gap_error", "resample_weights",
           "bootstrap_means", "paired_differences"]


class BenchmarkError(ValueError):
    """A per-walk array or bootstrap setting is malformed (names the argument)."""


def prediction_scores(pred: np.ndarray, truth: np.ndarray, dt_s: float,
                      horizons_s: tuple[float, ...]) -> dict[str, np.ndarray]:
    """Per-walk errors of predictions, the same quantities as
    :func:`blindspot.traj.evaluation.score_prediction` for one path.

    Args:
        pred, truth: (N, H, 2) predicted and true positions at the predicted frames, m; NaN
            rows after a walk's horizon (in both) are left out.
        dt_s: frame period, s. horizons_s: horizons of ADE/FDE, s.

    Returns:
        {metric: (N,)}: ``path_error_mean_m`` (the paper's metric: mean over the predicted
        points of the distance to the nearest point of the true path of the same frames),
        ``path_error_first_m``, ``ade_m``/``fde_m`` (whole horizon), and ``ade_<h>s`` /
        ``fde_<h>s`` (mean error over steps 1..n and the error at step n, n = round(h / dt));
        NaN where a walk's horizon is shorter.

    Raises:
        BenchmarkError: arrays not real (N, H, 2) of one shape, or dt / a horizon not > 0.
    """
    who = "prediction_scores"
    p = check_array(pred, "pred", ("N", "H", 2), error=BenchmarkError, who=who, allow_nan=True)
    t = check_array(truth, "truth", p.shape, error=BenchmarkError, who=who, allow_nan=True)
    if not dt_s > 0 or any(not h > 0 for h in horizons_s):
        raise BenchmarkError(f"{who}: expected dt_s > 0 and horizons_s > 0 (s), found {dt_s!r}, "
                             f"{list(horizons_s)!r}")
    err = displacement(p, t)                                               # (N, H)
    near = path_error(p, t)                                                # (N, H)
    valid = np.isfinite(t).all(axis=-1)
    n_valid = valid.sum(axis=1)
    last = np.maximum(n_valid - 1, 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = {
            "path_error_mean_m": np.where(valid, near, 0).sum(axis=1) / n_valid,
            "path_error_first_m": near[:, 0],
            "ade_m": np.where(valid, err, 0).sum(axis=1) / n_valid,
            "fde_m": np.take_along_axis(err, last[:, None], axis=1)[:, 0],
        }
    for h in horizons_s:
        n = int(round(h / dt_s))
        ok = (n >= 1) & (n <= n_valid)
        key = f"{h:g}s"
        if 1 <= n <= err.shape[1]:
            out[f"ade_{key}"] = np.where(ok, err[:, :n].mean(axis=1), np.nan)
            out[f"fde_{key}"] = np.where(ok, err[:, n - 1], np.nan)
        else:
            out[f"ade_{key}"] = out[f"fde_{key}"] = np.full(len(p), np.nan)
    return out


def hidden_gap_error(filled: np.ndarray, truth: np.ndarray, observed: np.ndarray,
                     hidden: np.ndarray) -> np.ndarray:
    """Per-walk mean error of a filled track on the frames that were hidden and filled, as
    ``hidden_mean_m`` of :func:`blindspot.traj.evaluation.score_interpolation`.

    filled, truth: (N, T, 2) m; observed, hidden: (N, T) bool (a radar point; the body hidden
    behind the car). Returns (N,) m, NaN for a walk without a hidden frame inside a gap.
    """
    who = "hidden_gap_error"
    f = check_array(filled, "filled", ("N", "T", 2), error=BenchmarkError, who=who,
                    allow_nan=True)
    t = check_array(truth, "truth", f.shape, error=BenchmarkError, who=who, allow_nan=True)
    obs = check_array(observed, "observed", f.shape[:2], error=BenchmarkError, who=who, dtype=bool)
    hid = check_array(hidden, "hidden", f.shape[:2], error=BenchmarkError, who=who, dtype=bool)
    seen = np.cumsum(obs, axis=1)
    gap = ~obs & (seen > 0) & (seen < seen[:, -1:])        # evaluation.gap_mask, per walk
    use = gap & hid
    err = np.linalg.norm(f - t, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(use, err, 0.0).sum(axis=1) / use.sum(axis=1)


def resample_weights(n: int, n_boot: int, seed: int) -> np.ndarray:
    """(n_boot, n) counts: how often each of n walks is drawn in each bootstrap resample
    (multinomial(n, 1/n) per row, the same as drawing n indices with replacement)."""
    if not (isinstance(n, (int, np.integer)) and n >= 1 and isinstance(n_boot, (int, np.integer))
            and n_boot >= 1):
        raise BenchmarkError(f"resample_weights: expected n >= 1 and n_boot >= 1 integers, found "
                             f"{n!r}, {n_boot!r}")
    rng = np.random.default_rng(seed)
    return rng.multinomial(n, np.full(n, 1.0 / n), size=n_boot).astype(np.float64)


def _boot_mean(values: np.ndarray, weights: np.ndarray, level: float) -> dict:
    v = np.asarray(values, dtype=np.float64)
    ok = np.isfinite(v)
    if not ok.any():
        return {"mean": float("nan"), "ci95": [float("nan"), float("nan")], "n": 0}
    w = weights[:, ok]
    with np.errstate(invalid="ignore", divide="ignore"):
        means = (w @ v[ok]) / w.sum(axis=1)
    means = means[np.isfinite(means)]            # a resample that drew none of these walks
    lo, hi = np.quantile(means, [(1 - level) / 2, (1 + level) / 2])
    return {"mean": float(v[ok].mean()), "ci95": [float(lo), float(hi)], "n": int(ok.sum())}


def bootstrap_means(scores: Mapping[str, Mapping[str, np.ndarray]], *, n_boot: int,
                    level: float = 0.95, seed: int = 0) -> dict[str, dict[str, dict]]:
    """Mean and percentile-bootstrap interval of every (method, metric) vector.

    Args:
        scores: {method: {metric: (N,) per-walk values}}, every vector over the same N walks
            in the same order (NaN = not applicable to that walk).
        n_boot: resamples. level: interval level (0.95: the 2.5 and 97.5 % quantiles).
        seed: seed of the resampling (one resample set for all methods and metrics).

    Returns:
        {method: {metric: {"mean", "ci95": [lo, hi], "n"}}} (``n`` = walks with a value; the
        key is ``ci95`` whatever the level, as the benchmark's JSON names it).

    Raises:
        BenchmarkError: vectors of different lengths, or level outside (0, 1).
    """
    n = _common_length(scores)
    if not 0 < level < 1:
        raise BenchmarkError(f"bootstrap_means: level must be in (0, 1), found {level!r}")
    w = resample_weights(n, n_boot, seed)
    return {m: {k: _boot_mean(v, w, level) for k, v in per.items()} for m, per in scores.items()}


def paired_differences(scores: Mapping[str, Mapping[str, np.ndarray]],
                       pairs: list[tuple[str, str]], *, n_boot: int, level: float = 0.95,
                       seed: int = 0) -> dict[str, dict[str, dict]]:
    """Bootstrap of per-walk differences ``a - b`` for every metric the two methods share.

    Returns {"a - b": {metric: {"mean", "ci95", "n"}}}: a negative mean with an interval
    below 0 says method a has the smaller error on these walks. The resamples are those of
    :func:`bootstrap_means` with the same seed.
    """
    n = _common_length(scores)
    w = resample_weights(n, n_boot, seed)
    out = {}
    for a, b in pairs:
        if a not in scores or b not in scores:
            raise BenchmarkError(f"paired_differences: pair ({a!r}, {b!r}) names a method "
                                 f"without scores; have {sorted(scores)}")
        shared = [k for k in scores[a] if k in scores[b]]
        out[f"{a} - {b}"] = {k: _boot_mean(np.asarray(scores[a][k], float)
                                           - np.asarray(scores[b][k], float), w, level)
                             for k in shared}
    return out


def _common_length(scores: Mapping[str, Mapping[str, np.ndarray]]) -> int:
    lengths = {np.shape(v)[0] if np.ndim(v) == 1 else -1
               for per in scores.values() for v in per.values()}
    if len(lengths) != 1 or -1 in lengths or 0 in lengths:
        raise BenchmarkError(f"per-walk scores must all be non-empty (N,) vectors over the same "
                             f"walks; found lengths {sorted(lengths)}")
    return lengths.pop()
