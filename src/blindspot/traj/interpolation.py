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


def pad_history(history: np.ndarray, length: int, fit_points: int = 10) -> np.ndarray:
    """Extend a (T, 2) history at its start to ``length`` rows by walking its first observed
    points backwards at their mean velocity (a least-squares line over the first ``fit_points``
    observed rows). Rows already there are kept as they are, NaN included."""
    h = _check_track(history, "pad_history", "history")
    length = check_count(length, "length", error=InterpolationError, who="pad_history")
    if not np.isfinite(h).all(axis=1).any():
        raise InterpolationError("pad_history: cannot pad a history with no observed point")
    return pad_histories(h[None], length, fit_points)[0][-max(length, len(h)):]


def pad_histories(histories: np.ndarray, length: int, fit_points: int = 10) -> np.ndarray:
    """Right-aligned histories made at least ``length`` rows long, their unobserved lead filled.

    histories : (B, L, 2) in metres, each ending where its track ends; the rows before a
        track's first observed row (a shorter track in a batch) are NaN. Those rows, and
        ``max(0, length - L)`` new rows in front, are filled by walking the track's first
        ``fit_points`` observed rows backwards along their least-squares line (position against
        frame), as one track alone would be padded. Rows from the first observed one on are
        kept as they are, NaN included.
    Returns (B, max(L, length), 2). Raises InterpolationError for a malformed array, a track
    with no observed row, or a length / fit_points that is not a positive integer.
    """
    who = "pad_histories"
    h = check_array(histories, "histories", ("B", "L", 2), error=InterpolationError, who=who,
                    allow_nan=True)
    length = check_count(length, "length", error=InterpolationError, who=who)
    fit_points = check_count(fit_points, "fit_points", ge=1, error=InterpolationError, who=who)
    n_new = max(0, length - h.shape[1])
    h = np.concatenate([np.full((h.shape[0], n_new, 2), np.nan), h], axis=1)
    obs = np.isfinite(h).all(axis=-1)                                    # (B, L')
    if not obs.any(axis=1).all():
        raise InterpolationError(f"{who}: tracks {np.flatnonzero(~obs.any(axis=1))[:5].tolist()} "
                                 "have no observed point to pad from")
    first = np.argmax(obs, axis=1)                                       # (B,)
    # the first fit_points observed rows, in order, as indices relative to the first one
    order = np.argsort(~obs, axis=1, kind="stable")[:, :fit_points]      # (B, k)
    n_fit = np.minimum(obs.sum(axis=1), fit_points)
    use = np.arange(order.shape[1])[None, :] < n_fit[:, None]            # (B, k)
    rel = np.where(use, order - first[:, None], 0).astype(float)
    pts = np.take_along_axis(h, order[..., None], axis=1)                # (B, k, 2)
    pts = np.where(use[..., None], pts, 0.0)
    cnt = n_fit.astype(float)
    t = np.where(use, rel - (rel.sum(axis=1) / cnt)[:, None], 0.0)
    p_mean = pts.sum(axis=1) / cnt[:, None]
    sxx = (t**2).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        vel = (t[..., None] * np.where(use[..., None], pts - p_mean[:, None], 0.0)).sum(axis=1) \
            / sxx[:, None]
    vel = np.where((n_fit >= 2)[:, None], vel, 0.0)
    anchor = p_mean - vel * (rel.sum(axis=1) / cnt)[:, None]             # the line at `first`
    offset = np.arange(h.shape[1])[None, :] - first[:, None]            # (B, L') frames from first
    line = anchor[:, None, :] + vel[:, None, :] * offset[..., None]
    return np.where((offset < 0)[..., None], line, h)


