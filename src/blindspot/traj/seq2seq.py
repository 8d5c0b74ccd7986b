"""A direct multi-step path predictor: an encoder over the observed track and a head that emits
every future step at once, with a Gaussian per step.

Where the next-point LSTM (:mod:`blindspot.traj.lstm`) predicts one point and is rolled out step
by step (its errors feed back, and it is trained on one-step errors it never makes at 4.8 s),
this model reads the ``obs_len`` observed positions once and outputs all ``horizon`` future
positions together, trained on the loss that is scored, the mean Euclidean error over the
horizon (ADE), as in the sequence-to-sequence predictors of the ETH/UCY literature (e.g.
Alahi et al. 2016's encoder without social pooling; Becker et al. 2018, "RED: a simple but
effective baseline predictor for the TrajNet benchmark", an RNN encoder with a multi-step
dense head, which beats constant velocity there).

What the model sees and emits (each choice a :class:`Seq2SeqConfig` field, measured by
``studies/ethucy_models.py``):

* ``cell``: the encoder of the observed steps: a GRU or LSTM, a dense layer over the flattened
  steps (RED's dense variant), or a transformer (pre-norm self-attention over the steps with a
  learned position embedding, Vaswani et al. 2017; its last step's output).
* ``frame="heading"``: every track is moved to its own heading frame (origin at the last
  observed point, +x along the last step, :func:`blindspot.traj.predictor.heading_frame`), so the
  model is invariant to where the pedestrian is and which way they walk; ``"world"`` keeps world
  axes (translated to the last point).
* ``inputs``: the observed positions in that frame or their per-frame displacements.
* ``outputs``: future positions, or per-frame displacements summed into positions.
* ``residual``: the head predicts the deviation from constant velocity (the last step carried
  on), so an untrained head is CVM.
* ``mirror``: training copies reflected across the heading axis, and the prediction averaged
  with that of the mirrored track (walking has no preferred side).
* ``rotation_deg``: training copies rotated by a uniform random angle in
  [-rotation_deg, rotation_deg] (180 = any direction, the usual world-frame augmentation).
* ``scale_aug`` (a > 0): each training window (its neighbours' positions and steps with it)
  scaled by a factor log-uniform in [e^-a, e^a], a walker of another speed on a path of the
  same shape (a scene recorded at another pace or scale, as ETH/UCY's eth is against the
  others).
* Gaussian head (``nll_weight > 0``): per step, log standard deviations along both axes and a
  correlation, trained by the Gaussian negative log-likelihood with the mean held fixed
  (detached), so the uncertainty head never pulls the mean away from the ADE optimum.

* ``neighbours`` (K > 0): social context. The K pedestrians nearest to the walker at the last
  observed frame (:func:`blindspot.traj.ethucy.neighbour_tracks`) enter as, per neighbour and
  observed step, its position relative to the walker and its own step, both in the walker's
  frame, and a presence flag; a per-neighbour MLP embeds them and attention with the walker's
  encoding as query pools them (:class:`SocialAttention`, the attention pooling of Vemula et
  al. 2018, "Social Attention", and Sadeghian et al. 2019, "SoPhie", in place of Social LSTM's
  occupancy grid, Alahi et al. 2016), with a learned "nobody" slot so an empty scene is a
  valid input. Predicting without neighbours (``neighbours=None``) means nobody is near.

* ``basis_rank`` (k > 0): a low-rank prior over motion shapes. Each mean path's deviation from
  the residual base is projected on the k leading right singular vectors of the training
  windows' deviations (mirrored copies included; set once before training, a buffer saved with
  the weights): the "singular space" of Bae et al. 2024, "SingularTrajectory", without its
  adaptive anchors. A fine-tuned model keeps its ``init``'s basis.

* ``modes`` (M > 1): the head emits M hypotheses, each a Gaussian path, and their
  probabilities (a mixture; :mod:`blindspot.traj.mixture`), trained by relaxed
  winner-takes-all on the ADE (Rupprecht et al. 2017, "Learning in an uncertain world"; the
  multiple-trajectory loss of Cui et al. 2019, "Multimodal trajectory predictions for autonomous
  driving"): the hypothesis nearest the truth takes weight 1 - :data:`WTA_EPSILON` of the
  ADE, the others share the rest; the probabilities are trained by cross-entropy on that
  winner and the winner's Gaussian by its NLL. Each hypothesis starts at one of M anchors,
  k-means centres of the training futures' deviations from constant velocity (the anchors
  of Chai et al. 2019, "MultiPath"), so the hypotheses start apart. Its mean and covariance
  (what ``predict`` / ``predict_distribution`` give) are the mixture's moments;
  :meth:`Seq2SeqModel.predict_mixture` gives the mixture itself. Mirrored copies are a
  training augmentation only here (the M hypotheses are not averaged with the mirrored
  scene's, which would pair unrelated hypotheses).

An ensemble (:class:`Seq2SeqEnsemble`) averages the members' means; its covariance is the
moment-matched mixture (mean of the members' covariances plus the spread of their means), the
"deep ensembles" estimate of Lakshminarayanan et al. 2017.

Shapes: histories (B, T, 2) metres (the last ``obs_len`` rows used, no NaN there), neighbours
(B, K, obs_len, 2) metres (NaN = absent), predictions (B, horizon, 2) metres, covariances
(B, horizon, 2, 2) m^2.

Determinism: ``torch.manual_seed(seed)`` (weights), a private ``torch.Generator`` (batch order,
augmentation), deterministic algorithms and a fixed thread count: the same data, config, seed
and thread count give the same weights bit for bit.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
import torch
from torch import nn

from blindspot.arrays import check_array
from blindspot.io import atomic_path
from blindspot.traj.config import (
    SEQ2SEQ_CELLS as CELLS,
    SEQ2SEQ_FRAMES as FRAMES,
    SEQ2SEQ_INPUTS as INPUTS,
    SEQ2SEQ_LOSSES as LOSSES,
    SEQ2SEQ_OUTPUTS as OUTPUTS,
    Seq2SeqConfig,
)
from blindspot.traj.distribution import GaussianForecast
from blindspot.traj.mixture import MixtureForecast, kmeans
from blindspot.traj.predictor import HistoryError, check_history, heading_frame

__all__ = [
    "CELLS",
    "FRAMES",
    "INPUTS",
    "OUTPUTS",
    "LOSSES",
    "Seq2SeqConfig",
    "Seq2SeqNet",
    "SocialAttention",
    "social_features",
    "Seq2SeqModel",
    "Seq2SeqEnsemble",
    "FitReport",
    "train_seq2seq",
    "train_ensemble",
]

_MIRROR = np.array([1.0, -1.0])
#: relaxed winner-takes-all: the share of the ADE loss the M - 1 losing hypotheses take
WTA_EPSILON = 0.05
_ENSEMBLE_FORMAT = "blindspot.seq2seq-ensemble/1"


# --------------------------------------------------------------------------------------------
# the network
# --------------------------------------------------------------------------------------------


#: per neighbour and observed step: relative x, y, own step x, y, present
SOCIAL_FEATURES = 5


class SocialAttention(nn.Module):
    """Attention pooling over neighbours: (B, K, obs_len * 5) features and a (B, D) query ->
    (B, D) context. Each neighbour is embedded by an MLP; its score is
    ``v . tanh(W_e e_k + W_q q)`` (additive attention, Bahdanau et al. 2015); a learned "nobody"
    slot (key and value parameters) takes part in every softmax so a walker alone gets a valid,
    learned context; absent neighbours (``mask`` False) are left out."""

    def __init__(self, n_in: int, dim: int) -> None:
        super().__init__()
        self.embed = nn.Sequential(nn.Linear(n_in, dim), nn.ReLU(), nn.Linear(dim, dim), nn.ReLU())
        self.key = nn.Linear(dim, dim)
        self.query = nn.Linear(dim, dim, bias=False)
        self.score = nn.Linear(dim, 1, bias=False)
        self.nobody = nn.Parameter(torch.zeros(1, 1, dim))

    def forward(self, feats: torch.Tensor, mask: torch.Tensor, q: torch.Tensor) -> torch.Tensor:
        e = self.embed(feats)                                              # (B, K, D)
        e = torch.cat([self.nobody.expand(e.shape[0], 1, -1), e], dim=1)   # (B, K + 1, D)
        m = torch.cat([torch.ones_like(mask[:, :1]), mask], dim=1)
        a = self.score(torch.tanh(self.key(e) + self.query(q)[:, None])).squeeze(-1)
        a = torch.softmax(a.masked_fill(~m, float("-inf")), dim=1)
        return (a[..., None] * e).sum(dim=1)


class Seq2SeqNet(nn.Module):
    """Encoder (GRU/LSTM/transformer over the (obs_len or obs_len - 1, 2) input sequence, or a
    dense layer over it flattened) -> dense head -> (horizon, 5): mean offset (2) and Gaussian
    parameters (log std x, log std y, atanh rho); with ``cfg.neighbours`` the
    :class:`SocialAttention` context joins the head's input. With ``cfg.basis_rank`` k > 0 the
    mean offsets are projected on the span of the ``basis`` buffer's k orthonormal columns
    (:meth:`set_basis`; zero until set)."""

    def __init__(self, cfg: Seq2SeqConfig) -> None:
        super().__init__()
        self.cfg = cfg
        self.social = (SocialAttention(cfg.obs_len * SOCIAL_FEATURES, cfg.hidden_size)
                       if cfg.neighbours > 0 else None)
        self.embed = nn.Linear(2, cfg.hidden_size)
        n_steps = cfg.obs_len - (1 if cfg.inputs == "displacement" else 0)
        if cfg.cell == "mlp":     # the whole input sequence flattened (RED's dense variant)
            self.encoder = nn.Sequential(nn.Linear(2 * n_steps, cfg.hidden_size), nn.ReLU())
        elif cfg.cell == "transformer":   # pre-norm self-attention over the observed steps
            def layer() -> nn.TransformerEncoderLayer:
                return nn.TransformerEncoderLayer(
                    cfg.hidden_size, cfg.attention_heads, dim_feedforward=2 * cfg.hidden_size,
                    dropout=0.0, batch_first=True, norm_first=True)

            self.encoder = nn.TransformerEncoder(layer(), cfg.num_layers,
                                                 norm=nn.LayerNorm(cfg.hidden_size),
                                                 enable_nested_tensor=False)
            for i in range(1, cfg.num_layers):   # torch deep-copies the first: own draws
                self.encoder.layers[i] = layer()
            self.position = nn.Parameter(0.02 * torch.randn(n_steps, cfg.hidden_size))
        else:
            rnn = nn.GRU if cfg.cell == "gru" else nn.LSTM
            self.encoder = rnn(cfg.hidden_size, cfg.hidden_size, num_layers=cfg.num_layers,
                               batch_first=True)
        n_ctx = cfg.hidden_size * (2 if self.social is not None else 1)
        # M hypotheses of (horizon, 5) and, when M > 1, their M logits
        n_out = cfg.modes * cfg.horizon * 5 + (cfg.modes if cfg.modes > 1 else 0)
        self.head = nn.Sequential(nn.Linear(n_ctx + 2, cfg.head_hidden), nn.ReLU(),
                                  nn.Linear(cfg.head_hidden, n_out))
        # start at CVM with unit-ish spread: zero the last layer
        nn.init.zeros_(self.head[-1].weight)
        nn.init.zeros_(self.head[-1].bias)
        if cfg.basis_rank > 0:
            self.register_buffer("basis", torch.zeros(cfg.horizon * 2, cfg.basis_rank))

    def set_basis(self, deviations: np.ndarray) -> None:
        """Span of the mean offsets: the ``cfg.basis_rank`` leading right singular vectors of
        ``deviations`` (N, horizon, 2), framed training futures less their residual base."""
        k, h = self.cfg.basis_rank, self.cfg.horizon
        if k == 0:
            raise ValueError("Seq2SeqNet.set_basis: expected cfg.basis_rank > 0, found 0")
        d = check_array(deviations, "deviations", ("N", h, 2), who="Seq2SeqNet.set_basis")
        if len(d) < k:
            raise ValueError(f"Seq2SeqNet.set_basis: deviations: expected at least "
                             f"basis_rank = {k} paths, found {len(d)}")
        vt = np.linalg.svd(d.reshape(len(d), -1), full_matrices=False)[2]
        with torch.no_grad():
            self.basis.copy_(torch.as_tensor(vt[:k].T, dtype=self.basis.dtype))

    def _project(self, out: torch.Tensor) -> torch.Tensor:
        """(..., horizon, 5) head output with its mean offsets projected on the basis."""
        if self.cfg.basis_rank == 0:
            return out
        mean = out[..., :2].flatten(-2)
        mean = (mean @ self.basis) @ self.basis.T
        return torch.cat([mean.unflatten(-1, (self.cfg.horizon, 2)), out[..., 2:]], dim=-1)

    def set_anchors(self, anchors: np.ndarray) -> None:
        """Start hypothesis m at ``anchors[m]`` (M, horizon, 2), a framed deviation from the
        residual base (the head's mean-offset biases; its weights stay zero); with a basis,
        at the anchor's projection on it (the nearest path the head can emit)."""
        a = np.asarray(anchors, dtype=float)
        if a.shape != (self.cfg.modes, self.cfg.horizon, 2):
            raise ValueError(f"Seq2SeqNet.set_anchors: anchors: expected shape "
                             f"{(self.cfg.modes, self.cfg.horizon, 2)}, found {a.shape}")
        if self.cfg.outputs == "displacement":
            a = np.diff(a, axis=1, prepend=0.0)
        m, h = self.cfg.modes, self.cfg.horizon
        with torch.no_grad():
            bias = self.head[-1].bias[:m * h * 5].view(m, h, 5)
            bias[..., :2] = torch.as_tensor(a, dtype=bias.dtype)

    def forward(self, u: torch.Tensor, last_step: torch.Tensor,
                social: torch.Tensor | None = None
                ) -> torch.Tensor | tuple[torch.Tensor, torch.Tensor]:
        """u: (B, L, 2) inputs; last_step: (B, 2) last observed step; social: (B, K, obs_len,
        5) :func:`social_features` (needed when ``cfg.neighbours``) -> (B, horizon, 5); with
        ``cfg.modes`` M > 1, ``((B, M, horizon, 5), (B, M) logits)``."""
        if self.cfg.cell == "mlp":
            enc = self.encoder(u.flatten(1))
        elif self.cfg.cell == "transformer":
            enc = self.encoder(self.embed(u) + self.position)[:, -1]
        else:
            enc = self.encoder(torch.relu(self.embed(u)))[0][:, -1]
        if self.social is not None:
            if social is None:
                raise HistoryError("Seq2SeqNet: the model reads neighbours; pass social features")
            mask = social[..., -1].amax(dim=-1) > 0                          # (B, K)
            enc = torch.cat([enc, self.social(social.flatten(2), mask, enc)], dim=-1)
        z = torch.cat([enc, last_step], dim=-1)
        out = self.head(z)
        m, h = self.cfg.modes, self.cfg.horizon
        if m == 1:
            return self._project(out.view(-1, h, 5))
        return self._project(out[:, :m * h * 5].view(-1, m, h, 5)), out[:, m * h * 5:]


# --------------------------------------------------------------------------------------------
# frames and encodings (numpy, batched)
# --------------------------------------------------------------------------------------------


def _frames(obs: np.ndarray, cfg: Seq2SeqConfig) -> tuple[np.ndarray, np.ndarray]:
    """origin (B, 2), rot (B, 2, 2) of each observed track (heading frame or world axes)."""
    origin, rot = heading_frame(obs, cfg.speed_floor if cfg.speed_floor > 0 else None)
    if cfg.frame == "world":
        step = obs[:, -1] - obs[:, -2]
        scale = (np.maximum(np.hypot(step[:, 0], step[:, 1]), cfg.speed_floor)
                 if cfg.speed_floor > 0 else np.ones(obs.shape[0]))
        rot = np.eye(2)[None] / scale[:, None, None]
    return origin, rot


def _to(points: np.ndarray, origin: np.ndarray, rot: np.ndarray) -> np.ndarray:
    return np.einsum("bij,btj->bti", rot, points - origin[:, None, :])


def social_features(framed_obs: np.ndarray, framed_nb: np.ndarray) -> np.ndarray:
    """Neighbour features in the walker's frame.

    Args:
        framed_obs: (B, T, 2) the walker's observed positions (in its frame).
        framed_nb: (B, K, T, 2) the neighbours' positions in the same frame, NaN = absent.

    Returns:
        (B, K, T, 5): position relative to the walker at the same step (x, y), the neighbour's
        own step from the previous frame (x, y; 0 at the first step or next to an absence),
        present (1/0); zeros where absent.
    """
    present = np.isfinite(framed_nb).all(axis=-1)                              # (B, K, T)
    rel = np.where(present[..., None], framed_nb - framed_obs[:, None], 0.0)
    step = np.zeros_like(rel)
    both = present[..., 1:] & present[..., :-1]
    step[..., 1:, :] = np.where(both[..., None], np.diff(np.nan_to_num(framed_nb), axis=2), 0.0)
    return np.concatenate([rel, step, present[..., None].astype(float)], axis=-1)


def _to_nb(nb: np.ndarray, origin: np.ndarray, rot: np.ndarray) -> np.ndarray:
    return np.einsum("bij,bktj->bkti", rot, nb - origin[:, None, None, :])


def _mirror_social(f: np.ndarray) -> np.ndarray:
    """Social features of the mirrored scene (y components negated)."""
    return f * np.array([1.0, -1.0, 1.0, -1.0, 1.0])


def _framed_inputs(obs: np.ndarray, neighbours: np.ndarray | None, cfg: Seq2SeqConfig
                   ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray, np.ndarray]:
    """``(x, social, origin, rot)`` of observed tracks (B, obs_len, 2) metres: the tracks in
    their own frames (B, obs_len, 2), the :func:`social_features` (B, K, obs_len, 5) of the
    ``neighbours`` (B, K, obs_len, 2), NaN = absent, None = nobody near; None when the model
    reads none) and the frames (:func:`_frames`)."""
    origin, rot = _frames(obs, cfg)
    x = _to(obs, origin, rot)
    soc = None
    if cfg.neighbours > 0:
        nb = (np.full((obs.shape[0], cfg.neighbours, cfg.obs_len, 2), np.nan)
              if neighbours is None else neighbours)
        soc = social_features(x, _to_nb(nb, origin, rot))
    return x, soc, origin, rot


def _inputs(framed_obs: np.ndarray, cfg: Seq2SeqConfig) -> np.ndarray:
    return np.diff(framed_obs, axis=1) if cfg.inputs == "displacement" else framed_obs


def _cv_offsets(framed_obs: np.ndarray, horizon: int) -> np.ndarray:
    """(B, horizon, 2) constant-velocity future in the frame (last step carried on)."""
    step = framed_obs[:, -1] - framed_obs[:, -2]
    return step[:, None, :] * np.arange(1, horizon + 1)[None, :, None]


@dataclass
class FitReport:
    """What training one member did: the epoch kept (0: the ``init`` weights, which no epoch
    beat on val), validation ADE/FDE per epoch (m; with ``keep_by="best_of"`` and modes > 1,
    of each window's hypothesis with the lowest ADE), the ``init`` weights' val ADE (m; None
    without ``init``), time."""

    best_epoch: int
    val_ade: list[float] = field(default_factory=list)
    val_fde: list[float] = field(default_factory=list)
    seconds: float = 0.0
    init_val_ade: float | None = None

    @property
    def best_val_ade(self) -> float | None:
        """Val ADE (m) of the weights kept: the best epoch's, or the ``init`` weights' when no
        epoch beat them (``best_epoch`` 0; None without ``init``)."""
        return self.val_ade[self.best_epoch - 1] if self.best_epoch else self.init_val_ade


class Seq2SeqModel:
    """One trained network with its config; predicts means and Gaussians in world metres."""

    def __init__(self, net: Seq2SeqNet, cfg: Seq2SeqConfig, name: str = "seq2seq",
                 point: str = "mean") -> None:
        if point not in ("mean", "mode"):
            raise ValueError(f"Seq2SeqModel: point: expected 'mean' or 'mode', found {point!r}")
        self.net = net.eval()
        self.cfg = cfg
        self.name = name
        #: a multi-modal model's single prediction: the mixture's mean or its most probable
        #: hypothesis (the covariance is the mixture's second moment about it)
        self.point = point

    def _raw(self, obs: np.ndarray, neighbours: np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Framed mean (B, H, 2), framed cov (B, H, 2, 2), origin, rot of (B, obs_len, 2)
        (and neighbours (B, K, obs_len, 2) when the model reads them)."""
        x, soc, origin, rot = _framed_inputs(obs, neighbours, self.cfg)
        mean, cov = self._framed_both(x, soc)
        return mean, cov, origin, rot

    def _framed_both(self, x: np.ndarray, soc: np.ndarray | None, *, with_cov: bool = True
                     ) -> tuple[np.ndarray, np.ndarray | None]:
        """Framed mean (B, H, 2) and cov (B, H, 2, 2) (None unless ``with_cov``) of framed
        inputs, averaged with the mirrored scene's when ``cfg.mirror`` (the tracks and their
        mirror images in one network call of 2B rows)."""
        if not self.cfg.mirror or self.cfg.modes > 1:
            return self._framed(x, soc, with_cov=with_cov)
        n = x.shape[0]
        both, c_both = self._framed(
            np.concatenate([x, x * _MIRROR]),
            None if soc is None else np.concatenate([soc, _mirror_social(soc)]),
            with_cov=with_cov)
        mean = 0.5 * (both[:n] + both[n:] * _MIRROR)
        cov = None
        if with_cov:
            flip = np.array([[1.0, -1.0], [-1.0, 1.0]])
            cov = 0.5 * (c_both[:n] + c_both[n:] * flip)
        return mean, cov

    def _net_out(self, x: np.ndarray, soc: np.ndarray | None):
        cfg = self.cfg
        with torch.no_grad(), _threads(cfg.threads):
            u = torch.as_tensor(_inputs(x, cfg), dtype=torch.float32)
            last = torch.as_tensor(x[:, -1] - x[:, -2], dtype=torch.float32)
            s = None if soc is None else torch.as_tensor(soc, dtype=torch.float32)
            return self.net(u, last, s)

    def _framed(self, x: np.ndarray, soc: np.ndarray | None = None, *, with_cov: bool = True
                ) -> tuple[np.ndarray, np.ndarray | None]:
        if self.cfg.modes > 1:       # the mixture about its mean or its most probable path
            mix = self._framed_mixture(x, soc)
            centre = mix.most_likely() if self.point == "mode" else mix.mean()
            return centre, (mix.second_moment(centre) if with_cov else None)
        out = self._net_out(x, soc).double().numpy()
        mean = _decode_mean(out[..., :2], x, self.cfg)
        return mean, (_covariance(out[..., 2:]) if with_cov else None)

    def _framed_mixture(self, x: np.ndarray, soc: np.ndarray | None = None) -> MixtureForecast:
        """The M hypotheses of framed inputs as a :class:`MixtureForecast` in the frame."""
        out, logits = self._net_out(x, soc)
        out, logits = out.double().numpy(), logits.double().numpy()
        b, m = out.shape[:2]
        flat = out.reshape(b * m, *out.shape[2:])
        means = _decode_mean(flat[..., :2], np.repeat(x, m, axis=0), self.cfg)
        covs = _covariance(flat[..., 2:])
        w = np.exp(logits - logits.max(axis=1, keepdims=True))
        return MixtureForecast(w / w.sum(axis=1, keepdims=True),
                               means.reshape(b, m, *means.shape[1:]),
                               covs.reshape(b, m, *covs.shape[1:]))

    def predict_mixture(self, history: np.ndarray, horizon: int, *,
                        neighbours: np.ndarray | None = None) -> MixtureForecast:
        """(B, T, 2) history -> the M hypotheses over the next ``horizon`` (<= cfg.horizon)
        positions in world metres, a :class:`MixtureForecast` (a model with ``cfg.modes`` > 1;
        HistoryError otherwise); ``neighbours`` as in :meth:`predict_distribution`."""
        if self.cfg.modes < 2:
            raise HistoryError(f"{self.name}.predict_mixture: the model emits one path "
                               f"(modes = {self.cfg.modes}); expected modes > 1")
        obs = self._observed(history, horizon)
        return self._mixture_of_framed(_framed_inputs(
            obs, _check_neighbours(neighbours, obs.shape[0], self.cfg, self.name), self.cfg),
            horizon)

    def _mean_of_framed(self, framed: tuple[np.ndarray, np.ndarray | None, np.ndarray,
                                            np.ndarray], horizon: int) -> np.ndarray:
        """(B, horizon, 2) world mean positions of inputs framed once by
        :func:`_framed_inputs` (the per-epoch validation: the val tracks are framed, and their
        social features built, once per training instead of once per epoch); the same numbers
        as :meth:`predict` on those tracks."""
        x, soc, origin, rot = framed
        mean, _ = self._framed_both(x, soc, with_cov=False)
        return np.einsum("bij,bhj->bhi", np.linalg.inv(rot), mean[:, :horizon]) + origin[:, None, :]

    def _mixture_of_framed(self, framed: tuple[np.ndarray, np.ndarray | None, np.ndarray,
                                               np.ndarray], horizon: int) -> MixtureForecast:
        """The M hypotheses over ``horizon`` steps, world metres, of inputs framed by
        :func:`_framed_inputs` (a model with ``cfg.modes`` > 1): what :meth:`predict_mixture`
        gives, and the per-epoch validation's, whose val tracks are framed once."""
        x, soc, origin, rot = framed
        mix = self._framed_mixture(x, soc).truncated(horizon)
        return mix.transformed(np.linalg.inv(rot), origin)

    @property
    def uses_neighbours(self) -> bool:
        return self.cfg.neighbours > 0

    def predict_distribution(self, history: np.ndarray, horizon: int, *,
                             neighbours: np.ndarray | None = None) -> GaussianForecast:
        """(B, T, 2) history -> per-step Gaussian of the next ``horizon`` (<= cfg.horizon)
        positions in world metres (the network's own head, not yet calibrated); ``neighbours``
        (B, K, obs_len, 2) world metres, NaN = absent, None = nobody near."""
        obs = self._observed(history, horizon)
        nb = _check_neighbours(neighbours, obs.shape[0], self.cfg, self.name)
        mean, cov, origin, rot = self._raw(obs, nb)
        return _to_world(mean[:, :horizon], cov[:, :horizon], origin, rot)

    def predict(self, history: np.ndarray, horizon: int, *,
                neighbours: np.ndarray | None = None) -> np.ndarray:
        """(B, T, 2) history -> (B, horizon, 2) mean positions in metres."""
        return self.predict_distribution(history, horizon, neighbours=neighbours).mean

    def _observed(self, history: np.ndarray, horizon: int) -> np.ndarray:
        return _observed(history, horizon, self.cfg, self.name)


def _observed(history: np.ndarray, horizon: int, cfg: Seq2SeqConfig, name: str) -> np.ndarray:
    h = check_history(history, horizon, who=f"{name}.predict")
    if horizon > cfg.horizon:
        raise HistoryError(f"{name}.predict: the model emits {cfg.horizon} steps, asked for "
                           f"{horizon}")
    if h.shape[1] < cfg.obs_len or not np.isfinite(h[:, -cfg.obs_len:]).all():
        raise HistoryError(f"{name}.predict: needs the last obs_len={cfg.obs_len} rows observed "
                           f"(no NaN), found T={h.shape[1]} with "
                           f"{int(np.sum(~np.isfinite(h[:, -cfg.obs_len:])))} NaN values "
                           "there; fill gaps first (e.g. KalmanCV.smooth)")
    return h[:, -cfg.obs_len:]


def _check_neighbours(neighbours: np.ndarray | None, n: int, cfg: Seq2SeqConfig, name: str
                      ) -> np.ndarray | None:
    """None, or neighbours as (n, cfg.neighbours, obs_len, 2) (HistoryError otherwise); more
    neighbours than the model reads are cut to the nearest ``cfg.neighbours``."""
    if neighbours is None or cfg.neighbours == 0:
        return None
    nb = check_array(neighbours, "neighbours", (n, "K", cfg.obs_len, 2), error=HistoryError,
                     who=f"{name}.predict", allow_nan=True)
    if nb.shape[1] < cfg.neighbours:
        pad = np.full((n, cfg.neighbours - nb.shape[1], cfg.obs_len, 2), np.nan)
        nb = np.concatenate([nb, pad], axis=1)
    return nb[:, :cfg.neighbours]


def _decode_mean(offset: np.ndarray, x: np.ndarray, cfg: Seq2SeqConfig) -> np.ndarray:
    """Framed future positions (B, H, 2) from the head's offsets."""
    if cfg.outputs == "displacement":
        offset = np.cumsum(offset, axis=1)
    return (_cv_offsets(x, cfg.horizon) if cfg.residual else 0.0) + offset + x[:, -1:, :]


def _covariance(p: np.ndarray) -> np.ndarray:
    """(B, H, 3) (log sx, log sy, atanh rho) -> (B, H, 2, 2) covariances."""
    sx, sy = np.exp(p[..., 0]), np.exp(p[..., 1])
    rho = np.tanh(p[..., 2])
    c = np.empty(p.shape[:-1] + (2, 2))
    c[..., 0, 0], c[..., 1, 1] = sx**2, sy**2
    c[..., 0, 1] = c[..., 1, 0] = rho * sx * sy
    return c + 1e-6 * np.eye(2)


def _to_world(mean: np.ndarray, cov: np.ndarray, origin: np.ndarray, rot: np.ndarray
              ) -> GaussianForecast:
    inv = np.linalg.inv(rot)                            # rotation (and speed scaling)
    m = np.einsum("bij,bhj->bhi", inv, mean) + origin[:, None, :]
    c = np.einsum("bij,bhjk,blk->bhil", inv, cov, inv)
    return GaussianForecast(m, 0.5 * (c + np.swapaxes(c, -1, -2)))


class _threads:
    """Context: torch thread count fixed (and deterministic algorithms on), then restored."""

    def __init__(self, n: int) -> None:
        self.n = int(n)

    def __enter__(self) -> None:
        self.prev = (torch.get_num_threads(), torch.are_deterministic_algorithms_enabled())
        torch.set_num_threads(self.n)
        torch.use_deterministic_algorithms(True)

    def __exit__(self, *exc) -> None:
        torch.set_num_threads(self.prev[0])
        torch.use_deterministic_algorithms(self.prev[1])


class Seq2SeqEnsemble:
    """Members' mean and moment-matched covariance, optionally scaled per step.

    Attributes:
        members: trained :class:`Seq2SeqModel` s (same config but the seed).
        step_scale: (H,) covariance multipliers fitted on validation data
            (:func:`blindspot.traj.distribution.fit_step_scale`), or None.
        name: label used in reports.
    """

    def __init__(self, members: Sequence[Seq2SeqModel], *, name: str = "seq2seq",
                 step_scale: np.ndarray | None = None) -> None:
        if not members:
            raise ValueError("Seq2SeqEnsemble: expected at least one member, found none")
        self.members = list(members)
        self.cfg = self.members[0].cfg
        if len({replace(m.cfg, seed=0) for m in self.members}) != 1:
            raise ValueError("Seq2SeqEnsemble: members must share one config (all but the seed)")
        self.name = name
        self.step_scale = step_scale

    @property
    def uses_neighbours(self) -> bool:
        return self.cfg.neighbours > 0

    def predict_distribution(self, history: np.ndarray, horizon: int, *,
                             calibrated: bool = True, neighbours: np.ndarray | None = None
                             ) -> GaussianForecast:
        """(B, T, 2) -> GaussianForecast over ``horizon`` steps: mean of the members' means;
        covariance mean(cov_k) + cov(mean_k) (mixture moments), times ``step_scale`` when
        ``calibrated`` and a scale was fitted. ``neighbours``: see
        :meth:`Seq2SeqModel.predict_distribution`."""
        obs = _observed(history, horizon, self.cfg, self.name)
        # the members share one config, so one frame per track serves them all; the mixture's
        # moments are taken in that frame and carried to the world once (both are linear)
        x, soc, origin, rot = _framed_inputs(
            obs, _check_neighbours(neighbours, obs.shape[0], self.cfg, self.name), self.cfg)
        outs = [m._framed_both(x, soc) for m in self.members]
        means = np.stack([mu[:, :horizon] for mu, _ in outs])               # (K, B, H, 2)
        mean = means.mean(axis=0)
        d = means - mean
        cov = (np.mean([c[:, :horizon] for _, c in outs], axis=0)
               + np.einsum("kbhi,kbhj->bhij", d, d) / len(outs))
        fc = _to_world(mean, cov, origin, rot)
        if calibrated and self.step_scale is not None:
            fc = fc.scaled(self.step_scale[:horizon])
        return fc

    def predict(self, history: np.ndarray, horizon: int, *,
                neighbours: np.ndarray | None = None) -> np.ndarray:
        """(B, T, 2) -> (B, horizon, 2) the ensemble's mean positions in metres."""
        obs = _observed(history, horizon, self.cfg, self.name)
        x, soc, origin, rot = _framed_inputs(
            obs, _check_neighbours(neighbours, obs.shape[0], self.cfg, self.name), self.cfg)
        mean = np.mean([m._framed_both(x, soc, with_cov=False)[0][:, :horizon]
                        for m in self.members], axis=0)
        return np.einsum("bij,bhj->bhi", np.linalg.inv(rot), mean) + origin[:, None, :]

    @property
    def obs_len(self) -> int:
        """Observed positions each prediction reads (the last ``obs_len`` rows of a history)."""
        return self.cfg.obs_len

    window = obs_len

    def save(self, path: str | Path) -> Path:
        """Write the members' weights and their config with ``torch.save`` (format
        ``blindspot.seq2seq-ensemble/1``; temporary name, then rename). The ``step_scale``
        is not written: calibration is kept beside the model (the calibration stage's
        records)."""
        path = Path(path)
        blob = {"format": _ENSEMBLE_FORMAT, "name": self.name,
                "configs": [asdict(m.cfg) for m in self.members],
                "state_dicts": [m.net.state_dict() for m in self.members]}
        with atomic_path(path) as tmp:
            torch.save(blob, tmp)
        return path

    @classmethod
    def load(cls, path: str | Path) -> Seq2SeqEnsemble:
        """Read a file written by :meth:`save`; ValueError naming the file when it is not one."""
        path = Path(path)
        blob = torch.load(path, map_location="cpu", weights_only=True)
        found = blob.get("format") if isinstance(blob, dict) else type(blob).__name__
        if found != _ENSEMBLE_FORMAT:
            raise ValueError(f"{path}: not a Seq2SeqEnsemble file (expected format "
                             f"{_ENSEMBLE_FORMAT!r}, found {found!r})")
        configs, states = blob.get("configs"), blob.get("state_dicts")
        if (not isinstance(configs, list) or not isinstance(states, list) or not configs
                or len(configs) != len(states) or not isinstance(blob.get("name"), str)):
            raise ValueError(f"{path}: a damaged Seq2SeqEnsemble file: expected a name and as "
                             "many member configs as weight sets (at least one), found "
                             f"{len(configs) if isinstance(configs, list) else configs!r} "
                             f"configs and {len(states) if isinstance(states, list) else states!r}"
                             " weight sets")
        members = []
        for config, state in zip(blob["configs"], blob["state_dicts"]):
            cfg = Seq2SeqConfig(**config)
            net = Seq2SeqNet(cfg)
            net.load_state_dict(state)
            members.append(Seq2SeqModel(net, cfg, blob["name"]))
        return cls(members, name=blob["name"])


# --------------------------------------------------------------------------------------------
# training
# --------------------------------------------------------------------------------------------


def _training_arrays(xy: np.ndarray, cfg: Seq2SeqConfig, nb: np.ndarray | None = None
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Framed observed (N', obs_len, 2), future (N', horizon, 2) and social features (N', K,
    obs_len, 5) or None of windows (N, obs+H, 2), mirrored copies appended when
    ``cfg.mirror``."""
    obs, fut = xy[:, :cfg.obs_len], xy[:, cfg.obs_len:cfg.obs_len + cfg.horizon]
    origin, rot = _frames(obs, cfg)
    x, y = _to(obs, origin, rot), _to(fut, origin, rot)
    soc = None
    if cfg.neighbours > 0:
        nbf = (np.full((xy.shape[0], cfg.neighbours, cfg.obs_len, 2), np.nan) if nb is None
               else nb)
        soc = social_features(x, _to_nb(nbf, origin, rot))
    if cfg.mirror:
        x, y = np.concatenate([x, x * _MIRROR]), np.concatenate([y, y * _MIRROR])
        if soc is not None:
            soc = np.concatenate([soc, _mirror_social(soc)])
    return x, y, soc


def _torch_batch(x: torch.Tensor, cfg: Seq2SeqConfig) -> tuple[torch.Tensor, torch.Tensor,
                                                               torch.Tensor]:
    """(inputs, last step, constant-velocity-plus-last-point base) of framed windows."""
    u = torch.diff(x, dim=1) if cfg.inputs == "displacement" else x
    step = x[:, -1] - x[:, -2]
    k = torch.arange(1, cfg.horizon + 1, dtype=x.dtype)[None, :, None]
    base = x[:, -1:, :] + (step[:, None, :] * k if cfg.residual else 0.0)
    return u, step, base


def _rotate_batch(x: torch.Tensor, y: torch.Tensor, s: torch.Tensor | None, theta: torch.Tensor
                  ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None]:
    """The rotation augmentation: framed observed (B, T, 2) and future (B, H, 2) points and the
    vector parts of the social features (B, K, T, 5: relative position 0:2, own step 2:4; the
    presence flag 4 unchanged) each rotated by its scene's angle ``theta`` (B,) rad,
    counter-clockwise."""
    cos, sin = torch.cos(theta), torch.sin(theta)
    rot = torch.stack([torch.stack([cos, -sin], -1), torch.stack([sin, cos], -1)], -2)
    x, y = x @ rot.transpose(1, 2), y @ rot.transpose(1, 2)
    if s is not None:
        rk = rot[:, None, None]
        s = torch.cat([(rk @ s[..., 0:2, None])[..., 0], (rk @ s[..., 2:4, None])[..., 0],
                       s[..., 4:]], dim=-1)
    return x, y, s


def _scale_batch(x: torch.Tensor, y: torch.Tensor, s: torch.Tensor | None, k: torch.Tensor
                 ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None]:
    """The scale augmentation: framed observed (B, T, 2) and future (B, H, 2) points and the
    vector parts of the social features (B, K, T, 5: relative position and own step; the
    presence flag unchanged) each multiplied by its scene's factor ``k`` (B,)."""
    x, y = x * k[:, None, None], y * k[:, None, None]
    if s is not None:
        s = torch.cat([s[..., :4] * k[:, None, None, None], s[..., 4:]], dim=-1)
    return x, y, s


def _gaussian_nll(e: torch.Tensor, p: torch.Tensor) -> torch.Tensor:
    """Per-point NLL (without the constant ln 2 pi) of errors e (..., 2) under the head's
    Gaussians p (..., 3: log sx, log sy, atanh rho)."""
    ls = p[..., 0:2].clamp(-7.0, 5.0)
    rho = torch.tanh(p[..., 2]).clamp(-0.99, 0.99)
    zx, zy = e[..., 0] * torch.exp(-ls[..., 0]), e[..., 1] * torch.exp(-ls[..., 1])
    one = 1 - rho**2
    return 0.5 * (zx**2 - 2 * rho * zx * zy + zy**2) / one + ls.sum(-1) + 0.5 * torch.log(one)


def _loss(out: torch.Tensor | tuple[torch.Tensor, torch.Tensor], base: torch.Tensor,
          y: torch.Tensor, cfg: Seq2SeqConfig) -> tuple[torch.Tensor, torch.Tensor]:
    """(total loss, ADE of the batch) for head output (B, H, 5) against framed truth y; with
    ``cfg.modes`` > 1 the output is ``((B, M, H, 5), (B, M) logits)``, the loss the relaxed
    winner-takes-all one (module docstring) and the ADE that of the winners (best of M, or
    with ``wta_score="ade_fde"`` the hypotheses best by ADE + FDE)."""
    if cfg.modes > 1:
        return _mixture_loss(out[0], out[1], base, y, cfg)
    off = out[..., :2]
    if cfg.outputs == "displacement":
        off = torch.cumsum(off, dim=1)
    mean = base + off
    err = y - mean
    ade = torch.linalg.vector_norm(err, dim=-1).mean()
    fit = ade if cfg.loss == "ade" else (err**2).sum(-1).mean()
    if cfg.nll_weight <= 0:
        return fit, ade
    return fit + cfg.nll_weight * _gaussian_nll(err.detach(), out[..., 2:]).mean(), ade


def _mixture_loss(out: torch.Tensor, logits: torch.Tensor, base: torch.Tensor, y: torch.Tensor,
                  cfg: Seq2SeqConfig) -> tuple[torch.Tensor, torch.Tensor]:
    off = out[..., :2]
    if cfg.outputs == "displacement":
        off = torch.cumsum(off, dim=2)
    err = y[:, None] - (base[:, None] + off)                                 # (B, M, H, 2)
    dist = torch.linalg.vector_norm(err, dim=-1)                             # (B, M, H)
    per = dist.mean(-1) if cfg.loss == "ade" else (err**2).sum(-1).mean(-1)  # (B, M)
    score = (dist.mean(-1) + dist[..., -1] if cfg.wta_score == "ade_fde" else per).detach()
    win = score.argmin(dim=1)                                                # (B,)
    m = cfg.modes
    w = torch.full_like(per, WTA_EPSILON / (m - 1))
    w.scatter_(1, win[:, None], 1.0 - WTA_EPSILON)
    fit = (w * per).sum(1).mean()
    ade = dist.mean(-1).gather(1, win[:, None]).mean()
    loss = fit + torch.nn.functional.cross_entropy(logits, win)
    if cfg.nll_weight > 0:
        idx = win[:, None, None, None]
        e = err.detach().gather(1, idx.expand(-1, 1, *err.shape[2:]))[:, 0]
        p = out[..., 2:].gather(1, idx.expand(-1, 1, *out.shape[2:3], 3))[:, 0]
        loss = loss + cfg.nll_weight * _gaussian_nll(e, p).mean()
    return loss, ade


def base_deviations(x: np.ndarray, y: np.ndarray, cfg: Seq2SeqConfig) -> np.ndarray:
    """(N, horizon, 2) framed futures ``y`` (N, H, 2) less the residual base of framed
    observations ``x`` (N, obs_len, 2): what the head's mean offsets learn."""
    x = check_array(x, "x", ("N", cfg.obs_len, 2), who="base_deviations")
    y = check_array(y, "y", (len(x), cfg.horizon, 2), who="base_deviations")
    return y - (x[:, -1:, :] + (_cv_offsets(x, cfg.horizon) if cfg.residual else 0.0))


def mixture_anchors(x: np.ndarray, y: np.ndarray, cfg: Seq2SeqConfig, seed: int) -> np.ndarray:
    """(M, horizon, 2) starting points of the M hypotheses: k-means centres
    (:func:`blindspot.traj.mixture.kmeans`, seeded) of the :func:`base_deviations`."""
    dev = base_deviations(x, y, cfg).reshape(len(y), -1)
    return kmeans(dev, cfg.modes, seed=seed).reshape(cfg.modes, cfg.horizon, 2)


def train_seq2seq(train_xy: np.ndarray, val_xy: np.ndarray, cfg: Seq2SeqConfig, *,
                  seed: int | None = None, name: str = "seq2seq",
                  progress: Callable[[str], None] | None = None,
                  train_nb: np.ndarray | None = None, val_nb: np.ndarray | None = None,
                  init: Seq2SeqModel | None = None) -> tuple[Seq2SeqModel, FitReport]:
    """Train one network on windows (N, obs_len + horizon, 2) metres; keep the epoch with the
    lowest ADE on ``val_xy`` (model selection on validation data only).

    Args:
        train_xy, val_xy: (N, obs_len + horizon, 2) windows in metres, no NaN.
        cfg: the model and training settings.
        seed: overrides ``cfg.seed`` (ensemble members).
        name: label of the model.
        progress: called with one line per epoch (None = silent).
        train_nb, val_nb: (N, K, obs_len, 2) neighbours of the windows (metres, NaN =
            absent; ``Windows.neighbours``), read when ``cfg.neighbours`` > 0.
        init: start from this model's weights instead of a fresh draw (fine-tuning a
            pre-trained network; its motion basis and anchors with them); the optimiser and
            its schedule start afresh, and the weights
            themselves are scored on ``val_xy`` as epoch 0 (kept if no epoch beats them). Its
            config must equal ``cfg`` in every architecture key.

    Returns:
        ``(model, report)``.

    Raises:
        HistoryError: windows not (N, obs_len + horizon, 2) finite arrays, or none.
        ValueError: ``init`` of another architecture (names the keys).
    """
    t0 = time.perf_counter()
    if init is not None:
        _check_architecture(init.cfg, cfg, "train_seq2seq: init")
    seq = cfg.obs_len + cfg.horizon
    for key, arr in (("train_xy", train_xy), ("val_xy", val_xy)):
        a = check_array(arr, key, ("N", seq, 2), error=HistoryError, who="train_seq2seq")
        if a.shape[0] == 0:
            raise HistoryError(f"train_seq2seq: {key} holds no window")
    seed = cfg.seed if seed is None else int(seed)
    if cfg.neighbours > 0 and train_nb is not None:
        train_nb = _check_neighbours(train_nb, len(train_xy), cfg, "train_seq2seq")
    if cfg.neighbours > 0 and val_nb is not None:
        val_nb = _check_neighbours(val_nb, len(val_xy), cfg, "train_seq2seq")
    x_np, y_np, s_np = _training_arrays(np.asarray(train_xy, float), cfg, train_nb)
    val_obs = np.asarray(val_xy, float)[:, :cfg.obs_len]
    val_fut = np.asarray(val_xy, float)[:, cfg.obs_len:]
    # the val tracks framed once (what Seq2SeqModel.predict does to them on every epoch)
    val_framed = _framed_inputs(
        _observed(val_obs, cfg.horizon, cfg, name),
        _check_neighbours(val_nb, len(val_obs), cfg, name), cfg)
    with _threads(cfg.threads):
        torch.manual_seed(seed)
        gen = torch.Generator().manual_seed(seed)
        net = Seq2SeqNet(cfg)
        if init is not None:
            net.load_state_dict(init.net.state_dict())
        else:
            if cfg.basis_rank > 0:
                net.set_basis(base_deviations(x_np, y_np, cfg))
            if cfg.modes > 1:
                net.set_anchors(mixture_anchors(x_np, y_np, cfg, seed))
        opt = torch.optim.AdamW(net.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
        sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=cfg.epochs)
        x_all = torch.as_tensor(x_np, dtype=torch.float32)
        y_all = torch.as_tensor(y_np, dtype=torch.float32)
        s_all = None if s_np is None else torch.as_tensor(s_np, dtype=torch.float32)
        n = x_all.shape[0]
        report = FitReport(best_epoch=0)
        best_state, best_ade = None, np.inf

        def val_errors() -> np.ndarray:
            """(N_val, horizon) m: the network's errors on the val windows as they stand."""
            model = Seq2SeqModel(net, cfg, name)
            if cfg.keep_by == "best_of" and cfg.modes > 1:
                hyp = model._mixture_of_framed(val_framed, cfg.horizon).means   # (N, M, H, 2)
                err = np.linalg.norm(hyp - val_fut[:, None], axis=-1)
                best = err.mean(axis=-1).argmin(axis=1)
                return err[np.arange(len(err)), best]
            pred = model._mean_of_framed(val_framed, cfg.horizon)
            return np.linalg.norm(pred - val_fut, axis=-1)

        def weights() -> dict[str, torch.Tensor]:
            return {k: v.clone() for k, v in net.state_dict().items()}

        if init is not None:
            # the pre-trained weights are epoch 0's candidate: fine-tuning keeps them when no
            # epoch scores better on val
            best_ade = report.init_val_ade = float(val_errors().mean())
            best_state = weights()
        for epoch in range(1, cfg.epochs + 1):
            net.train()
            order = torch.randperm(n, generator=gen)
            for i in range(0, n, cfg.batch_size):
                idx = order[i:i + cfg.batch_size]
                x, y = x_all[idx], y_all[idx]
                s = None if s_all is None else s_all[idx]
                if cfg.rotation_deg > 0:
                    th = (torch.rand(x.shape[0], generator=gen) * 2 - 1) * np.deg2rad(
                        cfg.rotation_deg)
                    x, y, s = _rotate_batch(x, y, s, th)
                if cfg.scale_aug > 0:
                    x, y, s = _scale_batch(x, y, s, torch.exp(
                        (torch.rand(x.shape[0], generator=gen) * 2 - 1) * cfg.scale_aug))
                u, step, base = _torch_batch(x, cfg)
                loss, _ = _loss(net(u, step, s), base, y, cfg)
                opt.zero_grad()
                loss.backward()
                opt.step()
            sched.step()
            err = val_errors()
            report.val_ade.append(float(err.mean()))
            report.val_fde.append(float(err[:, -1].mean()))
            if report.val_ade[-1] < best_ade:
                best_ade, report.best_epoch = report.val_ade[-1], epoch
                best_state = weights()
            if progress is not None:
                progress(f"{name} seed {seed} epoch {epoch}: val ADE {report.val_ade[-1]:.4f} "
                         f"FDE {report.val_fde[-1]:.4f}")
        net.load_state_dict(best_state)
    report.seconds = time.perf_counter() - t0
    return Seq2SeqModel(net, replace(cfg, seed=seed), name), report


def train_ensemble(train_xy: np.ndarray, val_xy: np.ndarray, cfg: Seq2SeqConfig, *,
                   name: str = "seq2seq", progress: Callable[[str], None] | None = None,
                   train_nb: np.ndarray | None = None, val_nb: np.ndarray | None = None,
                   jobs: int = 1, init: Seq2SeqEnsemble | None = None
                   ) -> tuple[Seq2SeqEnsemble, list[FitReport]]:
    """``cfg.ensemble`` members with seeds ``cfg.seed + k`` (see :func:`train_seq2seq`).

    ``jobs`` > 1: one worker process per member, confined to ``jobs`` CPUs
    (:func:`blindspot.parallel.parallel_map`); each member is trained on ``cfg.threads``
    threads either way, so its weights are the same bits as in this process. ``progress`` is
    called in this process only (``jobs`` = 1). ``init``: member ``k`` starts from ``init``'s
    member ``k`` (fine-tuning); it must hold ``cfg.ensemble`` members (ValueError)."""
    seeds = [cfg.seed + k for k in range(cfg.ensemble)]
    if init is not None and len(init.members) != len(seeds):
        raise ValueError(f"train_ensemble: init holds {len(init.members)} members, "
                         f"cfg.ensemble = {len(seeds)}")
    starts = [None] * len(seeds) if init is None else list(init.members)
    if jobs <= 1 or len(seeds) == 1:
        runs = [train_seq2seq(train_xy, val_xy, cfg, seed=s, name=name, progress=progress,
                              train_nb=train_nb, val_nb=val_nb, init=m0)
                for s, m0 in zip(seeds, starts)]
    else:
        from functools import partial

        from blindspot.parallel import parallel_map

        runs = parallel_map(partial(_train_member, train_xy, val_xy, cfg, name, train_nb,
                                    val_nb), list(zip(seeds, starts)), len(seeds),
                            cpus=int(jobs))
    return Seq2SeqEnsemble([m for m, _ in runs], name=name), [r for _, r in runs]


def _train_member(train_xy: np.ndarray, val_xy: np.ndarray, cfg: Seq2SeqConfig, name: str,
                  train_nb: np.ndarray | None, val_nb: np.ndarray | None,
                  member: tuple[int, Seq2SeqModel | None]) -> tuple[Seq2SeqModel, FitReport]:
    """One member in a worker process (module level, so it pickles)."""
    seed, init = member
    return train_seq2seq(train_xy, val_xy, cfg, seed=seed, name=name, train_nb=train_nb,
                         val_nb=val_nb, init=init)


# what the weights compute (Seq2SeqNet's shapes, and the frame and encoding of its inputs and
# outputs); the rest are training settings a fine-tuning may change
_ARCHITECTURE = ("cell", "hidden_size", "num_layers", "head_hidden", "obs_len", "horizon",
                 "inputs", "outputs", "frame", "residual", "speed_floor", "neighbours", "modes",
                 "basis_rank")


def _check_architecture(have: Seq2SeqConfig, want: Seq2SeqConfig, who: str) -> None:
    keys = _ARCHITECTURE + (("attention_heads",) if want.cell == "transformer" else ())
    diff = [k for k in keys if getattr(have, k) != getattr(want, k)]
    if diff:
        raise ValueError(f"{who}: made with another " + ", ".join(
            f"{k} ({getattr(have, k)!r}, expected {getattr(want, k)!r})" for k in diff))
