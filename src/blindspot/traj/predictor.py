"""The one interface every path predictor offers (baselines, the LSTM, anything later).

A *history* is an array (B, T, 2) of (x, y) positions in metres at a fixed frame period, oldest
first; a NaN row means "no point in that frame" (missed detection, occlusion). A predictor
returns the next ``horizon`` positions of each of the B tracks, (B, horizon, 2), at the same
frame period.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from blindspot.arrays import check_array, check_count, check_number

__all__ = [
    "PathPredictor",
    "HistoryError",
    "check_history",
    "NextPointModel",
    "heading_frame",
    "to_frame",
    "from_frame",
    "heading_frame_pairs",
    "NextPointRollout",
    "HeadingFrameRollout",
    "MeanNextPoint",
    "ConstantVelocityTail",
]


@runtime_checkable
class PathPredictor(Protocol):
    """A model that extrapolates pedestrian tracks."""

    name: str

    def predict(self, history: np.ndarray, horizon: int) -> np.ndarray:
        """Predict the next ``horizon`` positions.

        Args:
            history: (B, T, 2) observed positions in metres, NaN rows = missing frames.
            horizon: number of future frames to predict (>= 1).

        Returns:
            (B, horizon, 2) predicted positions in metres.
        """
        ...


class HistoryError(ValueError):
    """A history array or horizon handed to a predictor is malformed."""


def check_history(history: np.ndarray, horizon: int, *, who: str = "predict") -> np.ndarray:
    """Validate a predictor's input and return it as a float64 (B, T, 2) array.

    A single track (T, 2) is not silently promoted: batching is explicit in this interface.
    NaN rows are missing frames; inf is refused.

    Raises:
        HistoryError: not real numbers (complex, object, strings, bools), wrong rank or last
            axis, an inf value, an empty time axis, or ``horizon`` not an integer >= 1.
    """
    h = check_array(history, "history", ("B", "T", 2), error=HistoryError, who=who,
                    allow_nan=True)
    if h.shape[1] < 1:
        raise HistoryError(f"{who}: history has no time steps (shape {h.shape})")
    check_count(horizon, "horizon", ge=1, error=HistoryError, who=who)
    return h


# --------------------------------------------------------------------------------------------
# Heading frame: rotation/translation-invariant use of a next-point model
# --------------------------------------------------------------------------------------------


@runtime_checkable
class NextPointModel(Protocol):
    """A one-step model: windows (B, window, 2) in metres -> next points (B, 2) in metres."""

    window: int

    def predict_next(self, windows: np.ndarray) -> np.ndarray: ...


_MIRROR = np.array([1.0, -1.0])


def heading_frame(windows: np.ndarray, speed_floor: float | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The frame of each window: origin at its last point, +x along its last step.

    Args:
        windows: (B, W, 2) points in metres, W >= 2, no NaN in the last two rows.
        speed_floor: if given (metres per frame, > 0), the frame is also scaled so that the
            last step has unit length, ``scale = max(|last step|, speed_floor)`` (the floor keeps
            a standing pedestrian's jitter from being blown up); None = metres.

    Returns:
        ``(origin (B, 2), rot (B, 2, 2))`` with ``rot`` mapping world offsets to frame
        coordinates (``q = rot @ (p - origin)``; with a speed floor ``rot`` includes the
        ``1 / scale`` factor). A window whose last step is zero (standing still) gets the
        world orientation.

    Raises:
        HistoryError: ``windows`` not real (B, W, 2) with W >= 2, or not finite in its last two
            rows.
    """
    windows = check_array(windows, "windows", ("B", "W", 2), error=HistoryError,
                          who="heading_frame", allow_nan=True)
    if windows.shape[1] < 2 or not np.isfinite(windows[:, -2:]).all():
        raise HistoryError(f"heading_frame: windows must be (B, W, 2) with W >= 2 and finite "
                           f"last two rows, found shape {windows.shape}")
    origin = windows[:, -1]
    step = windows[:, -1] - windows[:, -2]
    theta = np.arctan2(step[:, 1], step[:, 0])
    c, s = np.cos(theta), np.sin(theta)
    rot = np.stack([np.stack([c, s], axis=-1), np.stack([-s, c], axis=-1)], axis=-2)
    if speed_floor is not None:
        check_number(speed_floor, "speed_floor", gt=0.0, unit="m (per frame)",
                     who="heading_frame")
        scale = np.maximum(np.hypot(step[:, 0], step[:, 1]), speed_floor)
        rot = rot / scale[:, None, None]
    return origin, rot


