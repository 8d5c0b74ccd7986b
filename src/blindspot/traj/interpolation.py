"""Filling the frames where the pedestrian was hidden (the paper's Fig. 8).

A track is a ``(T, 2)`` array of (x, y) in metres, one row per radar frame, NaN where the radar gave
no point. A *gap* is a run of NaN rows with a seen point on both sides. Three ways to fill it, with
one output format (the track with the gap rows filled, observed rows untouched):

* ``forward``       the paper's method: roll a path predictor forward from the points before the gap;
* ``kalman``        a constant-velocity Kalman smoother over the whole track (uses both sides);
* ``bidirectional`` ours: roll the predictor forward from the points before the gap *and* backward
                    (on the time-reversed track) from the points after it, and blend the two rollouts
                    with weights that move linearly from the forward one to the backward one, so the
                    fill starts where the track leaves off and lands where the track picks up again.

Walking backwards in time is still a walking path, so a predictor trained on paths in every
direction serves for the backward rollout unchanged.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from blindspot.arrays import check_array, check_count
from blindspot.traj.config import INTERPOLATION_METHODS as METHODS
from blindspot.traj.predictor import PathPredictor


class InterpolationError(ValueError):
    """A track, mask or method handed to a gap filler is malformed (names the argument)."""


def find_gaps(observed: np.ndarray) -> np.ndarray:
    """Interior runs of unobserved frames.

    observed : (T,) bool. Returns (G, 2) int array of [start, stop) frame indices of each run of
    False that has a True on both sides (leading and trailing runs are not gaps: nothing bounds them).
    Raises InterpolationError when ``observed`` is not a 1-D boolean array.
    """
    obs = check_array(observed, "observed", ("T",), error=InterpolationError, who="find_gaps",
                      dtype=bool)
    edges = np.diff(np.concatenate([[1], obs.astype(np.int8), [1]]))
    starts = np.flatnonzero(edges == -1)
    stops = np.flatnonzero(edges == 1)
    interior = (starts > 0) & (stops < len(obs))
    if obs.any():
        first, last = np.flatnonzero(obs)[[0, -1]]
        interior &= (starts > first) & (stops <= last)
    return np.stack([starts[interior], stops[interior]], axis=1).reshape(-1, 2)


def _check_track(track: np.ndarray, who: str, name: str = "track") -> np.ndarray:
    """(T, 2) float64 (x, y) metres, NaN rows = no point; InterpolationError otherwise."""
    return check_array(track, name, ("T", 2), error=InterpolationError, who=who, allow_nan=True)


def _rollout(predictor: PathPredictor, history: np.ndarray, horizon: int) -> np.ndarray:
    """(horizon, 2) continuation of ``history`` (T, 2) by the predictor.

    A predictor with a fixed input ``window`` (the LSTM's 50 points) gets a history at least that
    long: a shorter one is extended backwards in time by :func:`pad_history`.
    """
    window = getattr(predictor, "window", None)
    if window is not None and len(history) < window:
        history = pad_history(history, window)
    return np.asarray(predictor.predict(history[None], horizon))[0]


def pad_history(history: np.ndarray, length: int, fit_points: int = 10) -> np.ndarray:
    """Extend a (T, 2) history at its start to ``length`` rows by walking its first observed
    points backwards at their mean velocity (a least-squares line over the first ``fit_points``
    observed rows). Rows already there are kept as they are, NaN included."""
    h = _check_track(history, "pad_history", "history")
    length = check_count(length, "length", error=InterpolationError, who="pad_history")
    fit_points = check_count(fit_points, "fit_points", ge=1, error=InterpolationError,
                             who="pad_history")
    seen = np.flatnonzero(~np.isnan(h).any(axis=1))
    if len(seen) == 0:
        raise InterpolationError("pad_history: cannot pad a history with no observed point")
    n_pad = length - len(h)
    if n_pad <= 0:
        return h
    idx = seen[:fit_points]
    if len(idx) >= 2:
        t = idx - idx.mean()
        vel = (t[:, None] * (h[idx] - h[idx].mean(axis=0))).sum(axis=0) / (t**2).sum()
        anchor = h[idx].mean(axis=0) - vel * idx.mean()  # the fitted line at frame 0
    else:
        vel, anchor = np.zeros(2), h[idx[0]]
    back = anchor + vel * np.arange(-n_pad, 0)[:, None]
    return np.vstack([back, h])


def fill_forward(track: np.ndarray, predictor: PathPredictor) -> np.ndarray:
    """Fill each gap by rolling ``predictor`` forward from everything seen (or filled) before it."""
    out = _check_track(track, "fill_forward").copy()
    for start, stop in find_gaps(~np.isnan(out).any(axis=1)):
        out[start:stop] = _rollout(predictor, _observed_prefix(out[:start]), stop - start)
    return out


def fill_bidirectional(track: np.ndarray, predictor: PathPredictor) -> np.ndarray:
    """Fill each gap with a blend of a forward rollout and a backward rollout (time-reversed)."""
    out = _check_track(track, "fill_bidirectional").copy()
    observed = ~np.isnan(out).any(axis=1)
    for start, stop in find_gaps(observed):
        n = stop - start
        fwd = _rollout(predictor, _observed_prefix(out[:start]), n)
        after = out[stop:][::-1]  # the future, reversed: it ends at the first point after the gap
        bwd = _rollout(predictor, _observed_prefix(after), n)[::-1]
        w = (np.arange(1, n + 1) / (n + 1))[:, None]  # 0 -> forward at the start, 1 -> backward
        out[start:stop] = (1.0 - w) * fwd + w * bwd
    return out


def fill_kalman(track: np.ndarray, smoother: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """Fill the gaps with a smoother's estimate (e.g. ``KalmanCV.smooth``); seen rows stay as seen."""
    out = _check_track(track, "fill_kalman").copy()
    smoothed = np.asarray(smoother(out))
    for start, stop in find_gaps(~np.isnan(out).any(axis=1)):
        out[start:stop] = smoothed[start:stop]
    return out


def _observed_prefix(history: np.ndarray) -> np.ndarray:
    """Drop the leading unobserved rows of a history (a predictor needs a first point to start)."""
    seen = np.flatnonzero(~np.isnan(history).any(axis=1))
    if len(seen) == 0:
        raise InterpolationError("no observed point on this side of the gap to roll out from")
    return history[seen[0]:]


def interpolate(track: np.ndarray, method: str, *, predictor: PathPredictor | None = None,
                smoother: Callable[[np.ndarray], np.ndarray] | None = None) -> np.ndarray:
    """Fill the gaps of ``track`` (T, 2) with ``method`` in METHODS.

    Raises:
        InterpolationError: ``track`` not a real (T, 2) array (NaN rows are the frames to fill,
            inf is refused), an unknown method, or a missing predictor / smoother.
    """
    if method == "forward":
        return fill_forward(track, _need(predictor, method))
    if method == "bidirectional":
        return fill_bidirectional(track, _need(predictor, method))
    if method == "kalman":
        return fill_kalman(track, _need(smoother, method))
    raise InterpolationError(f"interpolation method {method!r} unknown: expected one of "
                             f"{METHODS}")


def _need(obj, method):
    if obj is None:
        raise InterpolationError(f"interpolation method {method!r} needs a "
                         f"{'smoother' if method == 'kalman' else 'predictor'}")
    return obj
