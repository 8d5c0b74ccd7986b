"""The multi-modal path predictor as the safety chain uses a predictor: one object with
``predict``, ``predict_distribution`` and ``predict_mixture``.

:class:`MultiModalPredictor` wraps a :class:`~blindspot.traj.seq2seq.Seq2SeqEnsemble` whose
members have a multi-modal head (``modes`` > 1, :mod:`blindspot.traj.seq2seq`). Its
``predict_mixture`` pools the members' hypotheses (each member's probabilities divided by the
number of members) into one :class:`~blindspot.traj.mixture.MixtureForecast`; its
``predict_distribution`` is that mixture's moment-matched Gaussian about its single prediction
(the mixture's mean, or its most probable hypothesis: ``point``), times an optional per-step
covariance scale fitted on validation data; ``predict`` is the single prediction. The collision
probability of a mixture is the probability-weighted sum over its hypotheses of each Gaussian
path's (:func:`blindspot.safety.risk.mixture_collision_risk`), which
:func:`blindspot.safety.predict.risk_table` uses for any predictor offering
``predict_mixture``.
"""

from __future__ import annotations

import numpy as np

from blindspot.traj.distribution import GaussianForecast
from blindspot.traj.mixture import MixtureForecast
from blindspot.traj.predictor import HistoryError

__all__ = ["MultiModalPredictor"]


class MultiModalPredictor:
    """A multi-modal ensemble as a probabilistic predictor.

    Args:
        ensemble: a :class:`~blindspot.traj.seq2seq.Seq2SeqEnsemble` of members with
            ``cfg.modes`` > 1 (load one with ``Seq2SeqEnsemble.load``).
        point: ``"mean"`` (the mixture's mean) or ``"mode"`` (its most probable hypothesis):
            what ``predict`` returns and ``predict_distribution`` centres on.
        step_scale: (H,) covariance multipliers of ``predict_distribution`` (fitted on
            validation data, :func:`blindspot.traj.distribution.fit_step_scale`), or None.
        name: label in reports.

    Raises:
        HistoryError: an ensemble without a multi-modal head (names ``modes``), an unknown
            ``point`` or a ``step_scale`` that is not finite and > 0.
    """

    def __init__(self, ensemble, *, point: str = "mean", step_scale: np.ndarray | None = None,
                 name: str = "mix") -> None:
        modes = getattr(getattr(ensemble, "cfg", None), "modes", None)
        if not isinstance(modes, int) or modes < 2 or not hasattr(ensemble, "members"):
            raise HistoryError(f"MultiModalPredictor: ensemble: expected a Seq2SeqEnsemble with "
                               f"cfg.modes > 1, found modes = {modes!r}")
        if point not in ("mean", "mode"):
            raise HistoryError(f"MultiModalPredictor: point: expected 'mean' or 'mode', "
                               f"found {point!r}")
        if step_scale is not None:
            step_scale = np.asarray(step_scale, dtype=float)
            if step_scale.ndim != 1 or not np.all(np.isfinite(step_scale) & (step_scale > 0)):
                raise HistoryError(f"MultiModalPredictor: step_scale: expected (H,) finite "
                                   f"values > 0, found {step_scale!r}")
        self.ensemble = ensemble
        self.point = point
        self.step_scale = step_scale
        self.name = name

    @property
    def uses_neighbours(self) -> bool:
        return bool(self.ensemble.uses_neighbours)

    @property
    def obs_len(self) -> int:
        return int(self.ensemble.cfg.obs_len)

    window = obs_len

    def predict_mixture(self, history: np.ndarray, horizon: int, *,
                        neighbours: np.ndarray | None = None) -> MixtureForecast:
        """(B, T, 2) history (the last ``obs_len`` rows observed) -> the pooled mixture of every
        member's hypotheses over ``horizon`` steps, world metres."""
        parts = [m.predict_mixture(history, horizon, neighbours=neighbours)
                 for m in self.ensemble.members]
        n = len(parts)
        return MixtureForecast(np.concatenate([p.weights for p in parts], axis=1) / n,
                               np.concatenate([p.means for p in parts], axis=1),
                               np.concatenate([p.covs for p in parts], axis=1))

    def predict_distribution(self, history: np.ndarray, horizon: int, *,
                             neighbours: np.ndarray | None = None) -> GaussianForecast:
        """The mixture's second moment about the single prediction, as a Gaussian per step
        (times ``step_scale`` when one was given)."""
        mix = self.predict_mixture(history, horizon, neighbours=neighbours)
        centre = mix.most_likely() if self.point == "mode" else mix.mean()
        fc = GaussianForecast(centre, mix.second_moment(centre))
        if self.step_scale is not None:
            if len(self.step_scale) < horizon:
                raise HistoryError(f"{self.name}.predict_distribution: step_scale holds "
                                   f"{len(self.step_scale)} steps, asked for {horizon}")
            fc = fc.scaled(self.step_scale[:horizon])
        return fc

    def predict(self, history: np.ndarray, horizon: int, *,
                neighbours: np.ndarray | None = None) -> np.ndarray:
        """(B, T, 2) -> (B, horizon, 2) the single prediction, metres."""
        mix = self.predict_mixture(history, horizon, neighbours=neighbours)
        return mix.most_likely() if self.point == "mode" else mix.mean()
