"""Online scale tracking: a forecast's ellipses kept calibrated by one scale per level that every
revealed outcome moves, aiming a short new scene's ellipses at their nominal coverage with
radii of its own scale.

The sliding-window conformal ellipses of :mod:`blindspot.traj.conformal` need a window of the
scene's own outcomes before they are the scene's: on a short recording (ETH/UCY eth's test
scene, 181 predictions in bursts of a few pedestrians) most predictions are made with the
validation prior still in the window, and the 50 % ellipses of the direct LSTM cover 42 % there
(``reports/metrics/calibration_ethucy.json`` of 2026-12-05). This method keeps no window:

* the radius of the ``level`` ellipse at step h for a prediction made at time t is
  ``q_h exp(theta_t + c_t)`` in d^2 units (the squared Mahalanobis distance under the
  forecast's own covariance, as :mod:`blindspot.traj.conformal` scores), ``q_h`` the
  validation scores' ``level`` quantile at step h (the prior: the shape over the future
  steps), one ``theta`` and one ``c`` per level shared by every step;
* ``theta`` *tracks the scene's quantile*: online gradient descent on the pinball loss of
  the log score (the quantile tracker of Angelopoulos, Candès & Tibshirani 2023, "Conformal
  PID control for time series prediction", NeurIPS), one step ``eta (err - alpha)`` per
  revealed outcome in the order they are revealed, ``alpha = 1 - level``, ``err`` = 1 if the
  outcome lies outside the radius the tracker holds *when it is revealed*. Judged against the
  radius its prediction was given instead, every outcome of a burst revealed up to a horizon
  late would push the same way, and the scale would swing by orders of magnitude (a first
  version did, on ETH/UCY; ``tests/traj/test_scale_tracker.py``'s bursty and crowded streams
  check the radii stay near the scene's quantile);
* ``c`` *corrects the coverage the ellipses actually delivered*: ``kappa S / (N + n0)``,
  ``S`` the sum of ``err - alpha`` over the N revealed outcomes, each judged against the
  radius its prediction was given, ``n0`` outcomes at nominal before any (``prior_outcomes``):
  ``kappa`` times the running miss rate's distance from ``alpha`` (with ``n0`` nominal
  outcomes mixed in), bounded by ``kappa max(alpha, 1 - alpha)`` in log radius. Where the
  tracker's radii under-cover the scene's predictions the correction widens them, leaving a
  miss-rate error of ``c / kappa`` where it holds a correction c. A stronger integral (S
  divided by sqrt(N + n0), or not at all, as Angelopoulos et al.'s integral term) would
  drive that error to 0 but, with a crowd's outcomes revealed a horizon late, oscillated in
  a trial on the crowded stream of ``tests/traj/test_scale_tracker.py`` (many predictions per
  frame, each revealed 12 frames later) and was not taken;
* the radii are nested: each level is tracked on its own, and where a higher level's radius
  falls below a lower one's it takes the lower's (a 90 % ellipse holds the 50 % one); the
  correction of each level judges the nested radius its prediction was given.

No finite-sample guarantee is claimed: with a constant step the tracker keeps moving in a band
around the scene's quantile when the scene's scores are stationary, the correction leaves the
error above, and the outcomes revealed after a stream's last prediction are never learned
from. What it gives is measured: ``tests/traj/test_scale_tracker.py`` (a scene of another
scale, one that drifts, a crowded one whose radii must stay near its quantile) and
the ETH/UCY and simulated-path coverage of the stages. Sharing the scales over the H future
steps gives a scene of N predictions H N outcomes to learn from, the near steps' within a frame
of each prediction.

The interface is :class:`~blindspot.traj.conformal.OnlineEllipses`' (``levels``, :meth:`radii`,
``coverage``, ``setting``), so :func:`~blindspot.traj.conformal.select_on_held_out_streams`
chooses between both kinds of setting on validation scenes alone.

Causal by construction: a prediction's radii depend on outcomes revealed at or before its own
time (tested by changing every later score). Shapes as :mod:`blindspot.traj.conformal`'s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from blindspot.traj.conformal import ConformalError, OnlineEllipses, check_stream_inputs

__all__ = ["ScaleTracker"]


@dataclass(frozen=True)
class ScaleTracker(OnlineEllipses):
    """Quantile tracking of one log-scale per level with a bounded coverage correction (module
    docstring).

    Attributes:
        levels: nominal coverages in (0, 1), distinct in whole percent (they name the metrics
            keys).
        eta: the tracker's step in log radius per revealed outcome, in (0, 1] (0.05: a miss
            of the 50 % ellipse widens every step's radius by 2.5 %).
        kappa: the coverage correction's gain, >= 0 (0 = off): log radius per unit of the
            running miss rate's distance from ``1 - level`` (module docstring).
        prior_outcomes: outcomes at nominal coverage the running miss rate starts from, >= 0
            (the first few outcomes of a scene do not swing the correction).
    """

    levels: tuple[float, ...]
    eta: float = 0.05
    kappa: float = 10.0
    prior_outcomes: int = 50

    def __post_init__(self) -> None:
        self._check_levels()
        for name, lo, hi, lo_open in (("eta", 0.0, 1.0, True), ("kappa", 0.0, 100.0, False)):
            x = getattr(self, name)
            ok = isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool) \
                and np.isfinite(x) and (x > lo if lo_open else x >= lo) and x <= hi
            if not ok:
                bounds = f"{'(' if lo_open else '['}{lo:g}, {hi:g}]"
                raise ConformalError(f"{name}: expected a number in {bounds}, found {x!r}")
        k = self.prior_outcomes
        if isinstance(k, bool) or not (isinstance(k, (int, np.integer)) and k >= 0):
            raise ConformalError(f"prior_outcomes: expected an integer >= 0, found {k!r}")

    @property
    def setting(self) -> dict[str, float | int | str]:
        """What the metrics files record of the setting."""
        return {"online_method": "scale_tracker", "online_eta": self.eta,
                "online_kappa": self.kappa, "online_prior_outcomes": self.prior_outcomes}

    def radii(self, scores: np.ndarray, t_predicted: np.ndarray, t_revealed: np.ndarray,
              stream: np.ndarray, prior: np.ndarray) -> np.ndarray:
        """Radii (L, N, H), d^2 units, of every prediction's ellipses; the arguments and errors
        of :meth:`blindspot.traj.conformal.AdaptiveConformal.radii` (``prior`` (M, H): every
        finite score of a step counts for its quantile), and a :class:`ConformalError` for a
        step of ``prior`` without a finite score or with a 0 quantile (no scale to track).
        Every radius is finite and > 0, and no radius is below a lower level's (each level is
        tracked on its own; where a higher level's falls below, it takes the lower's, and its
        correction judges the radius given, :meth:`_stream`)."""
        s, tp, tr, group, prior = check_stream_inputs(scores, t_predicted, t_revealed, stream,
                                                      prior, who="ScaleTracker.radii")
        empty = np.isnan(prior).all(axis=0)
        if np.any(empty):
            raise ConformalError(f"ScaleTracker.radii: prior: expected a finite validation "
                                 f"score at every step, found none at steps "
                                 f"{np.flatnonzero(empty).tolist()}")
        lv = np.asarray(self.levels, float)
        q0 = np.stack([np.nanquantile(prior, x, axis=0, method="higher") for x in lv])  # (L, H)
        if not np.all(q0 > 0):
            raise ConformalError(f"ScaleTracker.radii: prior: expected a positive quantile at "
                                 f"every level and step, found 0 at "
                                 f"{np.argwhere(q0 <= 0).tolist()} (level, step)")
        out = np.empty((lv.size, *s.shape))
        for g in np.unique(group):
            rows = np.flatnonzero(group == g)
            out[:, rows] = self._stream(s[rows], tp[rows], tr[rows], q0, 1.0 - lv)
        return out

    def _stream(self, s: np.ndarray, tp: np.ndarray, tr: np.ndarray, q0: np.ndarray,
                alpha: np.ndarray) -> np.ndarray:
        """Radii (L, n, H) of one stream: the outcomes in the order they are revealed, the
        predictions in the order they are made; before each prediction time, every outcome
        revealed since moves the tracker one at a time and the correction's running sums. The
        radii given are nested across levels (a level's at least every lower level's), and the
        correction judges each outcome against the nested radius its prediction was given."""
        n, h = s.shape
        out = np.empty((alpha.size, n, h))
        i, k = np.nonzero(~np.isnan(s))                        # the outcomes that count
        by_time = np.argsort(tr[i, k], kind="stable")
        i, k = i[by_time], k[by_time]
        with np.errstate(divide="ignore"):                     # a 0 score: -inf, never a miss
            excess = np.log(s[i, k])[None] - np.log(q0[:, k])  # (L, J) log score over the prior's
        times = np.unique(tp)
        order = np.argsort(tp, kind="stable")
        bounds = np.r_[np.searchsorted(tp[order], times, side="left"), n]
        upto = np.searchsorted(tr[i, k], times, side="right")  # outcomes revealed by each time
        levels = range(alpha.size)
        theta = [0.0] * alpha.size
        a, eta = alpha.tolist(), float(self.eta)
        miss_sum = np.zeros(alpha.size)               # S: sum of (err - alpha), given radii
        up = np.argsort(-alpha, kind="stable")                 # levels, lowest coverage first
        done = 0
        for j, now in enumerate(upto):
            if now > done:
                rows = excess[:, done:now].tolist()
                for lv in levels:                              # the tracker, one outcome at a time
                    th, x, al = theta[lv], rows[lv], a[lv]
                    for e in x:
                        th += eta * ((e > th) - al)
                    theta[lv] = th
                given = out[:, i[done:now], k[done:now]]
                miss_sum += (s[i[done:now], k[done:now]][None] > given).sum(axis=1) \
                    - alpha * (now - done)
                done = now
            correction = self.kappa * miss_sum / (done + self.prior_outcomes) \
                if done + self.prior_outcomes else np.zeros(alpha.size)
            rows_now = order[bounds[j]:bounds[j + 1]]
            r = q0 * np.exp(np.asarray(theta) + correction)[:, None]          # (L, H)
            r[up] = np.maximum.accumulate(r[up], axis=0)                       # nested
            out[:, rows_now] = r[:, None, :]
        return out
