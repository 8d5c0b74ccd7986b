"""The ETH/UCY benchmark protocol: CVM, Kalman and the learned predictors scored by ADE / FDE.

:func:`run_benchmark` takes :class:`EthUcySettings` (the ``ethucy`` config group, typed, resolved
by :meth:`EthUcySettings.from_config`: change it with Hydra overrides, e.g. ``python -m blindspot
ethucy ethucy.models=[cvm] ethucy.folds=[eth]``) and returns a :class:`BenchmarkRun`: the results dict of
``reports/metrics/ethucy.json`` and what each model fitted per fold. Nothing is written here; the
Markdown page is :mod:`blindspot.report.ethucy_report`'s.

Protocol (see ``blindspot.traj.ethucy``): observe 8 positions (3.2 s), predict 12 (4.8 s),
leave-one-scene-out folds eth/hotel/univ/zara1/zara2, Social-GAN windows; every model that learns
anything learns it from its fold's ``train`` split (and ``val`` for the LSTM's validation) only.

* ``cvm``: constant velocity from the last two observed positions (Schöller et al. 2020).
* ``kalman``: constant-velocity Kalman filter, process noise fitted on the fold's train windows
  to minimise their 8 -> 12 ADE (``KalmanCV.fit(objective="forecast")``).
* ``lstm``: the direct multi-step predictor (:mod:`blindspot.traj.seq2seq`) with an LSTM
  encoder: 8 observed positions in, all 12 future positions out with a Gaussian per step,
  trained on the fold's train split (every fully observed 20-frame stretch of every pedestrian)
  on the 8 -> 12 ADE, the epoch kept by the val split's ADE; an ensemble of seeds.
* ``gru``: the same predictor with a GRU encoder (Cho et al. 2014) instead of the LSTM.
* ``mlp``: the same predictor with a dense (MLP) encoder instead of the LSTM.
* ``mix``: the multi-modal predictor: the same predictor (encoder ``mix_cell``) with
  ``mix_modes`` hypotheses and their probabilities (:mod:`blindspot.traj.mixture`); its single
  prediction is the mixture's mean or its most probable hypothesis, whichever has the lower
  ADE on the fold's val split; scored also best-of-N (N = its hypotheses) and as a mixture
  (NLL, coverage of its highest-density regions).
* ``lstm_rollout``: the project's next-point LSTM with a window of 8, trained on every fully
  observed 9-frame stretch (8 in, 1 out) of the fold's train split, validated on the val split,
  rolled out 12 steps (today's paper model; slow, kept for the ablation).

Seeds: every learned model is trained ``seeds`` times (seeds ``seed, seed + 1, ...``); its
ADE / FDE per fold are the mean over the seeds, and the distributions are scored for the first
seed's network.

Results ``{model: {fold: {"ade", "fde", "n_windows"}, ..., "avg": {"ade", "fde"}}, "best":
model, "seeds": {model: {"ade_mean", "fde_mean", "ade_sd", "fde_sd", "n"}}, "best_of_20":
{model: {fold: {"ade", "fde"}, "avg": {"ade", "fde"}}}}`` (avg = unweighted mean over the folds
run, as in the literature; ``best`` = the model with the lowest average ADE on the folds' *val*
splits, so the choice never looks at a test scene; ``seeds``: the mean and sample standard
deviation over the seeds of each learned model's fold-averaged ADE / FDE; ``best_of_20``: the
multi-modal models' best-of-20 scores, seed mean).

Predictive distributions (issue 10, section 2): every model but ``lstm_rollout`` gives a
:class:`~blindspot.traj.distribution.GaussianForecast` (cvm: :class:`CVNoise` fitted on the
fold's val split; kalman: its own propagated covariance; lstm/gru/mlp/transformer: the Gaussian
head and the ensemble spread). Each is calibrated on the fold's val split, never on test
(``calibration`` of :func:`run_fold`: a per-step covariance scale,
:func:`~blindspot.traj.distribution.fit_step_scale`; a per-step scale mixture; or, the stage's
setting, one such mixture per class of observed speed,
:func:`~blindspot.traj.distribution.fit_conditional_scale_mixture`) and scored on the test scene:
coverage of the 50/90/95 % ellipses and the NLL (:func:`calibration_scores`), beside the
online ellipses (sliding-window conformal or scale tracking) of :func:`online_coverage`.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from blindspot.traj.baselines import ConstantVelocity, KalmanCV
from blindspot.traj.config import ETHUCY_MODELS, EthUcyConfig, RolloutLSTMConfig, Seq2SeqConfig
from blindspot.traj.conformal import (AdaptiveConformal, OnlineEllipses,
                                      held_out_choice_coverage)
from blindspot.traj.distribution import (
    ConditionalScaleMixture,
    GaussianForecast,
    ScaleMixture,
    ellipse_coverage,
    fit_conditional_scale_mixture,
    fit_scale_mixture,
    fit_step_scale,
    gaussian_nll,
    mahalanobis_sq,
    observed_speed,
)
from blindspot.traj.ethucy import (
    FOLDS,
    FRAME_PERIOD_S,
    OBS_LEN,
    PRED_LEN,
    Windows,
    load_split,
    random_rotations,
)
from blindspot.traj.metrics import ade, fde
from blindspot.traj.online import online_candidates
from blindspot.traj.predictor import (
    HeadingFrameRollout,
    MeanNextPoint,
    NextPointRollout,
    PathPredictor,
    heading_frame_pairs,
)

__all__ = [
    "MODELS",
    "EthUcySettings",
    "FoldOutcome",
    "BenchmarkRun",
    "score",
    "calibration_scores",
    "online_coverage",
    "train_fold_seq2seq",
    "seq2seq_config",
    "choose_point",
    "mixture_scores",
    "seed_spread",
    "lstm_window_set",
    "train_fold_lstm",
    "val_windows",
    "run_fold",
    "benchmark_items",
    "summarise",
    "calibration_table",
    "run_benchmark",
]

MODELS: tuple[str, ...] = ETHUCY_MODELS
#: models that give a predictive distribution (scored for calibration)
PROBABILISTIC: tuple[str, ...] = ("cvm", "kalman", "lstm", "gru", "mlp", "transformer", "mix")
#: ellipse levels of ``calibration.json``
CALIBRATION_LEVELS: tuple[float, ...] = (0.5, 0.9, 0.95)
#: nominal levels of the reliability curve (figure)
RELIABILITY_LEVELS: tuple[float, ...] = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 0.99)
MIXTURE_COMPONENTS = 3
#: class edges of the observed speed (m/s, mean of the last two steps) for "conditional":
#: standing (< 0.2), slow, walking, brisk, fast (> 1.4; the preferred walking speed is about
#: 1.3-1.4 m/s, Bohannon 1997, "Comfortable and maximum walking speed of adults aged 20-79")
SPEED_EDGES_M_S: tuple[float, ...] = (0.2, 0.6, 1.0, 1.4)
#: encoder of each direct-predictor model key
SEQ2SEQ_CELL: dict[str, str] = {"lstm": "lstm", "gru": "gru", "mlp": "mlp",
                                 "transformer": "transformer", "mix": "mlp"}
#: hypotheses of the best-of-N score (the field's best-of-20)
BEST_OF = 20


@dataclass(frozen=True)
class EthUcySettings:
    """What one benchmark run does: the typed ``ethucy`` group (:class:`EthUcyConfig`, which
    checks every value) resolved by :meth:`from_config` (paths, seeds, candidate ellipses).

    Attributes:
        data_dir: the folder holding ``eth/ hotel/ univ/ zara1/ zara2/``.
        models: models to score, a subset of :data:`MODELS` (in this order in the results).
        folds: test folds, a subset of :data:`~blindspot.traj.ethucy.FOLDS`.
        lstm: the next-point LSTM's settings (``"lstm_rollout"``).
        seq2seq: the direct predictor's settings (``"lstm"``, ``"gru"``, ``"mlp"``,
            ``"transformer"``, ``"mix"``; the cell is set by the model key).
        calibration: how forecasts are calibrated on the val split: ``"mle"`` or
            ``"quantile"`` (a per-step scale, :func:`fit_step_scale`), ``"mixture"`` (a
            per-step scale mixture, :func:`fit_scale_mixture`) or ``"conditional"`` (one
            mixture per class of observed speed, :func:`fit_conditional_scale_mixture`).
        speed_edges: the classes' observed-speed edges for ``"conditional"``, m/s.
        online: candidate settings of the online ellipses scored beside the val calibration
            (:class:`~blindspot.traj.conformal.AdaptiveConformal`,
            :class:`~blindspot.traj.scale_tracker.ScaleTracker`: each test scene a stream
            whose revealed outcomes keep the ellipses calibrated;
            ``online_coverage_*``); each fold and model chooses one on its own val scenes
            (:func:`online_coverage`).
        seeds: seeds per learned model (``seq2seq.seed``, + 1, ...).
        mix_cell, mix_modes: the encoder and hypotheses of ``mix``.
    """

    data_dir: Path
    models: tuple[str, ...] = MODELS
    folds: tuple[str, ...] = FOLDS
    lstm: RolloutLSTMConfig = field(default_factory=RolloutLSTMConfig)
    seq2seq: Seq2SeqConfig = field(default_factory=Seq2SeqConfig)
    calibration: str = "mixture"
    speed_edges: tuple[float, ...] = SPEED_EDGES_M_S
    online: tuple[OnlineEllipses, ...] = field(
        default_factory=lambda: (AdaptiveConformal(CALIBRATION_LEVELS),))
    seeds: int = 1
    mix_cell: str = "mlp"
    mix_modes: int = BEST_OF

    def __post_init__(self) -> None:
        object.__setattr__(self, "data_dir", Path(self.data_dir))

    @classmethod
    def from_config(cls, config: EthUcyConfig, *, shared_dir: str | Path,
                    seed: int) -> EthUcySettings:
        """From the typed ``ethucy`` config group (:class:`~blindspot.traj.config.EthUcyConfig`,
        validated there): ``data`` relative to ``shared_dir`` (or absolute), the models, the
        folds, the calibration method, the direct predictor's and the next-point LSTM's settings
        (``seq2seq``, ``lstm_rollout``) and the torch threads; ``seed`` (the config's top-level
        seed) is every learned model's first seed."""
        return cls(data_dir=Path(shared_dir) / config.data, models=tuple(config.models),
                   folds=tuple(config.folds),
                   lstm=replace(config.lstm_rollout, seed=int(seed), num_threads=config.threads),
                   seq2seq=replace(config.seq2seq, seed=int(seed), threads=config.threads),
                   calibration=config.calibration,
                   speed_edges=tuple(config.calibration_speed_edges),
                   online=online_candidates(config, CALIBRATION_LEVELS),
                   seeds=config.seeds, mix_cell=config.mix_cell, mix_modes=config.mix_modes)


