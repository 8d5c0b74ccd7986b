"""Online scale tracking: a forecast's ellipses kept calibrated by moving one scale per level on
every revealed outcome, so that a short new scene reaches its nominal coverage.

The sliding-window conformal ellipses of :mod:`blindspot.traj.conformal` need a window of the
scene's own outcomes before they are the scene's: on a short recording (ETH/UCY eth's test scene,
181 predictions in bursts of a few pedestrians) most predictions are made with the validation
prior still in the window, and the 50 % ellipses of the direct LSTM cover 42 % there
(``reports/metrics/calibration_ethucy.json`` of 2026-12-06). This method keeps no window. It
tracks a quantile, as online gradient descent on the pinball loss does (the *quantile tracker*
of Angelopoulos, Candès & Tibshirani 2023, "Conformal PID control for time series prediction",
NeurIPS), on the log of the radius, with one scale shared by every future step:

* the radius of the ``level`` ellipse at step h for a prediction made at time t is
  ``q_h exp(theta_t + phi_{h,t})`` in d^2 units (the squared Mahalanobis distance under the
  forecast's own covariance, as :mod:`blindspot.traj.conformal` scores): ``q_h`` the
  validation scores' ``level`` quantile at step h (the prior: the shape over steps), ``theta``
  the scene's scale, ``phi_h`` an optional per-step correction;
* every outcome revealed by t, err = 1 if it fell outside the ellipse it was given, moves
  ``theta`` by ``eta (err - alpha)`` and ``phi_h`` of its own step by ``eta_step (err - alpha)``,
  ``alpha = 1 - level``: a miss widens by ``eta (1 - alpha)``, a hit narrows by ``eta alpha``.

Why it reaches nominal coverage: ``theta`` is ``eta`` times the running sum of ``err - alpha``, so
after N revealed outcomes the share outside is ``alpha + (theta_N - theta_0) / (eta N)``. A scale
far above the scene's quantile only narrows and one far below only widens, so ``theta`` stays
in a bounded range whenever the scene's quantile is neither 0 nor infinite, and the miss rate
approaches ``alpha`` as 1/N for any sequence of outcomes (Angelopoulos et al.'s Proposition 1,
there for one outcome per step; here several per time, each known at its own step's frame).
Sharing the scale over the future steps gives a scene of N predictions 12 N outcomes to learn
it from, the near steps' within a frame of each prediction. What no online method corrects
are the outcomes revealed after the stream's last prediction (ETH/UCY eth: 7 % of its
points), whose ellipses were drawn before any of them was known.

The interface is :class:`~blindspot.traj.conformal.AdaptiveConformal`'s (``levels``,
:meth:`radii`, :meth:`coverage`), so :func:`~blindspot.traj.conformal.select_on_held_out_streams`
chooses between both kinds of setting on validation scenes alone.

Causal by construction: a prediction's radii depend on outcomes revealed strictly by its own
time (tested by changing every later score). Shapes as :mod:`blindspot.traj.conformal`'s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from blindspot.traj.conformal import ConformalError, OnlineEllipses, check_stream_inputs

__all__ = ["ScaleTracker"]


@dataclass(frozen=True)
class ScaleTracker(OnlineEllipses):
    """Quantile tracking of one log-scale per level (module docstring).

    Attributes:
        levels: nominal coverages in (0, 1), distinct in whole percent (they name the metrics
            keys).
        eta: step of the shared log-scale per revealed outcome, > 0 (0.1: a miss of the 50 %
            ellipse widens every step's radius by 5 %).
        eta_step: step of each future step's own log-scale correction per outcome of that
            step, >= 0 (0 = off: the steps keep the prior's shape).
    """

    levels: tuple[float, ...]
    eta: float = 0.1
    eta_step: float = 0.0

    def __post_init__(self) -> None:
        self._check_levels()
        if not (np.isfinite(self.eta) and 0 < self.eta <= 1):
            raise ConformalError(f"eta: expected a step size in (0, 1], found {self.eta!r}")
        if not (np.isfinite(self.eta_step) and 0 <= self.eta_step <= 1):
            raise ConformalError(f"eta_step: expected a step size in [0, 1], found "
                                 f"{self.eta_step!r}")

    @property
    def setting(self) -> dict[str, float | str]:
        """What the metrics files record of the setting."""
        return {"online_method": "scale_tracker", "online_eta": self.eta,
                "online_eta_step": self.eta_step}

    def radii(self, scores: np.ndarray, t_predicted: np.ndarray, t_revealed: np.ndarray,
              stream: np.ndarray, prior: np.ndarray) -> np.ndarray:
        """Radii (L, N, H), d^2 units, of every prediction's ellipses; the arguments and errors
        of :meth:`blindspot.traj.conformal.AdaptiveConformal.radii` (``prior`` (M, H): every
        finite score of a step counts for its quantile), and a :class:`ConformalError` for a
        step of ``prior`` without a finite score. Every radius is finite and > 0 where the
        prior's quantile is."""
        s, tp, tr, group, prior = check_stream_inputs(scores, t_predicted, t_revealed, stream,
                                                      prior, who="ScaleTracker.radii")
        empty = np.isnan(prior).all(axis=0)
        if np.any(empty):
            raise ConformalError(f"ScaleTracker.radii: prior: expected a finite validation "
                                 f"score at every step, found none at steps "
                                 f"{np.flatnonzero(empty).tolist()}")
        lv = np.asarray(self.levels, float)
        q0 = np.stack([np.nanquantile(prior, x, axis=0, method="higher") for x in lv])  # (L, H)
        out = np.empty((lv.size, *s.shape))
        for g in np.unique(group):
            rows = np.flatnonzero(group == g)
            out[:, rows] = self._stream(s[rows], tp[rows], tr[rows], q0, 1.0 - lv)
        return out

    def _stream(self, s: np.ndarray, tp: np.ndarray, tr: np.ndarray, q0: np.ndarray,
                alpha: np.ndarray) -> np.ndarray:
        """Radii (L, n, H) of one stream: the outcomes in the order they are revealed, the
        predictions in the order they are made; between two prediction times, every outcome
        revealed in between moves the scales once (their sum)."""
        n, h = s.shape
        out = np.empty((alpha.size, n, h))
        i, k = np.nonzero(~np.isnan(s))                        # the outcomes that count
        by_time = np.argsort(tr[i, k], kind="stable")
        i, k = i[by_time], k[by_time]
        t_out = tr[i, k]
        times = np.unique(tp)
        order = np.argsort(tp, kind="stable")
        bounds = np.r_[np.searchsorted(tp[order], times, side="left"), n]
        upto = np.searchsorted(t_out, times, side="right")     # outcomes revealed by each time
        theta = np.zeros((alpha.size, 1))
        phi = np.zeros((alpha.size, h))
        done = 0
        for j, now in enumerate(upto):
            if now > done:
                ii, kk = i[done:now], k[done:now]
                g = (s[ii, kk][None] > out[:, ii, kk]) - alpha[:, None]            # (L, J)
                theta[:, 0] += self.eta * g.sum(axis=1)
                if self.eta_step:
                    phi += self.eta_step * np.stack([np.bincount(kk, w, minlength=h)
                                                     for w in g])
                done = now
            rows = order[bounds[j]:bounds[j + 1]]
            out[:, rows] = (q0 * np.exp(theta + phi))[:, None, :]
        return out
