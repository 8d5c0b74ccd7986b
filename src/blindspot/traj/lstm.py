"""Many-to-one LSTM regression of the next point from a window of points (paper Table 1).

Model: ``nn.LSTM`` over the W points of a window (input size 2), its last hidden state into an
MLP head ``Linear(hidden, head_hidden) -> ReLU -> Linear(head_hidden, 2)``. PyTorch's LSTM cell
has fixed tanh/sigmoid gates, so the paper's ReLU activation (Table 1) lives in the head; this is
the place Keras users usually mean by "activation" of a regression LSTM's dense layer.

Normalisation (:class:`NormStats`, fitted on the training windows only):

- ``translate=True``: each window is expressed relative to its own last point, so the network
  never sees where the pedestrian is, only how they moved (translation invariance). With
  ``translate=False`` a fitted mean position is subtracted instead.
- ``normalise=True``: inputs are divided by a fitted scalar RMS (one scale for x and y, so
  directions are not distorted) and the target by its own fitted RMS.
- ``target="displacement"``: the network predicts ``next - last point``; ``"absolute"``: it
  predicts the next point in the same frame as its inputs. When translating, that frame is
  centred on the last point, so the two targets coincide; they differ only with
  ``translate=False`` (absolute = next point minus the fitted mean position).

:class:`LSTMPredictor` wraps a model (or a seed ensemble of models) and its statistics, predicts
one step from windows and rolls out several steps (predict, append, slide) for a whole batch at
once.
"""

from __future__ import annotations

import copy
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from blindspot.io import atomic_path
from blindspot.arrays import check_array, check_count
from blindspot.traj.config import LSTMConfig
from blindspot.traj.predictor import HistoryError
from blindspot.traj.windows import interpolate_gaps

_FORMAT = "blindspot.lstm/1"
_ENSEMBLE_FORMAT = "blindspot.lstm-ensemble/1"
_ACTIVATIONS = {"relu": nn.ReLU, "tanh": nn.Tanh, "identity": nn.Identity}
# Rows per network call in inference: a batch runs as blocks of this many rows (whatever the
# number of worker threads, so the result does not depend on it). Measured on the scene
# ensemble (5 networks, 50-point windows, one thread): 4,096 rows in one call 2.38 s, in blocks
# of 512 / 256 / 128 / 64 rows 1.62 / 1.62 / 1.60 / 1.76 s (the blocks stay in cache).
BLOCK_ROWS = 128