@dataclass
class FoldOutcome:
    """Scores of one model on one fold plus what was fitted (for the report)."""

    ade: float
    fde: float
    n_windows: int
    seconds: float
    fitted: dict[str, Any] = field(default_factory=dict)
    calibration: dict[str, Any] | None = None


def _context(predictor: Any, windows: Windows) -> dict[str, Any]:
    """The keyword arguments giving a predictor that reads neighbours the windows' ones."""
    if getattr(predictor, "uses_neighbours", False):
        if windows.neighbours is None:
            raise ValueError(f"{predictor.name}: reads neighbours; load the windows with "
                             "load_split(..., neighbours=K)")
        return {"neighbours": windows.neighbours}
    return {}


def score(predictor: PathPredictor, test: Windows, obs_len: int = OBS_LEN,
          pred_len: int = PRED_LEN) -> tuple[float, float]:
    """ADE and FDE (m) of ``predictor`` on test windows (N, obs_len + pred_len, 2) (with
    their neighbours when the predictor reads them)."""
    pred = predictor.predict(test.observed(obs_len), pred_len, **_context(predictor, test))
    truth = test.future(obs_len)
    return ade(pred, truth), fde(pred, truth)


def lstm_window_set(data_dir: Path, fold: str, split: str, s: RolloutLSTMConfig, *,
                    augment: bool = True):
    """Next-point windows (8 in -> 1 out) of a fold's split as a ``WindowSet``.

    Every fully observed 9-frame stretch of every pedestrian (no minimum-neighbour filter: the
    LSTM sees one pedestrian at a time). In the heading frame the pairs come from
    :func:`~blindspot.traj.predictor.heading_frame_pairs` (mirrored copies when ``augment`` and
    ``s.mirror``); in the world frame ``s.rotations`` random rotations are added when
    ``augment``.
    """
    from blindspot.traj.windows import WindowSet

    w = load_split(data_dir, fold, split, seq_len=OBS_LEN + 1, min_peds=1)
    xy, pid = w.xy, w.track_id
    if s.frame == "heading":
        mirror = augment and s.mirror
        x, y = heading_frame_pairs(xy, residual=s.residual, mirror=mirror,
                                   speed_floor=s.speed_floor)
        return WindowSet(x=x, y=y, path_id=np.tile(pid, 2) if mirror else pid)
    if augment and s.rotations:
        xy = np.concatenate([xy, random_rotations(xy, s.rotations, np.random.default_rng(s.seed))])
        pid = np.tile(pid, s.rotations + 1)
    return WindowSet(x=xy[:, :OBS_LEN], y=xy[:, OBS_LEN], path_id=pid)


