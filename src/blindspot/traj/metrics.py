"""Path-prediction errors, in metres.

Two families of error live here:

* the paper's metric, :func:`path_error`: every predicted point is scored by its Euclidean
  distance to the *nearest* point of the actual path, whatever its time stamp (so a prediction
  that lies on the true path but runs late still scores well);
* the time-aligned errors of the pedestrian-forecasting literature: :func:`ade` (average
  displacement error over the horizon), :func:`fde` (final displacement error) and
  :func:`per_step_error` (mean error at each horizon step).

Arrays hold (x, y) in metres in their last axis. A NaN row in the *actual* / *truth* array means
"no ground truth at that step" and is left out of every mean; a NaN in a prediction propagates
(a model that returns NaN must not look good). Every input is checked by
:func:`blindspot.arrays.check_array`: real numbers (not complex, object, strings or bools),
shape (..., T, 2), no inf; otherwise :class:`MetricShapeError` names the argument, the expected
and the found shape or dtype.
"""

from __future__ import annotations

import numpy as np

from blindspot.arrays import check_array

__all__ = ["MetricShapeError", "path_error", "displacement", "ade", "fde", "per_step_error"]


class MetricShapeError(ValueError):
    """Inputs to a metric do not have the shapes, dtype or values the metric needs."""


def _as_points(a: np.ndarray, name: str, who: str) -> np.ndarray:
    """(..., T, 2) float64 points; NaN allowed (missing truth / a NaN prediction), inf not."""
    return check_array(a, name, ("...", "T", 2), error=MetricShapeError, who=who, allow_nan=True)


def path_error(pred: np.ndarray, actual: np.ndarray) -> np.ndarray:
    """Distance of each predicted point to the nearest point of the actual path (paper's metric).

    Args:
        pred: (N, 2) predicted points (or (..., N, 2) for a batch of paths).
        actual: (M, 2) points of the actual path (or (..., M, 2), leading dims matching
            ``pred``'s); NaN rows are missing points and are ignored.

    Raises:
        MetricShapeError: not real (..., N, 2) / (..., M, 2) arrays, leading dims differ, or inf.

    Returns:
        (N,) (or (..., N)) distances in metres, ``d_i = min_j ||pred_i - actual_j||`` over the
        non-NaN rows ``j``. NaN where the predicted point is NaN or the actual path has no valid
        point at all.
    """
    p = _as_points(pred, "pred", "path_error")
    a = _as_points(actual, "actual", "path_error")
    if p.shape[:-2] != a.shape[:-2]:
        raise MetricShapeError(f"path_error: leading dims of pred {p.shape} and actual "
                               f"{a.shape} differ")
    diff = p[..., :, None, :] - a[..., None, :, :]              # (..., N, M, 2)
    dist = np.hypot(diff[..., 0], diff[..., 1])                 # (..., N, M)
    missing = np.isnan(a).any(axis=-1)                          # (..., M)
    dist = np.where(missing[..., None, :], np.inf, dist)
    nearest = dist.min(axis=-1) if dist.shape[-1] else np.full(dist.shape[:-1], np.inf)
    # NaN propagates through min only via the un-masked entries: restore it for NaN predictions
    nearest = np.where(np.isnan(p).any(axis=-1), np.nan, nearest)
    return np.where(np.isinf(nearest), np.nan, nearest)


def displacement(pred: np.ndarray, truth: np.ndarray, *, who: str = "displacement"
                 ) -> np.ndarray:
    """Time-aligned Euclidean error ``||pred_t - truth_t||``.

    Args:
        pred, truth: (..., T, 2) arrays of the same shape.

    Returns:
        (..., T) errors in metres (NaN where either point is NaN).

    Raises:
        MetricShapeError: not real (..., T, 2) arrays of the same shape, or an inf value.
    """
    p = _as_points(pred, "pred", who)
    t = _as_points(truth, "truth", who)
    if p.shape != t.shape:
        raise MetricShapeError(f"{who}: pred shape {p.shape} differs from truth shape {t.shape}")
    d = p - t
    return np.hypot(d[..., 0], d[..., 1])


def _mean_over_truth(err: np.ndarray, truth_missing: np.ndarray, axis=None) -> np.ndarray:
    """Mean of ``err`` over entries whose truth exists; NaN predictions stay NaN."""
    valid = ~truth_missing
    total = np.where(valid, err, 0.0).sum(axis=axis)
    count = valid.sum(axis=axis)
    with np.errstate(invalid="ignore", divide="ignore"):
        return total / count


def ade(pred: np.ndarray, truth: np.ndarray) -> float:
    """Average displacement error: mean of ``||pred_t - truth_t||`` over all steps and windows.

    Args:
        pred, truth: (..., T, 2); truth rows that are NaN are left out.

    Returns:
        The mean error in metres (NaN if a prediction is NaN where truth exists).
    """
    err = displacement(pred, truth, who="ade")
    return float(_mean_over_truth(err, np.isnan(np.asarray(truth, float)).any(axis=-1)))


def fde(pred: np.ndarray, truth: np.ndarray) -> float:
    """Final displacement error: mean over windows of the error at the last step ``T-1``.

    Args:
        pred, truth: (..., T, 2); windows whose last truth row is NaN are left out.

    Returns:
        The mean final error in metres.
    """
    err = displacement(pred, truth, who="fde")[..., -1]
    return float(_mean_over_truth(err, np.isnan(np.asarray(truth, float)[..., -1, :]).any(axis=-1)))


def per_step_error(pred: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Mean time-aligned error at each step of the horizon.

    Args:
        pred, truth: (..., T, 2).

    Returns:
        (T,) mean error in metres at each step, averaged over all leading dims (truth-NaN
        entries left out). ``per_step_error(p, t).mean()`` equals ``ade(p, t)`` when no truth
        is missing.
    """
    err = displacement(pred, truth, who="per_step_error")
    missing = np.isnan(np.asarray(truth, float)).any(axis=-1)
    T = err.shape[-1]
    return _mean_over_truth(err.reshape(-1, T), missing.reshape(-1, T), axis=0)