@dataclass(frozen=True)
class NormStats:
    """How windows become network inputs and network outputs become points.

    With ``o`` the origin (the window's last point when ``translate``, else ``in_offset``)::

        u = (x - o) / in_scale                      network input, (B, W, 2)
        displacement: next = x[:, -1] + r * out_scale
        absolute:     next = o + r * out_scale      r = network output, (B, 2)
    """

    translate: bool
    target: str
    in_offset: tuple[float, float] = (0.0, 0.0)
    in_scale: float = 1.0
    out_scale: float = 1.0

    @classmethod
    def fit(cls, x: np.ndarray, y: np.ndarray, cfg: LSTMConfig) -> NormStats:
        """Fit on training windows x (N, W, 2) and targets y (N, 2) (float64 accumulation).
        Raises HistoryError when they are not finite real arrays of those shapes."""
        x = check_array(x, "x", ("N", "W", 2), error=HistoryError, who="NormStats.fit")
        y = check_array(y, "y", (len(x), 2), error=HistoryError, who="NormStats.fit")
        if not cfg.normalise:
            return cls(cfg.translate, cfg.target)
        if cfg.translate:
            offset = np.zeros(2)
            origin = x[:, -1:, :]
        else:
            offset = x.reshape(-1, 2).mean(axis=0)
            origin = offset[None, None, :]
        in_scale = float(np.sqrt(np.mean((x - origin) ** 2)))
        tgt = y - (x[:, -1] if cfg.target == "displacement" else origin[:, 0])
        out_scale = float(np.sqrt(np.mean(tgt**2)))
        # a degenerate training set (all windows constant) keeps unit scale rather than dividing by 0
        return cls(
            cfg.translate,
            cfg.target,
            (float(offset[0]), float(offset[1])),
            in_scale if in_scale > 0 else 1.0,
            out_scale if out_scale > 0 else 1.0,
        )

    def _origin(self, x: torch.Tensor) -> torch.Tensor:
        if self.translate:
            return x[:, -1, :]
        return torch.tensor(self.in_offset, dtype=x.dtype).expand(x.shape[0], 2)

    def encode(self, x: torch.Tensor) -> torch.Tensor:
        """(B, W, 2) windows in metres -> (B, W, 2) network input."""
        return (x - self._origin(x)[:, None, :]) / self.in_scale

    def encode_target(self, x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        """(B, 2) next points in metres -> (B, 2) training target in network units."""
        base = x[:, -1, :] if self.target == "displacement" else self._origin(x)
        return (y - base) / self.out_scale

    def decode(self, x: torch.Tensor, r: torch.Tensor) -> torch.Tensor:
        """(B, 2) network output -> (B, 2) next points in metres."""
        base = x[:, -1, :] if self.target == "displacement" else self._origin(x)
        return base + r * self.out_scale


class LSTMRegressor(nn.Module):
    """Many-to-one LSTM: (B, W, 2) normalised window -> (B, 2) normalised next-point target."""

    def __init__(self, cfg: LSTMConfig) -> None:
        super().__init__()
        self.cfg = cfg
        self.lstm = nn.LSTM(
            input_size=2,
            hidden_size=cfg.hidden_size,
            num_layers=cfg.num_layers,
            batch_first=True,
            dropout=cfg.dropout if cfg.num_layers > 1 else 0.0,
        )
        if cfg.head_hidden > 0:
            self.head = nn.Sequential(
                nn.Linear(cfg.hidden_size, cfg.head_hidden),
                _ACTIVATIONS[cfg.head_activation](),
                nn.Linear(cfg.head_hidden, 2),
            )
        else:
            self.head = nn.Linear(cfg.hidden_size, 2)

    def forward(self, u: torch.Tensor) -> torch.Tensor:
        if u.ndim != 3 or u.shape[-1] != 2:
            raise ValueError(f"LSTMRegressor input: expected shape (B, W, 2), found {tuple(u.shape)}")
        out, _ = self.lstm(u)
        return self.head(out[:, -1, :])


def _as_windows(arr: Any, window: int, what: str) -> torch.Tensor:
    """(B, window, 2) finite real windows as float64 (positions far from the origin keep their
    centimetres: :class:`NormStats` translates before the network's float32); HistoryError
    naming ``what`` otherwise."""
    arr = check_array(arr, what, ("B", window, 2), error=HistoryError, who="lstm")
    return torch.from_numpy(np.ascontiguousarray(arr, dtype=np.float64))


def fill_history(history: np.ndarray) -> np.ndarray:
    """Make a (B, T, 2) history NaN-free for rollout.

    Interior missing rows are linearly interpolated (:func:`interpolate_gaps`); missing rows before
    a track's first observed point take that point's value (they only affect the oldest inputs).
    A track that ends in missing rows, or has none observed, raises ValueError: extrapolating is
    the model's job, so trim the history to its last observed point and roll out from there.
    """
    filled = interpolate_gaps(history)
    valid = np.isfinite(filled).all(axis=-1)  # (B, T)
    if not valid.all():
        empty = ~valid.any(axis=1)
        if empty.any():
            raise ValueError(f"history: track(s) {np.flatnonzero(empty)[:5].tolist()} have no observed point")
        trailing = ~valid[:, -1]
        if trailing.any():
            b = int(np.flatnonzero(trailing)[0])
            n_missing = int(valid.shape[1] - 1 - np.flatnonzero(valid[b])[-1])
            raise ValueError(
                f"history: track {b} ends with {n_missing} missing (NaN) rows; trim it to its last observed point "
                "and roll out from there"
            )
        first = valid.argmax(axis=1)  # first observed index per track
        lead = ~valid  # only leading gaps remain
        filled[lead] = np.broadcast_to(filled[np.arange(len(first)), first][:, None, :], filled.shape)[lead]
    return filled


class LSTMPredictor:
    """Trained :class:`LSTMRegressor` (s) with their normalisation, usable as a PathPredictor.

    One network, or an ensemble of networks of one config trained with different seeds (see
    :func:`blindspot.traj.train.train_ensemble`): every step predicts the mean of the members'
    next points, so the rollout feeds back the ensemble's point, not each member's own. An
    ensemble lowers the variance a single training run carries (weight init, batch order, the
    last bits of the CPU's kernels), which three test walks otherwise turn into large swings of
    the scene numbers (issue 10; Lakshminarayanan et al. 2017 for deep ensembles).

    Attributes:
        name: "lstm".
        config: the members' :class:`LSTMConfig`.
        model, stats: the first member's network (eval mode) and :class:`NormStats`.
        members: all ``(model, stats)`` pairs, at least one.
        workers: threads inference splits a batch over (:meth:`with_workers`; 1 by default).
    """

    name = "lstm"
    workers = 1

    def __init__(self, model: LSTMRegressor, stats: NormStats,
                 more: list[tuple[LSTMRegressor, NormStats]] | None = None) -> None:
        self.members = [(model.eval(), stats)] + [(m.eval(), st) for m, st in (more or [])]
        configs = {asdict(m.cfg).__repr__() for m, _ in self.members}
        if len(configs) != 1:
            raise ValueError(f"LSTMPredictor: ensemble members must share one model config, "
                             f"found {len(configs)} different ones")
        self.model, self.stats = self.members[0]
        self.config: LSTMConfig = model.cfg

    @classmethod
    def ensemble(cls, predictors: list[LSTMPredictor]) -> LSTMPredictor:
        """One predictor averaging the members of ``predictors`` (each one or more networks)."""
        if not predictors:
            raise ValueError("LSTMPredictor.ensemble: expected at least one predictor, found none")
        pairs = [pair for p in predictors for pair in p.members]
        return cls(*pairs[0], more=pairs[1:]).with_workers(max(p.workers for p in predictors))

    @property
    def window(self) -> int:
        return self.config.window

    @property
    def n_members(self) -> int:
        return len(self.members)

    def member(self, i: int) -> LSTMPredictor:
        """The ``i``-th network alone, as a predictor (for per-seed scores), with the same
        ``workers``."""
        return LSTMPredictor(*self.members[i]).with_workers(self.workers)

    def with_workers(self, workers: int) -> LSTMPredictor:
        """The same networks, running a batch's blocks of :data:`BLOCK_ROWS` rows on
        ``workers`` threads (torch releases the GIL inside its kernels). The blocks are the same
        for any ``workers``, and :meth:`predict` runs every block single-threaded, so the
        result has the same bits for every ``workers``. ValueError for ``workers`` < 1."""
        workers = check_count(workers, "workers", ge=1, who="LSTMPredictor.with_workers")
        out = copy.copy(self)
        out.workers = workers
        return out

    def _rows(self, x: torch.Tensor) -> torch.Tensor:
        # translate (encode) and put back (decode) in float64, the network alone in float32:
        # a float32 position 5e6 m from the origin (UTM) is only good to 0.5 m
        x = x.double()
        with torch.inference_mode():
            out = [st.decode(x, m(st.encode(x).float()).double()) for m, st in self.members]
            return out[0] if len(out) == 1 else torch.stack(out).mean(dim=0)

    def step(self, x: torch.Tensor) -> torch.Tensor:
        """(B, W, 2) windows in metres -> (B, 2) float64 next points in metres (torch, no
        grad); the mean over the members. Windows are translated in float64 before the
        network's float32 (:class:`NormStats`), so a walk far from the origin (UTM coordinates)
        is predicted as the same walk near it. The rows run as blocks of :data:`BLOCK_ROWS` (a
        Python loop over blocks, not rows), on ``workers`` threads when there are several
        blocks."""
        blocks = torch.split(x, BLOCK_ROWS)
        if len(blocks) <= 1:
            return self._rows(x)
        if self.workers <= 1:
            return torch.cat([self._rows(b) for b in blocks])
        with ThreadPoolExecutor(min(self.workers, len(blocks))) as pool:
            return torch.cat(list(pool.map(self._rows, blocks)))

    @staticmethod
    @contextmanager
    def _single_threaded(n_rows: int):
        """torch's own thread pool at one thread while a batch of several blocks runs (the same
        arithmetic per block for any ``workers``, and no second layer of threads on the same
        cores); restored afterwards, also on error. torch's thread count is process-wide, so
        :meth:`predict` is not meant to be called from several threads at once."""
        if n_rows <= BLOCK_ROWS:
            yield
            return
        previous = torch.get_num_threads()
        torch.set_num_threads(1)
        try:
            yield
        finally:
            torch.set_num_threads(previous)

    def predict_next(self, windows: np.ndarray) -> np.ndarray:
        """One-step prediction: windows (B, W, 2) in metres -> (B, 2) float64 next points.

        Raises HistoryError when ``windows`` is not a finite real (B, W, 2) array (fill gaps
        first: :func:`blindspot.traj.windows.interpolate_gaps`)."""
        x = _as_windows(windows, self.window, "windows")   # no NaN: fill gaps first
        return self.step(x).numpy()

    def predict(self, history: np.ndarray, horizon: int) -> np.ndarray:
        """Autoregressive rollout for a batch: predict, append, slide, ``horizon`` times.

        The whole history goes through :func:`fill_history` (interior gaps interpolated, leading
        gaps held, trailing gaps refused); then only its last W points are used.

        Args:
            history: (B, T, 2) observed points in metres, T >= W.
            horizon: number of future points, >= 1 (as every predictor's).

        Returns:
            (B, horizon, 2) float64 predicted points.

        Raises:
            HistoryError: ``history`` not real (B, T >= W, 2) (NaN rows allowed, inf not),
                ``horizon`` not an integer >= 1; ValueError from :func:`fill_history`.
        """
        history = check_array(history, "history", ("B", "T", 2), error=HistoryError,
                              who="lstm.predict", allow_nan=True)
        if history.shape[1] < self.window:
            raise HistoryError(f"lstm.predict: history needs at least window={self.window} "
                               f"points, found T={history.shape[1]}")
        horizon = check_count(horizon, "horizon", ge=1, error=HistoryError, who="lstm.predict")
        x = torch.from_numpy(np.ascontiguousarray(fill_history(history)[:, -self.window:],
                                                  dtype=np.float64))
        out = torch.empty((x.shape[0], int(horizon), 2), dtype=torch.float64)
        with self._single_threaded(x.shape[0]):
            for k in range(int(horizon)):  # one batched network call per future step
                nxt = self.step(x)
                out[:, k] = nxt
                x = torch.cat([x[:, 1:], nxt[:, None, :]], dim=1)
        return out.double().numpy()

    def save(self, path: str | Path) -> Path:
        """Write weights, config and statistics with ``torch.save`` (temp name, then rename).

        One network is written as format ``blindspot.lstm/1`` (one blob); an ensemble as
        ``blindspot.lstm-ensemble/1`` holding one such blob per member, in member order."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        blobs = [{"format": _FORMAT, "config": asdict(m.cfg), "stats": asdict(st),
                  "state_dict": m.state_dict()} for m, st in self.members]
        blob = blobs[0] if len(blobs) == 1 else {"format": _ENSEMBLE_FORMAT, "members": blobs}
        with atomic_path(path) as tmp:
            torch.save(blob, tmp)
        return path

    @classmethod
    def load(cls, path: str | Path) -> LSTMPredictor:
        """Read a file written by :meth:`save` (one network or an ensemble); ValueError naming
        the file if it is neither."""
        path = Path(path)
        blob = torch.load(path, map_location="cpu", weights_only=True)
        found = blob.get("format") if isinstance(blob, dict) else type(blob).__name__
        if found == _ENSEMBLE_FORMAT and blob.get("members"):
            pairs = [_member_from_blob(b, path) for b in blob["members"]]
            return cls(*pairs[0], more=pairs[1:])
        if found != _FORMAT:
            raise ValueError(f"{path}: not an LSTMPredictor file (expected format {_FORMAT!r} or "
                             f"{_ENSEMBLE_FORMAT!r}, found {found!r})")
        return cls(*_member_from_blob(blob, path))


def _member_from_blob(blob: Any, path: Path) -> tuple[LSTMRegressor, NormStats]:
    if not isinstance(blob, dict) or blob.get("format") != _FORMAT:
        raise ValueError(f"{path}: an ensemble member is not a {_FORMAT!r} blob")
    cfg = LSTMConfig(**blob["config"])
    st = blob["stats"]
    stats = NormStats(st["translate"], st["target"], tuple(st["in_offset"]), st["in_scale"], st["out_scale"])
    model = LSTMRegressor(cfg)
    model.load_state_dict(blob["state_dict"])
    return model, stats