def train_fold_lstm(data_dir: Path, fold: str, s: RolloutLSTMConfig, progress: bool
                    ) -> tuple[PathPredictor, float, int, int]:
    """Train the LSTM on a fold's train split (validated on its val split).

    Returns:
        ``(predictor, val_rmse_m, n_train, n_val)``: the predictor to score (the LSTM itself,
        or the LSTM / ensemble mean wrapped in a rollout), the one-step
        validation RMSE in metres per coordinate (mean over ensemble members), and the window
        counts.
    """
    from blindspot.traj.lstm import LSTMConfig
    from blindspot.traj.train import TrainConfig, train_lstm

    train = lstm_window_set(data_dir, fold, "train", s)
    val = lstm_window_set(data_dir, fold, "val", s, augment=False)
    model_cfg = LSTMConfig(window=OBS_LEN, hidden_size=s.hidden_size, num_layers=s.num_layers,
                           head_hidden=s.head_hidden, target=s.target)
    train_cfg = TrainConfig(epochs=s.epochs, batch_size=s.batch_size, lr=s.lr, seed=s.seed,
                            num_threads=s.num_threads)
    results = [train_lstm(train, val, model_cfg, replace(train_cfg, seed=s.seed + k),
                          progress=progress) for k in range(s.ensemble)]
    val_rmse = float(np.mean([r.val_rmse_m for r in results]))
    model = (results[0].predictor if s.ensemble == 1
             else MeanNextPoint([r.predictor for r in results]))
    predictor: PathPredictor
    if s.frame == "heading":
        predictor = HeadingFrameRollout(model, residual=s.residual, symmetric=s.mirror,
                                        speed_floor=s.speed_floor, name="lstm")
    elif s.ensemble == 1:
        predictor = results[0].predictor      # the LSTM's own rollout (fills gaps itself)
    else:
        predictor = NextPointRollout(model, name="lstm")
    return predictor, val_rmse, len(train), len(val)


