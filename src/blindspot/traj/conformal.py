"""Adaptive conformal ellipses: a forecast's uncertainty kept calibrated online, from the outcomes
the system has already seen.

A calibration fitted on validation data (:mod:`blindspot.traj.calibration`,
:func:`blindspot.traj.distribution.fit_scale_mixture`) is right for data like the validation
data. A new scene is not: on the ETH/UCY test folds the 50 % ellipses of a val-calibrated
forecast cover 15-68 % (``reports/metrics/calibration_ethucy.json`` of 2026-11-30). A deployed predictor sees,
a few seconds after each prediction, where the pedestrian actually went. This module uses those
revealed outcomes, and only those, to keep each level's ellipse calibrated:

* the *score* of a prediction at future step h is the squared Mahalanobis distance ``d^2`` of
  the true position under the forecast's own covariance (any fixed scale of it; the ellipse's
  shape and orientation stay the forecast's);
* the radius of the ``level`` ellipse at step h for a prediction made at time t is the
  conformal quantile, at level ``1 - a_t``, of the scores of step h of the last ``window``
  predictions whose step h was revealed by t (split conformal prediction on a sliding
  window: Vovk, Gammerman & Shafer 2005; the ``ceil((1 - a)(M + 1))``-th smallest of M);
* ``a_t`` follows adaptive conformal inference (ACI; Gibbs & Candès 2021, "Adaptive conformal
  inference under distribution shift", NeurIPS): at each prediction time that has new revealed
  outcomes it moves once, by ``gamma (alpha - err)``, ``alpha = 1 - level``, ``err`` the share
  of those outcomes that fell outside the ellipse they were given. One step per time, not per
  outcome: a crowded frame (ETH/UCY univ reveals up to 57 outcomes at once) would otherwise
  push the level past 0 or 1 and buy its coverage with unbounded or empty ellipses. Gibbs &
  Candès' Proposition 4.1 (average miscoverage within ``(max(a_1, 1 - a_1) + gamma) /
  (gamma T)`` of ``alpha`` after T steps) is for one outcome per step revealed at once; with
  several per step, revealed a horizon late, it holds only approximately, so the coverage is
  reported with the share of unbounded ellipses (:meth:`AdaptiveConformal.coverage`).

The window starts filled with validation scores (the prior: before the first revealed outcome
the ellipses are the validation data's conformal ones): ``window`` of them evenly spaced
through the validation set (all its scenes, not the tail of its last file), then it slides into
the stream's own. Each step has its own window, so an outcome may be revealed step by step:
the true position h steps ahead is known h steps after the prediction, not only once the whole
future has passed (``t_revealed`` (N, H)).

A new scene can differ from the validation data by a scale: the Kalman filter's median d^2 on
one ETH/UCY val scene, against the same fold's other val scenes, ranges from 0.01x to 16x
(``studies/online_calibration.py --split val-scenes``). A short recording (eth's test
scene: 181 predictions) makes most of its predictions with the prior still in the window, and
ACI's small steps cannot make up for it. With ``rescale_prior_after = k``, once a step's window
holds k of the stream's own scores the prior scores still in it are multiplied by the ratio of
the medians (own / prior; not where the prior's median is 0): the prior keeps its shape (its
tail, which k scores cannot tell) and takes the scene's scale. This is our heuristic, not part
of Gibbs & Candès' method; it uses revealed outcomes only, and it fades as the prior leaves the
window (after ``window`` own outcomes the window and the guarantee are the plain method's).
Which setting a scene needs is chosen on validation scenes met as new scenes
(:func:`select_on_held_out_streams`).

What every online method shares (:class:`OnlineEllipses`: ``levels``, ``radii``, the coverage
report, ``setting``) and its input check (:func:`check_stream_inputs`) live here too; the other
method, :class:`blindspot.traj.scale_tracker.ScaleTracker`, keeps no window and moves one scale
per level on every revealed outcome. :func:`select_on_held_out_streams` chooses among settings
of both kinds.

Causal by construction: a prediction's radii depend on scores revealed strictly by its own time
(tested by changing every later score). One stream per scene recording (``stream``): outcomes
are not shared between recordings.

Shapes: scores (N predictions, H steps); times (N,) in any one unit (ETH/UCY: frame rows);
radii (L levels, N, H) in d^2 units (compare with ``d^2`` of the same forecast).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from blindspot.arrays import check_array

__all__ = ["AdaptiveConformal", "ConformalError", "HeldOutStreamScore", "OnlineEllipses",
           "check_candidates", "check_stream_inputs", "cluster_bootstrap_coverage",
           "ellipse_hits",
           "held_out_choice_coverage", "rank_held_out", "select_on_held_out_streams",
           "stream_coverage"]

#: prefix of the adaptive ellipses' coverage keys in the metrics files
#: (``online_coverage_50`` beside the val calibration's ``coverage_50``)
KEY_PREFIX = "online_coverage_"


class ConformalError(ValueError):
    """Scores, times or settings of the online ellipses (:class:`AdaptiveConformal`,
    :class:`~blindspot.traj.scale_tracker.ScaleTracker`) of the wrong shape or value."""


def check_stream_inputs(scores, t_predicted, t_revealed, stream, prior, *, who: str
                        ) -> tuple[np.ndarray, ...]:
    """The arguments of an online method's ``radii`` checked and as arrays: ``(scores (N, H),
    t_predicted (N,), t_revealed (N, H), stream (N,) int, prior (M, H))``; a (N,)
    ``t_revealed`` (the whole future known at once) broadcast to every step.

    Raises:
        ConformalError (prefixed with ``who``): mismatched shapes, non-finite times, a
            non-integer stream, or an outcome revealed at or before its prediction.
    """
    s = check_array(scores, "scores", ("N", "H"), error=ConformalError, who=who,
                    allow_nan=True)
    n, h = s.shape
    prior = check_array(prior, "prior", ("M", h), error=ConformalError, who=who,
                        allow_nan=True)
    tp = check_array(t_predicted, "t_predicted", (n,), error=ConformalError, who=who)
    per_step = np.ndim(t_revealed) == 2
    tr = check_array(t_revealed, "t_revealed", (n, h) if per_step else (n,),
                     error=ConformalError, who=who)
    group = check_array(stream, "stream", (n,), error=ConformalError, who=who, dtype=int)
    tr = tr if per_step else np.broadcast_to(tr[:, None], (n, h))
    early = tr <= tp[:, None]
    if np.any(early):
        i, k = np.unravel_index(int(np.argmax(early)), early.shape)
        at = f"row {i} step {k}" if per_step else f"row {i}"
        raise ConformalError(f"{who}: t_revealed must be after t_predicted (an outcome is "
                             f"known only after its prediction is made); {at} has "
                             f"t_predicted {tp[i]:g}, t_revealed {tr[i, k]:g}")
    return s, tp, tr, group, prior


class OnlineEllipses:
    """What the online ellipses share (:class:`AdaptiveConformal`,
    :class:`blindspot.traj.scale_tracker.ScaleTracker`): nominal ``levels``, ``radii(scores,
    t_predicted, t_revealed, stream, prior)`` (L, N, H) in d^2 units, the coverage computed
    from them, and ``setting``, what the metrics files record of the choice."""

    levels: tuple[float, ...]

    def radii(self, scores: np.ndarray, t_predicted: np.ndarray, t_revealed: np.ndarray,
              stream: np.ndarray, prior: np.ndarray) -> np.ndarray:
        """(L, N, H) radii in d^2 units of every prediction's ellipses (each method's own)."""
        raise NotImplementedError

    @property
    def setting(self) -> dict[str, float | int | str]:
        """``online_method`` and the method's parameters, for the metrics files."""
        raise NotImplementedError

    def coverage(self, scores: np.ndarray, t_predicted: np.ndarray, t_revealed: np.ndarray,
                 stream: np.ndarray, prior: np.ndarray, clusters: np.ndarray | None = None,
                 n_boot: int = 2000, seed: int = 0) -> dict[str, float | list[float]]:
        """Coverage and size of the :meth:`radii` (same arguments and errors), for the metrics
        files: ``online_coverage_<p>`` (p = the level in whole percent): the share of the
        finite ``scores`` inside their ellipse; ``online_unbounded_<p>``: the share of those
        points whose ellipse is unbounded (+inf: a coverage bought that way says nothing);
        ``online_radius_<p>``: the median finite radius, in standard deviations of the
        forecast's own covariance (sqrt of d^2; a Gaussian's 90 % ellipse: 2.15).

        With ``clusters`` (N,) (integer ids: the pedestrian of each prediction, the path), also
        ``online_coverage_<p>_ci95``: [lo, hi] of a cluster bootstrap (``n_boot`` resamples of
        the clusters with replacement, ``seed``; percentile interval) of the coverage of these
        same ellipses. One pedestrian's overlapping windows are not independent draws, so
        this, not a binomial interval over the points, says how far a fold's coverage can
        stray by chance (ETH/UCY eth: 181 windows of a few dozen pedestrians). The radii are
        held fixed (they depend on other pedestrians' outcomes too): an interval conditional
        on them."""
        radii = self.radii(scores, t_predicted, t_revealed, stream, prior)
        hits = ellipse_hits(scores, radii)
        seen = ~np.isnan(np.asarray(scores, float))
        out: dict[str, float | list[float]] = {}
        for lv, c, r in zip(self.levels, hits, radii):
            p = round(100 * lv)
            finite = r[seen & np.isfinite(r)]
            out[f"{KEY_PREFIX}{p}"] = float(c)
            out[f"online_unbounded_{p}"] = float(np.isinf(r[seen]).mean()) if seen.any() else 0.0
            out[f"online_radius_{p}"] = float(np.sqrt(np.median(finite))) if finite.size \
                else float("inf")
        if clusters is not None:
            inside = (np.asarray(scores, float)[None] <= radii) & seen[None]     # (L, N, H)
            ci = cluster_bootstrap_coverage(inside, seen, clusters, n_boot, seed)
            for lv, (lo, hi) in zip(self.levels, ci):
                out[f"{KEY_PREFIX}{round(100 * lv)}_ci95"] = [float(lo), float(hi)]
        return out

    def _check_levels(self) -> None:
        lv = np.asarray(self.levels, float)
        if lv.ndim != 1 or lv.size == 0 or not np.all((lv > 0) & (lv < 1)) \
                or len({round(100 * x) for x in lv}) != lv.size:
            raise ConformalError(f"levels: expected nominal coverages in (0, 1), distinct in "
                                 f"whole percent, found {self.levels!r}")