def _frame_args(points, origin, rot, who: str) -> tuple[np.ndarray, ...]:
    """(points (B, ..., 2), origin (B, 2), rot (B, 2, 2)) checked, sharing B."""
    points = check_array(points, "points", ("...", 2), error=HistoryError, who=who,
                         allow_nan=True)
    origin = check_array(origin, "origin", ("B", 2), error=HistoryError, who=who)
    rot = check_array(rot, "rot", ("B", 2, 2), error=HistoryError, who=who)
    if points.ndim < 2 or not points.shape[0] == origin.shape[0] == rot.shape[0]:
        raise HistoryError(f"{who}: points (B, ..., 2), origin (B, 2) and rot (B, 2, 2) must "
                           f"share B, found shapes {points.shape}, {origin.shape}, {rot.shape}")
    return points, origin, rot


def to_frame(points: np.ndarray, origin: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """World points (B, ..., 2) -> frame coordinates ``rot @ (p - origin)`` per batch row.

    Raises:
        HistoryError: arrays not real, of the wrong shapes or B, or inf (NaN points propagate).
    """
    points, origin, rot = _frame_args(points, origin, rot, "to_frame")
    flat = points.reshape(points.shape[0], -1, 2) - origin[:, None, :]
    return np.einsum("bij,bnj->bni", rot, flat).reshape(points.shape)


def from_frame(points: np.ndarray, origin: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """Frame coordinates (B, ..., 2) -> world points ``rot^-1 q + origin``.

    Raises:
        HistoryError: as :func:`to_frame`.
    """
    points, origin, rot = _frame_args(points, origin, rot, "from_frame")
    flat = points.reshape(points.shape[0], -1, 2)
    inv = np.linalg.inv(rot)
    return (np.einsum("bij,bnj->bni", inv, flat) + origin[:, None, :]).reshape(points.shape)


def heading_frame_pairs(sequences: np.ndarray, *, residual: bool = True, mirror: bool = True,
                        speed_floor: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Training pairs for a next-point model used through :class:`HeadingFrameRollout`.

    Args:
        sequences: (N, W + 1, 2) stretches of W inputs and the next point, metres, no NaN.
        residual: make the target the deviation from constant velocity (next point minus the
            last point carried one more step); the model then learns corrections to CVM.
        mirror: also add every pair reflected across the heading axis (walking has no
            preferred side), doubling N.

    Returns:
        ``(x (N', W, 2), y (N', 2))`` in each window's heading frame (``N' = 2N`` with mirror).
    """
    seq = check_array(sequences, "sequences", ("N", "W + 1", 2), error=HistoryError,
                      who="heading_frame_pairs")
    if seq.shape[1] < 3:
        raise HistoryError(f"heading_frame_pairs: sequences must be (N, W + 1, 2) with W >= 2, "
                           f"found shape {seq.shape}")
    origin, rot = heading_frame(seq[:, :-1], speed_floor)
    framed = to_frame(seq, origin, rot)
    if mirror:
        framed = np.concatenate([framed, framed * _MIRROR])
    x, y = framed[:, :-1], framed[:, -1]
    if residual:
        y = y - (x[:, -1] - x[:, -2])
    return x, y


class NextPointRollout:
    """Autoregressive rollout of a next-point model in world coordinates (predict, append,
    slide), batched over tracks.

    Attributes:
        model: a :class:`NextPointModel`. name: label used in reports.
    """

    def __init__(self, model: NextPointModel, *, name: str = "lstm") -> None:
        self.model = model
        self.name = name

    @property
    def window(self) -> int:
        return int(self.model.window)

    def step(self, windows: np.ndarray) -> np.ndarray:
        """Next points (B, 2) in metres for windows (B, window, 2)."""
        return np.asarray(self.model.predict_next(windows), dtype=float)

    def predict(self, history: np.ndarray, horizon: int) -> np.ndarray:
        """Roll out ``horizon`` steps from the last ``window`` points of each history.

        Args:
            history: (B, T, 2) in metres, T >= window; the last ``window`` rows must be
                observed (fill gaps first, e.g. with ``KalmanCV.smooth``).
            horizon: number of future points.

        Returns:
            (B, horizon, 2) predicted points in metres.
        """
        h = check_history(history, horizon, who=f"{self.name}.predict")
        W = self.window
        if h.shape[1] < W:
            raise HistoryError(f"{self.name}.predict: needs at least window={W} points, found "
                               f"T={h.shape[1]}")
        x = h[:, -W:]
        if not np.isfinite(x).all():
            raise HistoryError(f"{self.name}.predict: the last {W} history rows contain NaN; "
                               "fill gaps first (e.g. KalmanCV.smooth)")
        out = np.empty((h.shape[0], horizon, 2))
        for k in range(horizon):          # one batched model call (two if symmetric) per step
            out[:, k] = self.step(x)
            x = np.concatenate([x[:, 1:], out[:, k, None]], axis=1)
        return out




class HeadingFrameRollout(NextPointRollout):
    """Autoregressive rollout of a next-point model in each window's heading frame.

    At every step the current window is moved to its heading frame (:func:`heading_frame`),
    the model predicts the next point there, and the point is mapped back to the world and
    appended. This makes the prediction invariant to where the pedestrian is and which way they
    walk. With ``residual`` the model's output is a correction to constant velocity (train it on
    :func:`heading_frame_pairs` with the same flag); with ``symmetric`` the prediction is
    averaged with that of the mirrored window (exact left/right symmetry).

    Attributes:
        model: a :class:`NextPointModel` (e.g. ``blindspot.traj.lstm.LSTMPredictor``).
        residual, symmetric: see above.
        speed_floor: also scale each window by its last step (None = metres; see
            :func:`heading_frame`); train with the same value.
        name: label used in reports.
    """

    def __init__(self, model: NextPointModel, *, residual: bool = True, symmetric: bool = True,
                 speed_floor: float | None = None, name: str = "lstm") -> None:
        super().__init__(model, name=name)
        self.speed_floor = speed_floor
        self.residual = residual
        self.symmetric = symmetric

    def step(self, windows: np.ndarray) -> np.ndarray:
        """Next points (B, 2) in metres for windows (B, window, 2)."""
        origin, rot = heading_frame(windows, self.speed_floor)
        x = to_frame(windows, origin, rot)
        nxt = np.asarray(self.model.predict_next(x), dtype=float)
        if self.symmetric:
            nxt = 0.5 * (nxt + np.asarray(self.model.predict_next(x * _MIRROR), float) * _MIRROR)
        if self.residual:
            nxt = nxt + (x[:, -1] - x[:, -2])
        return from_frame(nxt[:, None, :], origin, rot)[:, 0]


class MeanNextPoint:
    """The mean of several next-point models (e.g. the same LSTM trained with different seeds).

    Averaging independently trained models lowers the variance of each step, which matters in
    an autoregressive rollout where step errors feed back.
    """

    def __init__(self, models: list[NextPointModel]) -> None:
        if not models:
            raise ValueError("MeanNextPoint: expected at least one model, found none")
        windows = {int(m.window) for m in models}
        if len(windows) != 1:
            raise ValueError(f"MeanNextPoint: models disagree on the window length: {windows}")
        self.models = list(models)
        self.window = windows.pop()

    def predict_next(self, windows: np.ndarray) -> np.ndarray:
        """(B, window, 2) -> (B, 2): mean of the models' next points."""
        return np.mean([np.asarray(m.predict_next(windows), float) for m in self.models], axis=0)


class ConstantVelocityTail:
    """A fixed-horizon predictor (a direct multi-step model emits ``max_horizon`` steps and no
    more) carried past its last step at the velocity of that step.

    Needed where a forecast has to reach further than the model was trained to: a track whose
    last point was seen ``lead`` frames before the prediction time is forecast ``lead + horizon``
    steps from that point (:func:`blindspot.traj.forecast.forecast_tracks`). Steps up to
    ``max_horizon`` are the base model's own; step ``max_horizon + k`` is its last point plus
    ``k`` times its last step, ``p_H + k (p_H - p_{H-1})`` (constant velocity, as
    :class:`blindspot.traj.baselines.ConstantVelocity` extrapolates the observed track).
    ``predict_distribution`` is the base model's, unchanged (it refuses steps past its horizon:
    no distribution is invented for them).

    Args:
        base: a :class:`PathPredictor` that emits at most ``max_horizon`` steps.
        max_horizon: the base model's horizon, >= 2 frames.
    Raises ValueError: ``max_horizon`` < 2.
    """

    def __init__(self, base, max_horizon: int) -> None:
        # >= 2 frames: a last step to carry on
        self.max_horizon = check_count(max_horizon, "max_horizon", ge=2,
                                       who="ConstantVelocityTail")
        self.base = base
        self.name = getattr(base, "name", type(base).__name__)

    @property
    def window(self):
        """The base model's history length in frames (None when it has none)."""
        return getattr(self.base, "window", None)

    def predict(self, history: np.ndarray, horizon: int) -> np.ndarray:
        """(B, T, 2) history -> (B, horizon, 2) metres; any ``horizon`` >= 1. Raises what the
        base model raises for a malformed history (e.g. HistoryError); HistoryError naming
        ``horizon`` when it is not an integer >= 1."""
        horizon = check_count(horizon, "horizon", ge=1, error=HistoryError,
                              who=f"{self.name}.predict")
        n = min(horizon, self.max_horizon)
        pred = np.asarray(self.base.predict(history, n), float)
        if horizon <= n:
            return pred
        step = pred[:, -1] - pred[:, -2]                                        # (B, 2)
        k = np.arange(1, int(horizon) - n + 1, dtype=float)
        return np.concatenate([pred, pred[:, -1:] + k[None, :, None] * step[:, None, :]], axis=1)

    def predict_distribution(self, history: np.ndarray, horizon: int, **options):
        """The base model's Gaussian forecast, unchanged (a
        :class:`blindspot.traj.distribution.GaussianForecast`: mean (B, horizon, 2) m, cov
        (B, horizon, 2, 2) m^2); ``horizon`` at most ``max_horizon``, else the base model's
        error."""
        return self.base.predict_distribution(history, horizon, **options)