def val_windows(data_dir: Path, fold: str, neighbours: int = 0) -> Windows:
    """The fold's val split under the test protocol (20-frame Social-GAN windows), with each
    window's ``neighbours`` nearest pedestrians when > 0."""
    return load_split(data_dir, fold, "val", neighbours=neighbours)


def reveal_times(start: np.ndarray, per_step: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """``(t_predicted (N,), t_revealed)`` of Social-GAN windows starting at frame rows ``start``
    (N,), frame rows of 0.4 s: a window is predicted at its last observed frame, ``start +
    OBS_LEN - 1``; step h (0-based) of its future is known at its own frame, ``t_predicted + 1
    + h`` (``per_step``; (N, PRED_LEN)), or the whole future at its last frame (N,)."""
    tp = np.asarray(start, dtype=np.int64) + OBS_LEN - 1
    if per_step:
        return tp, tp[:, None] + 1 + np.arange(PRED_LEN)
    return tp, tp + PRED_LEN


def online_coverage(online: Sequence[OnlineEllipses], val_forecast: GaussianForecast,
                    val: Windows, test_forecast: GaussianForecast, test: Windows
                    ) -> dict[str, Any]:
    """``{"online_coverage_50", ...}``: coverage on the test windows of the online ellipses
    (:class:`~blindspot.traj.conformal.AdaptiveConformal`,
    :class:`~blindspot.traj.scale_tracker.ScaleTracker`) of a forecast, with the
    setting chosen among ``online`` on the val windows alone
    (:func:`~blindspot.traj.conformal.held_out_choice_coverage`: each val scene met as a new
    scene, the fold's other val scenes its prior; with one val scene, the first candidate).
    The val scores (d^2 of ``val_forecast``) are then the test scenes' prior. Each
    test scene file is a stream; each future point is known at its own frame
    (:func:`reveal_times`); the ellipse of each window uses only the outcomes known when it
    is predicted. Also ``online_coverage_<p>_ci95`` (a bootstrap over the test pedestrians,
    ``track_id``), the setting chosen (its ``setting``: ``online_method`` and its
    parameters) and its mean distance from nominal on the val scenes
    (``online_val_distance``).

    A fold's val scenes never include its own test recording (the tails of the *other*
    folds' test recordings they do hold are not this fold's test scene), so the choice never
    looks at the scene it is scored on. Constant velocity's noise model is fitted on all the
    val scenes, the held-out one included, so its val distances are somewhat optimistic."""
    d2_val = mahalanobis_sq(val_forecast, val.future())
    d2 = mahalanobis_sq(test_forecast, test.future())
    out, _ = held_out_choice_coverage(
        online, (d2_val, *reveal_times(val.start), val.file_index),
        (d2, *reveal_times(test.start), test.file_index), clusters=test.track_id)
    return out


def calibration_scores(forecast: GaussianForecast, truth: np.ndarray,
                       mixture: ScaleMixture | ConditionalScaleMixture | None = None,
                       feature: np.ndarray | None = None) -> dict[str, Any]:
    """``{"coverage_50", "coverage_90", "coverage_95", "nll", "reliability": {"levels",
    "coverage"}}`` of a forecast (B, H) against truth (B, H, 2): ellipse coverage at
    :data:`CALIBRATION_LEVELS` and :data:`RELIABILITY_LEVELS`, mean NLL (nats per point) -
    of the Gaussian forecast itself, or with ``mixture`` of its scale mixture (a
    :class:`ConditionalScaleMixture` reads each track's ``feature`` (B,))."""
    if isinstance(mixture, ConditionalScaleMixture):
        cov = mixture.coverage(forecast, truth, feature, CALIBRATION_LEVELS)
        rel = mixture.coverage(forecast, truth, feature, RELIABILITY_LEVELS)
        nll = mixture.nll(forecast, truth, feature)
    elif mixture is not None:
        cov = mixture.coverage(forecast, truth, CALIBRATION_LEVELS)
        rel = mixture.coverage(forecast, truth, RELIABILITY_LEVELS)
        nll = mixture.nll(forecast, truth)
    else:
        cov = ellipse_coverage(forecast, truth, CALIBRATION_LEVELS)
        rel = ellipse_coverage(forecast, truth, RELIABILITY_LEVELS)
        nll = gaussian_nll(forecast, truth)
    out: dict[str, Any] = {f"coverage_{round(100 * lv)}": float(c)
                           for lv, c in zip(CALIBRATION_LEVELS, cov)}
    out["nll"] = float(nll)
    out["reliability"] = {"levels": list(RELIABILITY_LEVELS), "coverage": [float(c) for c in rel]}
    return out


def train_fold_seq2seq(data_dir: Path, fold: str, cfg: Seq2SeqConfig, name: str,
                       progress: bool = False, *, train: Windows | None = None,
                       val: Windows | None = None):
    """Train the direct predictor's ensemble on a fold's train split, keeping each member's
    epoch with the lowest ADE on the fold's val split (Social-GAN windows).

    Training windows: every fully observed 20-frame stretch of every pedestrian of the train
    split (no neighbour filter: the model sees one pedestrian at a time), at each of
    ``cfg.time_steps`` (:func:`~blindspot.traj.ethucy.resample_tracks`).

    Returns:
        ``(ensemble, fitted)``: the :class:`~blindspot.traj.seq2seq.Seq2SeqEnsemble` and what
        the report shows (members' kept epochs, training windows, seconds). ``train`` /
        ``val``: the fold's windows when already loaded (as this function loads them).
    """
    from blindspot.traj.seq2seq import train_ensemble

    if train is None:
        train = load_split(data_dir, fold, "train", min_peds=1, neighbours=cfg.neighbours,
                           time_steps=cfg.time_steps)
    if val is None:
        val = val_windows(data_dir, fold, cfg.neighbours)
    say = (lambda line: print(f"[{fold}] {line}", flush=True)) if progress else None
    ens, reports = train_ensemble(train.xy, val.xy, cfg, name=name, progress=say,
                                  train_nb=train.neighbours, val_nb=val.neighbours)
    fitted = {"best_epochs": [r.best_epoch for r in reports], "n_train_windows": len(train),
              "n_val_windows": len(val), "train_seconds": float(sum(r.seconds for r in reports))}
    return ens, fitted


def seq2seq_config(seq2seq: Seq2SeqConfig, name: str, mix_cell: str = "mlp",
                   mix_modes: int = BEST_OF) -> Seq2SeqConfig:
    """The direct predictor's settings for model key ``name``: its encoder, and for ``mix``
    ``mix_cell`` with ``mix_modes`` hypotheses."""
    if name not in SEQ2SEQ_CELL:
        raise ValueError(f"name: expected one of {tuple(SEQ2SEQ_CELL)}, found {name!r}")
    if name == "mix":
        return replace(seq2seq, cell=mix_cell, modes=int(mix_modes))
    return replace(seq2seq, cell=SEQ2SEQ_CELL[name], modes=1)


def choose_point(ens: Any, val: Windows) -> str:
    """``"mean"`` or ``"mode"``: which single prediction of a multi-modal ``ens`` (one member)
    has the lower ADE on the val windows (the mixture's mean, or its most probable
    hypothesis); the member is left predicting that one."""
    model = ens.members[0]
    mix = model.predict_mixture(val.observed(), PRED_LEN, neighbours=val.neighbours)
    truth = val.future()
    point = "mode" if ade(mix.most_likely(), truth) < ade(mix.mean(), truth) else "mean"
    model.point = point
    return point


def mixture_scores(model: Any, test: Windows, n: int = BEST_OF) -> dict[str, Any]:
    """Best-of-``n`` ADE / FDE (m) of a multi-modal model's ``n`` most probable hypotheses on
    the test windows and, of its whole mixture, the NLL (nats per point) and the coverage of
    the 50/90/95 % highest-density regions (uncalibrated; :mod:`blindspot.traj.mixture`)."""
    from blindspot.traj.mixture import best_of

    mix = model.predict_mixture(test.observed(), PRED_LEN, neighbours=test.neighbours)
    means = mix.most_probable(min(n, mix.modes))
    b_ade, b_fde = best_of(means, test.future())
    cov = mix.coverage(test.future(), CALIBRATION_LEVELS)
    return {"best_of_ade": b_ade, "best_of_fde": b_fde, "best_of_n": int(means.shape[1]),
            "mixture_nll": mix.nll(test.future()),
            **{f"mixture_coverage_{round(100 * lv)}": float(c)
               for lv, c in zip(CALIBRATION_LEVELS, cov)}}


def _train_seeds(data_dir: Path, fold: str, cfg: Seq2SeqConfig, name: str, seeds: int,
                 progress: bool, val: Windows, test: Windows) -> tuple[Any, dict[str, Any]]:
    """Train ``name`` with ``seeds`` seeds (``cfg.seed`` + k) on the fold; score each on test
    and val. Returns the first seed's predictor and ``fitted`` with the per-seed rows
    (``seed_scores``) and their mean test ADE / FDE (``ade``, ``fde``)."""
    train = load_split(data_dir, fold, "train", min_peds=1, neighbours=cfg.neighbours,
                       time_steps=cfg.time_steps)
    rows, first, fitted = [], None, {}
    for k in range(seeds):
        ens, fit = train_fold_seq2seq(data_dir, fold, replace(cfg, seed=cfg.seed + k), name,
                                      progress, train=train, val=val)
        row: dict[str, Any] = {"seed": cfg.seed + k, "best_epochs": fit["best_epochs"]}
        if cfg.modes > 1:
            row["point"] = choose_point(ens, val)
            row.update(mixture_scores(ens.members[0], test))
        row["ade"], row["fde"] = score(ens, test)
        row["val_ade"], row["val_fde"] = score(ens, val)
        rows.append(row)
        if first is None:
            first, fitted = ens, fit
    fitted = {**fitted, "seed_scores": rows,
              "val_ade_m": float(np.mean([r["val_ade"] for r in rows])),
              "val_fde_m": float(np.mean([r["val_fde"] for r in rows]))}
    return first, fitted


def run_fold(data_dir: Path, fold: str, models: Sequence[str], lstm: RolloutLSTMConfig,
             progress: bool = True, seq2seq: Seq2SeqConfig | None = None,
             calibration: str = "mixture",
             speed_edges: Sequence[float] = SPEED_EDGES_M_S,
             online: Sequence[OnlineEllipses] | None = None, *, seeds: int = 1,
             mix_cell: str = "mlp", mix_modes: int = BEST_OF) -> dict[str, FoldOutcome]:
    """Evaluate the requested models on one fold: ADE/FDE on test and val, and (models with a
    distribution) calibration on test after a calibration fitted on val, and the coverage of
    the online ellipses of the setting chosen among ``online`` on val
    (:func:`online_coverage`; default: :class:`AdaptiveConformal`'s settings alone).

    The direct predictors (``lstm``, ``gru``, ``mlp``, ``mix``) are trained with ``seeds``
    seeds; their ADE / FDE are the seeds' mean (``fitted["seed_scores"]`` each seed's), their
    distributions the first seed's."""
    online = tuple(online) if online else (AdaptiveConformal(CALIBRATION_LEVELS),)
    seq2seq = seq2seq if seq2seq is not None else Seq2SeqConfig()
    k = seq2seq.neighbours if any(m in SEQ2SEQ_CELL for m in models) else 0
    test = load_split(data_dir, fold, "test", neighbours=k)
    val = val_windows(data_dir, fold, k)
    speed = {"val": observed_speed(val.observed(), FRAME_PERIOD_S),
             "test": observed_speed(test.observed(), FRAME_PERIOD_S)}
    out: dict[str, FoldOutcome] = {}
    for name in models:
        t0 = time.perf_counter()
        fitted: dict[str, Any] = {}
        if name == "cvm":
            predictor: Any = ConstantVelocity().fit(val.observed(), val.future())
            fitted = {"noise_beta": predictor.noise.beta.tolist()}
        elif name == "kalman":
            train = load_split(data_dir, fold, "train")
            predictor = KalmanCV().fit(train.xy, objective="forecast", obs_len=OBS_LEN)
            fitted = {"process_psd_m2_s3": predictor.process_psd, "meas_std_m": predictor.meas_std}
        elif name in SEQ2SEQ_CELL:
            predictor, fitted = _train_seeds(
                data_dir, fold, seq2seq_config(seq2seq, name, mix_cell, mix_modes), name,
                int(seeds), progress, val, test)
        elif name == "lstm_rollout":
            predictor, val_rmse, n_train, n_val = train_fold_lstm(data_dir, fold, lstm, progress)
            fitted = {"val_rmse_m": val_rmse, "n_train_windows": n_train, "n_val_windows": n_val}
        else:  # guarded by EthUcyConfig
            raise ValueError(f"models: expected a subset of {MODELS}, found {name!r}")
        if "seed_scores" in fitted:      # the seeds' mean
            a, f = (float(np.mean([r[k] for r in fitted["seed_scores"]])) for k in ("ade", "fde"))
        else:
            a, f = score(predictor, test)
            fitted["val_ade_m"], fitted["val_fde_m"] = score(predictor, val)
        calib = None
        if name in PROBABILISTIC:
            raw_val = predictor.predict_distribution(val.observed(), PRED_LEN,
                                                     **_context(predictor, val))
            raw_test = predictor.predict_distribution(test.observed(), PRED_LEN,
                                                      **_context(predictor, test))
            if calibration == "conditional":
                cmix = fit_conditional_scale_mixture(raw_val, val.future(), speed["val"],
                                                     speed_edges, n_components=MIXTURE_COMPONENTS)
                fitted["conditional_mixture"] = cmix.to_dict()
                calib = calibration_scores(raw_test, test.future(), cmix, speed["test"])
            elif calibration == "mixture":
                mix = fit_scale_mixture(raw_val, val.future(), n_components=MIXTURE_COMPONENTS)
                fitted["mixture"] = {"weights": mix.weights.tolist(),
                                     "scales": mix.scales.tolist()}
                calib = calibration_scores(raw_test, test.future(), mix)
            else:
                scale = fit_step_scale(raw_val, val.future(), method=calibration)
                fitted["step_scale"] = [float(x) for x in scale]
                calib = calibration_scores(raw_test.scaled(scale), test.future())
            calib["uncalibrated"] = {k: v for k, v in calibration_scores(
                raw_test, test.future()).items() if k != "reliability"}
            calib.update(online_coverage(online, raw_val, val, raw_test, test))
        out[name] = FoldOutcome(a, f, len(test), time.perf_counter() - t0, fitted, calib)
    return out


@dataclass(frozen=True)
class BenchmarkRun:
    """One benchmark run.

    Attributes:
        settings: what was run.
        per_fold: ``{fold: {model: FoldOutcome}}``.
        results: :func:`summarise` of ``per_fold``, the content of ``reports/metrics/ethucy.json``.
        seconds: wall time of the run.
    """

    settings: EthUcySettings
    per_fold: dict[str, dict[str, FoldOutcome]]
    results: dict[str, dict[str, dict[str, float]]]
    seconds: float

    def details(self) -> dict[str, dict[str, dict[str, Any]]]:
        """``{fold: {model: {"ade", "fde", "n_windows", "seconds", "fitted"}}}`` as plain dicts
        (what :func:`blindspot.report.ethucy_report.format_report` reads)."""
        return {fold: {m: asdict(o) for m, o in rows.items()} for fold, rows in self.per_fold.items()}

    def validation(self) -> dict[str, dict[str, dict[str, float]]]:
        """The scores on each fold's val split, shaped like :attr:`results`:
        ``{model: {fold: {"ade", "fde"}, "avg": {"ade", "fde"}}}`` (avg: unweighted mean)."""
        out: dict[str, dict[str, dict[str, float]]] = {}
        for m in self.settings.models:
            rows = {f: {"ade": r[m].fitted["val_ade_m"], "fde": r[m].fitted["val_fde_m"]}
                    for f, r in self.per_fold.items()}
            rows["avg"] = {k: float(np.mean([v[k] for v in rows.values()])) for k in ("ade", "fde")}
            out[m] = rows
        return out


def summarise(per_fold: dict[str, dict[str, FoldOutcome]], models: Sequence[str]
              ) -> dict[str, Any]:
    """JSON-ready ``{model: {fold: {ade, fde, n_windows}, "avg": {ade, fde}}, "best": model}``;
    ``best`` is the model with the lowest mean *val* ADE over the folds (FDE breaks a tie), so
    naming it never looks at a test scene."""
    out: dict[str, Any] = {}
    for m in models:
        rows = {fold: {"ade": r[m].ade, "fde": r[m].fde, "n_windows": r[m].n_windows}
                for fold, r in per_fold.items()}
        rows["avg"] = {"ade": float(np.mean([v["ade"] for v in rows.values()])),
                       "fde": float(np.mean([v["fde"] for v in rows.values()]))}
        out[m] = rows
    val = {m: (float(np.mean([r[m].fitted["val_ade_m"] for r in per_fold.values()])),
               float(np.mean([r[m].fitted["val_fde_m"] for r in per_fold.values()])))
           for m in models}
    out["best"] = min(models, key=lambda m: val[m])
    seeded = [m for m in models
              if all("seed_scores" in r[m].fitted for r in per_fold.values())]
    if seeded:
        out["seeds"] = {m: seed_spread(per_fold, m) for m in seeded}
    multi = [m for m in seeded if all("best_of_ade" in row for r in per_fold.values()
                                      for row in r[m].fitted["seed_scores"])]
    for m in multi:        # keyed by the hypotheses scored (BEST_OF unless a model has fewer)
        n = min(row["best_of_n"] for r in per_fold.values() for row in r[m].fitted["seed_scores"])
        out.setdefault(f"best_of_{n}", {})[m] = _best_of_rows(per_fold, m)
    return out


def seed_spread(per_fold: dict[str, dict[str, FoldOutcome]], model: str) -> dict[str, Any]:
    """``{"ade_mean", "fde_mean", "ade_sd", "fde_sd", "n", "ade", "fde"}`` of a model trained
    with several seeds: each seed's ADE / FDE averaged over the folds (``ade``, ``fde``: lists
    in seed order), their mean and sample standard deviation (0 with one seed)."""
    rows = [r[model].fitted["seed_scores"] for r in per_fold.values()]
    n = len(rows[0])
    if any(len(x) != n for x in rows):
        raise ValueError(f"per_fold: {model!r} was trained with different seed counts per fold "
                         f"({[len(x) for x in rows]})")
    out: dict[str, Any] = {"n": n}
    for k in ("ade", "fde"):
        per_seed = [float(np.mean([x[i][k] for x in rows])) for i in range(n)]
        out[k] = per_seed
        out[f"{k}_mean"] = float(np.mean(per_seed))
        out[f"{k}_sd"] = float(np.std(per_seed, ddof=1)) if n > 1 else 0.0
    return out


def _best_of_rows(per_fold: dict[str, dict[str, FoldOutcome]], model: str) -> dict[str, Any]:
    """``{fold: {"ade", "fde"}, "avg": {...}, "sd": {...}}``: a multi-modal model's best-of-N
    scores per fold (seed mean), their unweighted fold average and its sd over the seeds."""
    out: dict[str, Any] = {}
    per_seed: dict[str, list[list[float]]] = {"ade": [], "fde": []}
    for fold, r in per_fold.items():
        rows = r[model].fitted["seed_scores"]
        out[fold] = {k: float(np.mean([x[f"best_of_{k}"] for x in rows])) for k in ("ade", "fde")}
        for k in ("ade", "fde"):
            per_seed[k].append([x[f"best_of_{k}"] for x in rows])
    out["avg"] = {k: float(np.mean([out[f][k] for f in per_fold])) for k in ("ade", "fde")}
    fold_avg = {k: np.mean(np.array(v), axis=0) for k, v in per_seed.items()}   # (seeds,)
    out["sd"] = {k: float(np.std(v, ddof=1)) if len(v) > 1 else 0.0
                 for k, v in fold_avg.items()}
    return out


def calibration_table(per_fold: dict[str, dict[str, FoldOutcome]], *, reliability: bool = False
                      ) -> dict[str, dict[str, dict[str, Any]]]:
    """``{method: {fold: {"coverage_50", "coverage_90", "coverage_95", "nll"}}}`` of the models
    with a distribution (the shape of ``reports/metrics/calibration.json``); with
    ``reliability`` each fold also holds ``{"levels", "coverage"}`` of the reliability curve
    and the uncalibrated scores."""
    out: dict[str, dict[str, dict[str, Any]]] = {}
    for fold, rows in per_fold.items():
        for m, o in rows.items():
            if o.calibration is None:
                continue
            keep = {k: v for k, v in o.calibration.items()
                    if reliability or k not in ("reliability", "uncalibrated")}
            out.setdefault(m, {})[fold] = keep
    return out


#: relative training cost of each model on a fold (the learned ones dominate): the order in which
#: run_benchmark hands (fold, model) items to the workers, costliest first
_COST_RANK: dict[str, int] = {"lstm_rollout": 0, "transformer": 1, "lstm": 2, "gru": 3, "mix": 4,
                               "mlp": 5, "kalman": 6, "cvm": 7}


def benchmark_items(models: Sequence[str], folds: Sequence[str]) -> list[tuple[str, str]]:
    """The (fold, model) work items of a run, costliest model first (longest-processing-time
    order: the workers take the next item as they free up, so the cheap items fill the gaps
    at the end instead of one fold's training holding a core alone)."""
    ranked = sorted(models, key=lambda m: (_COST_RANK.get(m, -1), list(models).index(m)))
    return [(fold, m) for m in ranked for fold in folds]


def _run_item(item: tuple[str, str], *, data_dir: Path, lstm: RolloutLSTMConfig,
              progress: bool, seq2seq: Seq2SeqConfig, calibration: str,
              speed_edges: Sequence[float], online: Sequence[OnlineEllipses],
              seeds: int = 1, mix_cell: str = "mlp", mix_modes: int = BEST_OF) -> FoldOutcome:
    """One model on one fold (module level, so it pickles): :func:`run_fold` with that model."""
    fold, model = item
    return run_fold(data_dir, fold, (model,), lstm, progress=progress, seq2seq=seq2seq,
                    calibration=calibration, speed_edges=speed_edges, online=online,
                    seeds=seeds, mix_cell=mix_cell, mix_modes=mix_modes)[model]


def run_benchmark(settings: EthUcySettings, *, progress: bool = True,
                  jobs: int = 1) -> BenchmarkRun:
    """Score every model of ``settings`` on every fold (in the settings' order).

    ``jobs`` worker processes run the (fold, model) items side by side (:func:`benchmark_items`;
    each model is trained and scored on its own, seeded by the settings alone, so the scores
    do not depend on ``jobs`` or on which other models run; the per-fold progress bars are off
    when ``jobs`` > 1).

    Raises:
        EthUcyDataError: a fold's folder is missing or a scene file is malformed.
    """
    from blindspot.parallel import parallel_map

    t0 = time.perf_counter()
    items = benchmark_items(settings.models, settings.folds)
    work = partial(_run_item, data_dir=settings.data_dir, lstm=settings.lstm,
                   progress=progress and jobs <= 1, seq2seq=settings.seq2seq,
                   calibration=settings.calibration, speed_edges=settings.speed_edges,
                   online=settings.online, seeds=settings.seeds, mix_cell=settings.mix_cell,
                   mix_modes=settings.mix_modes)
    outcomes = dict(zip(items, parallel_map(work, items, jobs,
                                            progress="ETH/UCY folds x models" if progress
                                            else None)))
    per_fold = {fold: {m: outcomes[(fold, m)] for m in settings.models}
                for fold in settings.folds}
    return BenchmarkRun(settings, per_fold, summarise(per_fold, settings.models),
                        time.perf_counter() - t0)