@dataclass(frozen=True)
class AdaptiveConformal(OnlineEllipses):
    """Sliding-window conformal ellipses with ACI level updates (module docstring).

    Attributes:
        levels: nominal coverages in (0, 1), e.g. (0.5, 0.9, 0.95), distinct in whole percent
            (they name the metrics keys).
        gamma: ACI step size per prediction time (Gibbs & Candès 2021 use 0.005; 0 = plain
            sliding-window conformal prediction).
        window: revealed predictions whose scores are kept (the most recent ones), >= 1; a
            step without truth (NaN) in some of them has fewer scores.
        rescale_prior_after: 0 (off) or k >= 1: once a step's window holds k of the stream's
            own scores, the prior scores still in it are multiplied by the ratio of the
            medians of those own scores and of the prior (a prior of the new scene's scale;
            module docstring).
    """

    levels: tuple[float, ...]
    gamma: float = 0.005
    window: int = 100
    rescale_prior_after: int = 0

    def __post_init__(self) -> None:
        self._check_levels()
        if not (np.isfinite(self.gamma) and 0 <= self.gamma < 1):
            raise ConformalError(f"gamma: expected a step size in [0, 1), found {self.gamma!r}")
        if isinstance(self.window, bool) or not (isinstance(self.window, (int, np.integer))
                                                 and self.window >= 1):
            raise ConformalError(f"window: expected an integer >= 1, found {self.window!r}")
        k = self.rescale_prior_after
        if isinstance(k, bool) or not (isinstance(k, (int, np.integer)) and k >= 0):
            raise ConformalError(f"rescale_prior_after: expected an integer >= 0 (0 = off), "
                                 f"found {k!r}")

    def radii(self, scores: np.ndarray, t_predicted: np.ndarray, t_revealed: np.ndarray,
              stream: np.ndarray, prior: np.ndarray) -> np.ndarray:
        """Radii (L, N, H), d^2 units, of every prediction's ellipses.

        Args:
            scores: (N, H) d^2 of each prediction's true positions (NaN: a step without truth;
                it neither counts nor moves a level).
            t_predicted: (N,) time each prediction is made (its last observation).
            t_revealed: when each outcome is known, after ``t_predicted``: (N,) one time for
                the whole future (its last future point), or (N, H) one per step (step h's
                true position is known at step h's own time, so the near steps adapt a
                horizon sooner). An outcome is used by the predictions made at or after it.
            stream: (N,) int, the recording each prediction belongs to; each stream starts
                from ``prior`` and level ``1 - alpha``.
            prior: (M, H) validation scores (NaN allowed): ``window`` of them, evenly spaced
                through the M, are the window's initial content.

        Returns:
            (L, N, H) float: +inf where the level asks for more than the window holds (a
            level of 1 - a_t > M / (M + 1)), 0 where ACI has pushed it to <= 0.

        Raises:
            ConformalError: mismatched shapes, a reveal time not after its prediction time,
                non-finite times or a non-integer stream.

        The loop runs over the distinct prediction times of a stream (an online recursion: the
        level at t depends on the outcomes before t); everything within one time (all its
        predictions, steps and levels) is vectorised.
        """
        s, tp, tr, group, prior = check_stream_inputs(scores, t_predicted, t_revealed, stream,
                                                      prior, who="AdaptiveConformal.radii")
        n, h = s.shape
        alpha = 1.0 - np.asarray(self.levels, float)                      # (L,)
        out = np.empty((alpha.size, n, h))
        if prior.shape[0] > self.window:   # evenly spaced through the validation set
            prior = prior[np.arange(self.window) * prior.shape[0] // self.window]
        for g in np.unique(group):
            rows = np.flatnonzero(group == g)
            out[:, rows] = self._stream(s[rows], tp[rows], tr[rows], prior, alpha)
        return out

    @property
    def setting(self) -> dict[str, float | int | str]:
        """What the metrics files record of the setting."""
        return {"online_method": "aci_window", "online_gamma": self.gamma,
                "online_window": self.window, "online_rescale_after": self.rescale_prior_after}

    def _stream(self, s: np.ndarray, tp: np.ndarray, tr: np.ndarray, prior: np.ndarray,
                alpha: np.ndarray) -> np.ndarray:
        """Radii (L, n, H) of one stream (module docstring); ``tr`` (n, H) per-step reveal
        times. Each step keeps its own window: the scores of step k in the order they were
        revealed, after the prior's."""
        n, h = s.shape
        n_prior = prior.shape[0]
        steps = np.arange(h)
        out = np.empty((alpha.size, n, h))
        by_reveal = np.argsort(tr, axis=0, kind="stable")                 # (n, H) per step
        pool = np.concatenate([prior, np.take_along_axis(s, by_reveal, 0)])  # (M + n, H)
        tr_sorted = np.take_along_axis(tr, by_reveal, 0)
        times = np.unique(tp)
        revealed = np.stack([np.searchsorted(tr_sorted[:, k], times, side="right")
                             for k in steps], axis=1)                      # (T, H) counts
        prior_median = _median_or_nan(prior)                               # (H,)
        a = np.broadcast_to(alpha[:, None], (alpha.size, h)).copy()       # (L, H) ACI levels
        order = np.argsort(tp, kind="stable")
        bounds = np.r_[np.searchsorted(tp[order], times, side="left"), n]
        n_seen = np.zeros(h, np.int64)                                     # revealed per step
        slots = np.arange(min(self.window, len(pool)))[:, None]            # (W, 1)
        for k, now in enumerate(revealed):
            new = now - n_seen
            if new.any():      # outcomes revealed since the last prediction time: one ACI step
                pos = n_seen + np.arange(new.max())[:, None]               # (J, H) reveal ranks
                rows = by_reveal[np.minimum(pos, n - 1), steps]            # (J, H) predictions
                got = s[rows, steps]
                seen = (pos < now) & ~np.isnan(got)
                err = (got[None] > out[:, rows, steps]) & seen[None]       # (L, J, H)
                n_ok = seen.sum(0)                                         # (H,)
                share = err.sum(1) / np.maximum(n_ok, 1)                   # (L, H)
                a += np.where(n_ok > 0, self.gamma * (alpha[:, None] - share), 0.0)
                n_seen = now
            hi = n_prior + now                                             # (H,) pool ends
            at = np.maximum(hi - self.window, 0) + slots                   # (W, H) pool rows
            inside = at < hi
            recent = np.where(inside, pool[np.minimum(at, len(pool) - 1), steps], np.nan)
            if self.rescale_prior_after:
                recent = self._rescaled(recent, at < n_prior, prior_median)
            rows = order[bounds[k]:bounds[k + 1]]
            out[:, rows] = _conformal_quantile(recent, 1.0 - a)[:, None, :]
        return out

    def _rescaled(self, recent: np.ndarray, from_prior: np.ndarray,
                  prior_median: np.ndarray) -> np.ndarray:
        """The window (W, H) with its prior scores of each step multiplied by the ratio of the
        median of the stream's own scores in the window to the prior's median, for the steps
        whose window holds at least ``rescale_prior_after`` own finite scores."""
        own = np.where(from_prior, np.nan, recent)
        n_own = np.sum(~np.isnan(own), axis=0)
        ready = (n_own >= self.rescale_prior_after) & (prior_median > 0)
        if not ready.any():
            return recent
        ratio = np.ones(recent.shape[1])
        ratio[ready] = _median_or_nan(own[:, ready]) / prior_median[ready]
        return np.where(from_prior, recent * ratio, recent)


def _median_or_nan(x: np.ndarray) -> np.ndarray:
    """(H,) median of each column's finite values of x (M, H); NaN for a column without any."""
    if x.shape[0] == 0:
        return np.full(x.shape[1], np.nan)
    srt = np.sort(x, axis=0)                                   # NaN last
    m = np.sum(~np.isnan(x), axis=0)
    cols = np.arange(x.shape[1])
    last = x.shape[0] - 1
    mid = 0.5 * (srt[np.clip((m - 1) // 2, 0, last), cols] + srt[np.clip(m // 2, 0, last), cols])
    return np.where(m > 0, mid, np.nan)


def _conformal_quantile(scores: np.ndarray, q: np.ndarray) -> np.ndarray:
    """(L, H) the ``ceil(q (M_h + 1))``-th smallest of each step's M_h finite scores (M, H),
    for levels q (L, H): +inf when that rank exceeds M_h, 0 when q <= 0. ``q (M_h + 1)``
    within 1e-9 of a whole number counts as that number: ACI's level is a sum of steps whose
    rounding depends on the order they are added in, and must not decide the rank."""
    srt = np.sort(scores, axis=0)                              # NaN last
    m = np.sum(~np.isnan(scores), axis=0)                      # (H,)
    rank = np.ceil(q * (m + 1) - 1e-9).astype(np.int64) - 1    # (L, H), 0-based
    value = np.take_along_axis(srt, np.clip(rank, 0, max(scores.shape[0] - 1, 0)), axis=0) \
        if scores.shape[0] else np.full(q.shape, np.inf)
    value = np.where(np.maximum(rank, 0) >= m, np.inf, value)
    return np.where(q <= 0, 0.0, value)


@dataclass(frozen=True)
class HeldOutStreamScore:
    """How one candidate's ellipses did on validation streams each met as a new scene
    (:func:`select_on_held_out_streams`): the mean and the worst distance of a stream's
    coverage from nominal (over streams and levels), and the largest share of unbounded
    ellipses of any stream."""

    distance_mean: float
    distance_worst: float
    unbounded: float

    @classmethod
    def of(cls, distances: Sequence[np.ndarray], unbounded: Sequence[float]
           ) -> HeldOutStreamScore:
        """From each stream's (L,) distances |coverage - nominal| and unbounded share."""
        d = np.asarray(distances, float)
        return cls(float(d.mean()), float(d.max()), float(max(unbounded, default=0.0)))


def stream_coverage(candidate: OnlineEllipses, scores: np.ndarray, t_predicted: np.ndarray,
                    t_revealed: np.ndarray, prior: np.ndarray) -> tuple[np.ndarray, float]:
    """One stream met as a new scene, ``prior`` all it knows before its own outcomes (the
    arguments of :meth:`OnlineEllipses.radii`, one stream): the (L,) coverage of its ellipses
    and the largest share, over levels, of its finite scores whose ellipse is unbounded (0
    without a finite score)."""
    s = np.asarray(scores, float)
    radii = candidate.radii(s, t_predicted, t_revealed, np.zeros(len(s), np.int64), prior)
    seen = ~np.isnan(s)
    unbounded = float(np.isinf(radii[:, seen]).mean(axis=1).max()) if seen.any() else 0.0
    return ellipse_hits(s, radii), unbounded


def rank_held_out(table: Sequence[HeldOutStreamScore]) -> list[int]:
    """Indices of ``table``, best first: the candidates that never give an unbounded ellipse by
    their mean distance from nominal, then the others by their unbounded share and distance;
    ties keep the table's order."""
    return sorted(range(len(table)),
                  key=lambda i: (table[i].unbounded > 0, table[i].unbounded,
                                 table[i].distance_mean))


def _level_key(candidate: OnlineEllipses) -> tuple[float, ...]:
    """A candidate's levels as a hashable tuple of floats (a constructor may keep a list)."""
    return tuple(np.asarray(candidate.levels, float).ravel().tolist())


def select_on_held_out_streams(candidates: Sequence[OnlineEllipses], scores: np.ndarray,
                               t_predicted: np.ndarray, t_revealed: np.ndarray,
                               stream: np.ndarray) -> tuple[int, list[HeldOutStreamScore]]:
    """Choose among settings of the online ellipses (either kind: sliding-window conformal,
    :class:`AdaptiveConformal`, or scale tracking, :class:`blindspot.traj.scale_tracker.
    ScaleTracker`) on validation data alone.

    Each validation stream (a scene recording) is run as a new scene: its prior (the first
    window, or the quantiles a tracker starts from) is the scores of the *other* streams (the
    prior a test scene meets), and its
    ellipses are scored against its own outcomes (:func:`stream_coverage`). The choice is the
    first of :func:`rank_held_out`: the candidate with the smallest mean distance from nominal
    over streams and levels among those that never give an unbounded ellipse (one that says
    nothing); if every candidate does, the smallest largest unbounded share, then the
    distance. Ties go to the first candidate.

    Args:
        candidates: settings to choose from, all with the same ``levels``.
        scores, t_predicted, t_revealed, stream: validation scores and their times, as
            :meth:`AdaptiveConformal.radii` takes them; at least two streams.

    Returns:
        ``(index of the choice, one HeldOutStreamScore per candidate)``.

    Raises:
        ConformalError: no candidate (or not online ellipses), candidates with different
            levels (:func:`check_candidates`), fewer than two streams, or the errors of
            :meth:`AdaptiveConformal.radii`.
    """
    who = "select_on_held_out_streams"
    check_candidates(candidates, who)
    s = np.asarray(scores, float)
    group = np.asarray(stream)
    names = np.unique(group)
    if names.size < 2:
        raise ConformalError(f"{who}: expected at least two validation streams (each is held "
                             f"out of the others' prior), found {names.size}")
    levels = np.asarray(candidates[0].levels)
    tp, tr = np.asarray(t_predicted), np.asarray(t_revealed)
    table = []
    for c in candidates:
        per_stream = [stream_coverage(c, s[own], tp[own], tr[own], s[~own])
                      for own in (group == g for g in names)]
        table.append(HeldOutStreamScore.of([np.abs(hits - levels) for hits, _ in per_stream],
                                           [unb for _, unb in per_stream]))
    return rank_held_out(table)[0], table


def check_candidates(candidates, who: str, error: type[Exception] = ConformalError) -> None:
    """Raise ``error`` (prefixed with ``who``) unless ``candidates`` is a non-empty sequence of
    :class:`OnlineEllipses` with one set of levels: what a choice among settings needs."""
    if isinstance(candidates, (str, bytes)) or not isinstance(candidates, Sequence) \
            or not candidates or not all(isinstance(c, OnlineEllipses) for c in candidates):
        raise error(f"{who}: candidates: expected a non-empty sequence of online ellipses "
                    f"(AdaptiveConformal, ScaleTracker), found {candidates!r}")
    if len({_level_key(c) for c in candidates}) != 1:
        raise error(f"{who}: candidates: expected one set of levels, found "
                    f"{[c.levels for c in candidates]!r}")


def held_out_choice_coverage(candidates: Sequence[OnlineEllipses],
                             val: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
                             test: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
                             clusters: np.ndarray | None = None
                             ) -> tuple[dict[str, float | int | str | list[float]], OnlineEllipses]:
    """``(report, the online ellipses chosen)``: the setting chosen among ``candidates`` on the
    validation streams alone (:func:`select_on_held_out_streams`; the first candidate when
    there is one candidate or one validation stream), then scored on the test streams with
    every validation score as their prior (:meth:`OnlineEllipses.coverage`, the cluster
    bootstrap over ``clusters``). What the ETH/UCY folds and the simulated paths share.

    ``val`` and ``test`` are ``(scores (N, H), t_predicted (N,), t_revealed (N, H), stream
    (N,))``, as :meth:`OnlineEllipses.radii` takes them. The report is the coverage's keys,
    the chosen ``setting`` and, when there was a choice, ``online_val_distance``: its mean
    distance from nominal over the validation streams and levels.

    Raises:
        ConformalError: ``candidates`` not a non-empty sequence of :class:`OnlineEllipses`
            with one set of levels, ``val`` / ``test`` not 4-tuples, ``val`` not what
            :func:`check_stream_inputs` accepts, or the errors of the functions above.
    """
    who = "held_out_choice_coverage"
    check_candidates(candidates, who)
    for name, part in (("val", val), ("test", test)):
        if not isinstance(part, tuple) or len(part) != 4:
            size = f" of {len(part)} items" if isinstance(part, (tuple, list)) else ""
            raise ConformalError(f"{who}: {name}: expected a tuple (scores, t_predicted, "
                                 f"t_revealed, stream), found {type(part).__name__}{size}")
    check_stream_inputs(*val, val[0], who=f"{who}: val")    # also when there is no choice
    best, distance = 0, None
    if len(candidates) > 1 and np.unique(np.asarray(val[3])).size > 1:
        best, table = select_on_held_out_streams(candidates, *val)
        distance = table[best].distance_mean
    chosen = candidates[best]
    out = {**chosen.coverage(*test, val[0], clusters=clusters), **chosen.setting}
    if distance is not None:
        out["online_val_distance"] = distance
    return out, chosen


def ellipse_hits(scores: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """(L,) fraction of the finite scores (N, H) inside the radii (L, N, H)."""
    seen = ~np.isnan(scores)
    return ((scores[None] <= radii) & seen[None]).sum(axis=(1, 2)) / max(int(seen.sum()), 1)


def cluster_bootstrap_coverage(inside: np.ndarray, seen: np.ndarray, clusters: np.ndarray,
                               n_boot: int = 2000, seed: int = 0,
                               level: float = 0.95) -> np.ndarray:
    """(L, 2) percentile-bootstrap interval of each level's coverage, resampling clusters.

    Args:
        inside: (L, N, H) bool, a finite score inside its ellipse.
        seen: (N, H) bool, a finite score (one that counts).
        clusters: (N,) integer ids; each resample draws as many clusters as there are, with
            replacement, and pools their points (a cluster's points stay together).
        n_boot, seed: resamples and their seed; level: the interval's level.

    Raises:
        ConformalError: mismatched shapes, no cluster with a finite score, or n_boot < 1.
    """
    from blindspot.traj.bootstrap import resample_weights   # lazy: keeps this module light

    who = "cluster_bootstrap_coverage"
    ok = check_array(seen, "seen", ("N", "H"), error=ConformalError, who=who, dtype=bool)
    hit = check_array(inside, "inside", ("L", *ok.shape), error=ConformalError, who=who,
                      dtype=bool)
    ids = check_array(clusters, "clusters", ok.shape[:1], error=ConformalError, who=who,
                      dtype=int)
    if not (isinstance(n_boot, (int, np.integer)) and n_boot >= 1) or not ok.any():
        raise ConformalError(f"{who}: expected n_boot >= 1 and at least one finite score, "
                             f"found n_boot {n_boot!r}, {int(ok.sum())} finite scores")
    _, member = np.unique(ids, return_inverse=True)
    n_c = int(member.max()) + 1
    per_hits = np.stack([np.bincount(member, weights=(h & ok).sum(1), minlength=n_c)
                         for h in hit])                                    # (L, C)
    per_seen = np.bincount(member, weights=ok.sum(1), minlength=n_c)       # (C,)
    w = resample_weights(n_c, n_boot, seed)                                # (B, C)
    with np.errstate(invalid="ignore", divide="ignore"):
        cov = (w @ per_hits.T) / (w @ per_seen)[:, None]                   # (B, L)
    cov = cov[np.isfinite(cov).all(axis=1)]      # a resample that drew no finite score
    return np.quantile(cov, [(1 - level) / 2, (1 + level) / 2], axis=0).T