def _track_spans(observed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """First and last observed frame of each track of a (B, T) mask (-1 where none)."""
    any_ = observed.any(axis=1)
    first = np.where(any_, np.argmax(observed, axis=1), -1)
    last = np.where(any_, observed.shape[1] - 1 - np.argmax(observed[:, ::-1], axis=1), -1)
    return first, last


def gather_histories(tracks: np.ndarray, begin: np.ndarray, stop: np.ndarray,
                     min_length: int = 1, *, reverse: bool = False) -> np.ndarray:
    """Frames ``begin[b] .. stop[b] - 1`` of each track, right-aligned in one (B, L, 2) array.

    L = max(min_length, longest span); the rows before a shorter span are NaN. With
    ``reverse`` the span is taken in reversed time (ending at frame ``begin[b]``): the history
    of a track walked backwards. tracks (B, T, 2); begin, stop (B,) int with begin < stop.
    """
    n = stop - begin
    L = max(int(min_length), int(n.max()) if n.size else 1)
    r = np.arange(L)[None, :] - (L - n)[:, None]                         # (B, L) index in span
    frame = (stop[:, None] - 1 - (L - 1 - np.arange(L))[None, :]) if not reverse \
        else (begin[:, None] + (L - 1 - np.arange(L))[None, :])
    ok = r >= 0
    got = np.take_along_axis(tracks, np.clip(frame, 0, tracks.shape[1] - 1)[..., None], axis=1)
    return np.where(ok[..., None], got, np.nan)


def _rollout(predictor: PathPredictor, histories: np.ndarray, horizon: int) -> np.ndarray:
    """(B, horizon, 2) continuation of right-aligned ``histories`` (B, L, 2) by the predictor.

    A predictor with a fixed input ``window`` (the LSTM's 50 points) gets histories at least
    that long: a shorter one is extended backwards in time by :func:`pad_histories`.
    """
    window = getattr(predictor, "window", None)
    if window is not None:
        histories = pad_histories(histories, window)
    return np.asarray(predictor.predict(histories, horizon))


def _gap_table(observed: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every interior gap of a batch: (track, start, stop, rank of the gap in its track)."""
    padded = np.pad(observed.astype(np.int8), ((0, 0), (1, 1)), constant_values=1)
    edges = np.diff(padded, axis=1)
    gap = ~observed & _between(observed)
    starts = (edges[:, :-1] == -1) & gap
    stops = (edges[:, 1:] == 1) & gap                                   # last frame of each run
    b, s = np.nonzero(starts)
    _, e = np.nonzero(stops)
    rank = np.cumsum(starts, axis=1)[b, s] - 1
    return b, s, e + 1, rank


def _between(observed: np.ndarray) -> np.ndarray:
    """(B, T) True where a frame has an observed frame before and after it."""
    seen = np.cumsum(observed, axis=1)
    return (seen > 0) & (seen < seen[:, -1:])


def fill_forward(tracks: np.ndarray, predictor: PathPredictor) -> np.ndarray:
    """Fill each gap by rolling ``predictor`` forward from everything seen (or filled) before
    it. tracks (B, T, 2) -> (B, T, 2); the k-th gaps of all tracks are rolled out together."""
    return _fill_rollouts(tracks, predictor, two_sided=False, who="fill_forward")


def fill_bidirectional(tracks: np.ndarray, predictor: PathPredictor) -> np.ndarray:
    """Fill each gap with a blend of a forward rollout and a backward rollout (time-reversed).
    tracks (B, T, 2) -> (B, T, 2)."""
    return _fill_rollouts(tracks, predictor, two_sided=True, who="fill_bidirectional")


def _fill_rollouts(tracks: np.ndarray, predictor: PathPredictor, *, two_sided: bool,
                   who: str) -> np.ndarray:
    out = _check_tracks(tracks, who).copy()
    observed = np.isfinite(out).all(axis=-1)
    b_all, s_all, e_all, rank = _gap_table(observed)
    first, last = _track_spans(observed)
    window = getattr(predictor, "window", None) or 1
    for k in range(int(rank.max()) + 1 if rank.size else 0):   # the k-th gap of every track
        sel = rank == k
        b, start, stop = b_all[sel], s_all[sel], e_all[sel]
        n = stop - start
        horizon = int(n.max())
        fwd = _rollout(predictor, gather_histories(out[b], first[b], start, window), horizon)
        j = np.arange(horizon)[None, :]
        inside = j < n[:, None]                                          # (G, horizon)
        fill = fwd
        if two_sided:
            # the future walked backwards: from the track's last point down to the gap's end
            back = gather_histories(out[b], stop, last[b] + 1, window, reverse=True)
            bwd = _rollout(predictor, back, horizon)
            # step j of the gap is backward step n - 1 - j
            idx = np.clip(n[:, None] - 1 - j, 0, horizon - 1)
            bwd = np.take_along_axis(bwd, idx[..., None], axis=1)
            w = ((j + 1) / (n[:, None] + 1))[..., None]                 # 0 -> forward, 1 -> back
            fill = (1.0 - w) * fwd + w * bwd
        rows = np.broadcast_to(b[:, None], inside.shape)[inside]
        cols = (start[:, None] + j)[inside]
        out[rows, cols] = fill[inside]
    return out


def fill_kalman(tracks: np.ndarray, smoother: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """Fill the gaps with a smoother's estimate; seen rows stay as seen.

    tracks (B, T, 2); ``smoother`` maps (B, T, 2) tracks to (B, T, 2) smoothed positions (e.g.
    ``KalmanCV.smooth_batch``)."""
    out = _check_tracks(tracks, "fill_kalman").copy()
    smoothed = np.asarray(smoother(out))
    observed = np.isfinite(out).all(axis=-1)
    gap = ~observed & _between(observed)
    out[gap] = smoothed[gap]
    return out


def _check_tracks(tracks: np.ndarray, who: str) -> np.ndarray:
    """(B, T, 2) float64 (x, y) metres, NaN rows = no point; InterpolationError otherwise."""
    return check_array(tracks, "tracks", ("B", "T", 2), error=InterpolationError, who=who,
                       allow_nan=True)


def fill_gaps(tracks: np.ndarray, method: str, *, predictor: PathPredictor | None = None,
              smoother: Callable[[np.ndarray], np.ndarray] | None = None) -> np.ndarray:
    """Fill the gaps of a batch of tracks (B, T, 2) with ``method`` in METHODS.

    ``smoother`` (kalman) maps (B, T, 2) -> (B, T, 2). The gap rows of every track are filled,
    observed rows are untouched, rows before a track's first / after its last point stay NaN.

    Raises:
        InterpolationError: ``tracks`` not a real (B, T, 2) array (NaN rows are the frames to
            fill, inf is refused), an unknown method, or a missing predictor / smoother.
    """
    if method == "forward":
        return fill_forward(tracks, _need(predictor, method))
    if method == "bidirectional":
        return fill_bidirectional(tracks, _need(predictor, method))
    if method == "kalman":
        return fill_kalman(tracks, _need(smoother, method))
    raise InterpolationError(f"interpolation method {method!r} unknown: expected one of "
                             f"{METHODS}")


def interpolate(track: np.ndarray, method: str, *, predictor: PathPredictor | None = None,
                smoother: Callable[[np.ndarray], np.ndarray] | None = None) -> np.ndarray:
    """Fill the gaps of one track (T, 2) with ``method`` in METHODS: :func:`fill_gaps` on a
    batch of one. ``smoother`` (kalman) maps one track (T, 2) to (T, 2) (e.g. ``KalmanCV.smooth``).

    Raises:
        InterpolationError: ``track`` not a real (T, 2) array (NaN rows are the frames to fill,
            inf is refused), an unknown method, or a missing predictor / smoother.
    """
    t = _check_track(track, "interpolate")
    batch = None if smoother is None else (lambda b: np.asarray(smoother(b[0]))[None])
    return fill_gaps(t[None], method, predictor=predictor, smoother=batch)[0]


def _need(obj, method):
    if obj is None:
        raise InterpolationError(f"interpolation method {method!r} needs a "
                         f"{'smoother' if method == 'kalman' else 'predictor'}")
    return obj


def scene_track(points, scene: str, n_frames: int) -> np.ndarray:
    """(n_frames, 2) x, y of a scene's radar points (the ``localise`` output: columns ``scene``,
    ``frame``, ``x_m``, ``y_m``), NaN where the frame has no point."""
    track = np.full((n_frames, 2), np.nan)
    p = points[points.scene == scene]
    track[p.frame.to_numpy()] = p[["x_m", "y_m"]].to_numpy()
    return track
