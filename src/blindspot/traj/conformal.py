"""Adaptive conformal ellipses: a forecast's uncertainty kept calibrated online, from the outcomes
the system has already seen.

A calibration fitted on validation data (:mod:`blindspot.traj.calibration`,
:func:`blindspot.traj.distribution.fit_scale_mixture`) is right for data like the validation
data. A new scene is not: on the ETH/UCY test folds the 50 % ellipses of a val-calibrated
forecast cover 16-68 % (``reports/metrics/calibration_ethucy.json``). A deployed predictor sees,
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
  inference under distribution shift", NeurIPS): each revealed outcome moves it by
  ``gamma (alpha - err)``, ``alpha = 1 - level``, ``err`` = 1 when that outcome fell outside
  the ellipse it was given. Over any stream the long-run miscoverage then tends to ``alpha``
  whatever the shift (their Proposition 4.1: the average error is within
  ``(max(a_1, 1 - a_1) + gamma) / (gamma T)`` of ``alpha`` after T outcomes).

The window starts filled with the validation scores (the prior: before the first revealed
outcome the ellipses are the validation data's conformal ones) and slides into the stream's own.
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
        levels: nominal coverages in (0, 1), e.g. (0.5, 0.9, 0.95).
        gamma: ACI step size (Gibbs & Candès 2021 use 0.005; 0 = plain sliding-window
            conformal prediction).
        window: revealed scores kept per step (the most recent ones), >= 1.
    """

    levels: tuple[float, ...] = (0.5, 0.9, 0.95)
    gamma: float = 0.005
    window: int = 300

    def __post_init__(self) -> None:
        lv = np.asarray(self.levels, float)
        if lv.ndim != 1 or lv.size == 0 or not np.all((lv > 0) & (lv < 1)):
            raise ConformalError(f"levels: expected nominal coverages in (0, 1), found "
                                 f"{self.levels!r}")
        if not (np.isfinite(self.gamma) and 0 <= self.gamma < 1):
            raise ConformalError(f"gamma: expected a step size in [0, 1), found {self.gamma!r}")
        if not (isinstance(self.window, (int, np.integer)) and self.window >= 1):
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
            prior: (M, H) validation scores (NaN allowed), the window's initial content.

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
            raise ConformalError("t_revealed: an outcome is known only after its prediction is "
                                 f"made (t_revealed > t_predicted); first bad row "
                                 f"{int(np.argmax(tr <= tp))}")
        alpha = 1.0 - np.asarray(self.levels, float)                      # (L,)
        out = np.empty((alpha.size, n, h))
        prior = prior[-self.window:]
        for g in np.unique(group):
            rows = np.flatnonzero(group == g)
            out[:, rows] = self._stream(s[rows], tp[rows], tr[rows], prior, alpha)
        return out

    def coverage(self, scores: np.ndarray, t_predicted: np.ndarray, t_revealed: np.ndarray,
                 stream: np.ndarray, prior: np.ndarray) -> dict[str, float]:
        """``{"online_coverage_50": .., ...}``, one key per level (percent, rounded): the share
        of the finite ``scores`` inside their :meth:`radii` (same arguments and errors)."""
        hits = ellipse_hits(scores, self.radii(scores, t_predicted, t_revealed, stream, prior))
        return {f"{KEY_PREFIX}{round(100 * lv)}": float(c) for lv, c in zip(self.levels, hits)}

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
            if now > n_seen:   # outcomes revealed since the last prediction time: ACI update
                j = by_reveal[n_seen:now]
                err = s[j][None] > out[:, j]                              # (L, J, H)
                seen = ~np.isnan(s[j])[None]
                a += self.gamma * (alpha[:, None] * seen.sum(1) - (err & seen).sum(1))
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
    value = np.where(rank >= m, np.inf, value)
    return np.where(q <= 0, 0.0, value)


def ellipse_hits(scores: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """(L,) fraction of the finite scores (N, H) inside the radii (L, N, H)."""
    seen = ~np.isnan(scores)
    return ((scores[None] <= radii) & seen[None]).sum(axis=(1, 2)) / max(int(seen.sum()), 1)
