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
  predictions whose whole future was revealed by t (split conformal prediction on a sliding
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
the stream's own.
Causal by construction: a prediction's radii depend on scores revealed strictly by its own time
(tested by changing every later score). One stream per scene recording (``stream``): outcomes
are not shared between recordings.

Shapes: scores (N predictions, H steps); times (N,) in any one unit (ETH/UCY: frame rows);
radii (L levels, N, H) in d^2 units (compare with ``d^2`` of the same forecast).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from blindspot.arrays import check_array

__all__ = ["AdaptiveConformal", "ConformalError", "ellipse_hits"]

#: prefix of the adaptive ellipses' coverage keys in the metrics files
#: (``online_coverage_50`` beside the val calibration's ``coverage_50``)
KEY_PREFIX = "online_coverage_"


class ConformalError(ValueError):
    """Scores, times or settings of :class:`AdaptiveConformal` of the wrong shape or value."""


@dataclass(frozen=True)
class AdaptiveConformal:
    """Sliding-window conformal ellipses with ACI level updates (module docstring).

    Attributes:
        levels: nominal coverages in (0, 1), e.g. (0.5, 0.9, 0.95), distinct in whole percent
            (they name the metrics keys).
        gamma: ACI step size per prediction time (Gibbs & Candès 2021 use 0.005; 0 = plain
            sliding-window conformal prediction).
        window: revealed predictions whose scores are kept (the most recent ones), >= 1; a
            step without truth (NaN) in some of them has fewer scores.
    """

    levels: tuple[float, ...]
    gamma: float = 0.005
    window: int = 100

    def __post_init__(self) -> None:
        lv = np.asarray(self.levels, float)
        if lv.ndim != 1 or lv.size == 0 or not np.all((lv > 0) & (lv < 1)) \
                or len({round(100 * x) for x in lv}) != lv.size:
            raise ConformalError(f"levels: expected nominal coverages in (0, 1), distinct in "
                                 f"whole percent, found {self.levels!r}")
        if not (np.isfinite(self.gamma) and 0 <= self.gamma < 1):
            raise ConformalError(f"gamma: expected a step size in [0, 1), found {self.gamma!r}")
        if isinstance(self.window, bool) or not (isinstance(self.window, (int, np.integer))
                                                 and self.window >= 1):
            raise ConformalError(f"window: expected an integer >= 1, found {self.window!r}")

    def radii(self, scores: np.ndarray, t_predicted: np.ndarray, t_revealed: np.ndarray,
              stream: np.ndarray, prior: np.ndarray) -> np.ndarray:
        """Radii (L, N, H), d^2 units, of every prediction's ellipses.

        Args:
            scores: (N, H) d^2 of each prediction's true positions (NaN: a step without truth;
                it neither counts nor moves a level).
            t_predicted: (N,) time each prediction is made (its last observation).
            t_revealed: (N,) time its whole future is known (its last future point), after
                ``t_predicted``; an outcome is used by the predictions made at or after it.
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
        who = "AdaptiveConformal.radii"
        s = check_array(scores, "scores", ("N", "H"), error=ConformalError, who=who,
                        allow_nan=True)
        n, h = s.shape
        prior = check_array(prior, "prior", ("M", h), error=ConformalError, who=who,
                            allow_nan=True)
        tp = check_array(t_predicted, "t_predicted", (n,), error=ConformalError, who=who)
        tr = check_array(t_revealed, "t_revealed", (n,), error=ConformalError, who=who)
        group = check_array(stream, "stream", (n,), error=ConformalError, who=who, dtype=int)
        if np.any(tr <= tp):
            i = int(np.argmax(tr <= tp))
            raise ConformalError(f"{who}: t_revealed must be after t_predicted (an outcome is "
                                 f"known only after its prediction is made); row {i} has "
                                 f"t_predicted {tp[i]:g}, t_revealed {tr[i]:g}")
        alpha = 1.0 - np.asarray(self.levels, float)                      # (L,)
        out = np.empty((alpha.size, n, h))
        if prior.shape[0] > self.window:   # evenly spaced through the validation set
            prior = prior[np.arange(self.window) * prior.shape[0] // self.window]
        for g in np.unique(group):
            rows = np.flatnonzero(group == g)
            out[:, rows] = self._stream(s[rows], tp[rows], tr[rows], prior, alpha)
        return out

    def coverage(self, scores: np.ndarray, t_predicted: np.ndarray, t_revealed: np.ndarray,
                 stream: np.ndarray, prior: np.ndarray) -> dict[str, float]:
        """Coverage and size of the :meth:`radii` (same arguments and errors), for the metrics
        files: ``online_coverage_<p>`` (p = the level in whole percent): the share of the
        finite ``scores`` inside their ellipse; ``online_unbounded_<p>``: the share of those
        points whose ellipse is unbounded (+inf: a coverage bought that way says nothing);
        ``online_radius_<p>``: the median finite radius, in standard deviations of the
        forecast's own covariance (sqrt of d^2; a Gaussian's 90 % ellipse: 2.15)."""
        radii = self.radii(scores, t_predicted, t_revealed, stream, prior)
        hits = ellipse_hits(scores, radii)
        seen = ~np.isnan(np.asarray(scores, float))
        out: dict[str, float] = {}
        for lv, c, r in zip(self.levels, hits, radii):
            p = round(100 * lv)
            finite = r[seen & np.isfinite(r)]
            out[f"{KEY_PREFIX}{p}"] = float(c)
            out[f"online_unbounded_{p}"] = float(np.isinf(r[seen]).mean()) if seen.any() else 0.0
            out[f"online_radius_{p}"] = float(np.sqrt(np.median(finite))) if finite.size \
                else float("inf")
        return out

    def _stream(self, s: np.ndarray, tp: np.ndarray, tr: np.ndarray, prior: np.ndarray,
                alpha: np.ndarray) -> np.ndarray:
        """Radii (L, n, H) of one stream (module docstring)."""
        n, h = s.shape
        out = np.empty((alpha.size, n, h))
        by_reveal = np.argsort(tr, kind="stable")
        pool = np.concatenate([prior, s[by_reveal]])          # window content, in reveal order
        a = np.broadcast_to(alpha[:, None], (alpha.size, h)).copy()   # (L, H) ACI levels
        times = np.unique(tp)
        order = np.argsort(tp, kind="stable")
        bounds = np.r_[np.searchsorted(tp[order], times, side="left"), n]
        n_seen = 0                                                       # outcomes revealed
        for k, t in enumerate(times):
            now = int(np.searchsorted(tr[by_reveal], t, side="right"))
            if now > n_seen:   # outcomes revealed since the last prediction time: one ACI step
                j = by_reveal[n_seen:now]
                seen = ~np.isnan(s[j])                                    # (J, H)
                err = (s[j][None] > out[:, j]) & seen[None]               # (L, J, H)
                n_ok = seen.sum(0)                                        # (H,)
                share = err.sum(1) / np.maximum(n_ok, 1)                  # (L, H)
                a += np.where(n_ok > 0, self.gamma * (alpha[:, None] - share), 0.0)
                n_seen = now
            hi = prior.shape[0] + n_seen
            recent = pool[max(0, hi - self.window):hi]                    # (M, H)
            rows = order[bounds[k]:bounds[k + 1]]
            out[:, rows] = _conformal_quantile(recent, 1.0 - a)[:, None, :]
        return out


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


def ellipse_hits(scores: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """(L,) fraction of the finite scores (N, H) inside the radii (L, N, H)."""
    seen = ~np.isnan(scores)
    return ((scores[None] <= radii) & seen[None]).sum(axis=(1, 2)) / max(int(seen.sum()), 1)
