"""Typed configuration of the traj room: the Hydra groups ``dataset``, ``model``, ``train`` and
``eval`` as frozen dataclasses built through :mod:`blindspot.typed_config` (a bad value raises
:class:`~blindspot.typed_config.ConfigError` naming ``group.key``, the value and the allowed range).

Build them from the composed config with ``DatasetConfig.from_mapping(cfg.dataset)``,
``LSTMConfig.from_mapping(cfg.model)``, ``TrainConfig.from_mapping(cfg.train)``,
``EvalConfig.from_mapping(cfg.eval)``. :class:`PathSpec` (the path kinematics alone) is the part
of :class:`DatasetConfig` that :func:`blindspot.traj.paths.random_path_set` reads; it can be built
on its own with library defaults for tests and benchmarks.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from blindspot.typed_config import ConfigError, TypedConfig, setting

# The choices of the groups, declared here (this module imports no algorithm) and used by the
# algorithms: the ETH/UCY leave-one-scene-out folds and the gap-filling methods.
ETHUCY_FOLDS: tuple[str, ...] = ("eth", "hotel", "univ", "zara1", "zara2")
INTERPOLATION_METHODS = ("forward", "kalman", "bidirectional")

__all__ = [
    "ACTIVATIONS", "DatasetConfig", "ETHUCY_MODELS", "EthUcyConfig", "EvalConfig", "KalmanConfig",
    "LSTMConfig", "OPTIMIZERS", "OnlineCandidatesConfig",
    "PREDICTION_METHODS", "PathSpec", "SCHEDULES", "SEQ2SEQ_CELLS", "SEQ2SEQ_FRAMES",
    "SEQ2SEQ_INPUTS", "SEQ2SEQ_KEEP_BY", "SEQ2SEQ_LOSSES", "SEQ2SEQ_OUTPUTS",
    "SEQ2SEQ_WTA_SCORES", "Seq2SeqConfig", "SplitConfig", "TARGETS",
    "TrainConfig",
]

ACTIVATIONS: tuple[str, ...] = ("relu", "tanh", "identity")
TARGETS: tuple[str, ...] = ("displacement", "absolute")
OPTIMIZERS: tuple[str, ...] = ("adam", "adamw")
SCHEDULES: tuple[str, ...] = ("constant", "cosine")
PREDICTION_METHODS: tuple[str, ...] = ("lstm", "constant_velocity", "kalman")
ETHUCY_MODELS: tuple[str, ...] = ("cvm", "kalman", "lstm", "gru", "mlp", "transformer", "mix",
                                  "lstm_rollout")
SEED_MAX = 2**63 - 1     # the largest seed numpy and torch both take


# ----------------------------------------------------------------------------- dataset
@dataclass(frozen=True)
class PathSpec(TypedConfig):
    """How synthetic pedestrian paths are drawn (all SI; degrees only in ``*_deg`` names).

    Attributes:
        points_per_path: points per path (the paper: 200).
        frame_period_s: time between points, the radar frame period.
        speed_mps: [low, high] walking speed, drawn uniformly.
        start_range_m: [low, high] range of the first point, drawn uniformly.
        start_angle_deg: [low, high] bearing of the first point, drawn uniformly.
        turn_rate_deg_s: [low, high] constant turn rate of a path, drawn uniformly (positive =
            clockwise seen from above, i.e. heading turning towards +x).
        motion_weights: relative frequency of (approaching, receding, perpendicular) paths.
        heading_spread_deg: approaching/receding heading deviates from radial by up to this.
        perpendicular_spread_deg: perpendicular heading deviates from tangential by up to this.
        min_range_m, max_range_m, max_abs_angle_deg: field of view every point must stay in.
        sharp_turn_prob: share of paths that also make one sharp turn (a pedestrian turning at a
            corner, as in the paper's scenes), on top of the gentle constant turn rate.
        sharp_turn_deg: [low, high] magnitude of that turn; its sign is drawn at random.
        sharp_turn_duration_s: [low, high] time the heading takes to swing through it.

    The defaults are a generic library setting for tests and benchmarks; the experiment's values
    are in conf/dataset/ (read through :class:`DatasetConfig`, which has no defaults).
    """

    points_per_path: int = setting(200, ge=2)
    frame_period_s: float = setting(0.1, gt=0.0)
    # a walker, like the scenes' pedestrian (radar.scene.PedestrianConfig.speed_mps <= 10 m/s)
    speed_mps: tuple[float, float] = setting((0.5, 2.0), ge=0.0, le=10.0, ordered=True)
    start_range_m: tuple[float, float] = setting((5.0, 45.0), ge=0.0, ordered=True)
    start_angle_deg: tuple[float, float] = setting((-60.0, 60.0), ge=-90.0, le=90.0, ordered=True)
    turn_rate_deg_s: tuple[float, float] = setting((-4.0, 4.0), ordered=True)
    motion_weights: tuple[float, float, float] = setting(
        (1.0, 1.0, 1.0), ge=0.0, nonzero=True,
        doc="three non-negative weights (approaching, receding, perpendicular), not all 0")
    heading_spread_deg: float = setting(45.0, ge=0.0, le=90.0)
    perpendicular_spread_deg: float = setting(20.0, ge=0.0, le=90.0)
    min_range_m: float = setting(1.0, ge=0.0)
    max_range_m: float = setting(50.0, gt=0.0)
    max_abs_angle_deg: float = setting(75.0, gt=0.0, le=90.0)
    sharp_turn_prob: float = setting(0.0, ge=0.0, le=1.0)
    sharp_turn_deg: tuple[float, float] = setting((20.0, 90.0), ge=0.0, le=180.0, ordered=True)
    sharp_turn_duration_s: tuple[float, float] = setting((0.3, 1.5), ge=0.0, ordered=True)

    def validate(self) -> None:
        if not self.min_range_m < self.max_range_m:
            raise ConfigError("max_range_m", self.max_range_m, f"> min_range_m ({self.min_range_m}) >= 0")
        lo, hi = self.start_range_m
        if lo < self.min_range_m or hi > self.max_range_m:
            raise ConfigError("start_range_m", list(self.start_range_m),
                              f"inside [min_range_m, max_range_m] = [{self.min_range_m}, {self.max_range_m}]")
        if max(abs(a) for a in self.start_angle_deg) > self.max_abs_angle_deg:
            raise ConfigError("start_angle_deg", list(self.start_angle_deg),
                              f"inside +-max_abs_angle_deg ({self.max_abs_angle_deg})")

    @property
    def times_s(self) -> np.ndarray:
        """(points_per_path,) time of each point from the start of the path."""
        return np.arange(self.points_per_path) * self.frame_period_s

    def path_spec(self) -> PathSpec:
        """The path kinematics alone (a plain :class:`PathSpec`)."""
        from dataclasses import fields

        return PathSpec(**{f.name: getattr(self, f.name) for f in fields(PathSpec)})


@dataclass(frozen=True)
class SplitConfig(TypedConfig):
    """Windows per split (``dataset.split``); no path is in two splits."""

    train: int = setting(ge=0)
    val: int = setting(ge=0)
    test: int = setting(ge=0)


@dataclass(frozen=True)
class DatasetConfig(PathSpec):
    """The Hydra group ``dataset`` (conf/dataset/paper.yaml): the path kinematics (every field
    of :class:`PathSpec`) plus how many paths, how they become windows and the split.

    Attributes:
        n_paths: paths to simulate.
        window: points per input window (the paper: 50).
        stride: start of consecutive windows, in points.
        fill_gaps: "linear" (interpolate missed points before windowing) or "none".
        target: a window's response: the next "measured" point or the "truth".
        split: windows per split (train / val / test).
        seed: seed of the path draws.

    Every key is required here (conf/dataset/ is the source of truth; the :class:`PathSpec`
    defaults are only for code that draws paths without the experiment's config).
    """

    GROUP = "dataset"
    REQUIRE_ALL = True

    n_paths: int = setting(ge=1, kw_only=True)
    window: int = setting(ge=1, kw_only=True)
    stride: int = setting(ge=1, kw_only=True)
    fill_gaps: str = setting(choices=("linear", "none"), kw_only=True)
    target: str = setting(choices=("measured", "truth"), kw_only=True)
    split: SplitConfig = setting(kw_only=True)
    # seeds feed numpy and torch generators, which take at most 64-bit seeds
    seed: int = setting(ge=0, le=SEED_MAX, kw_only=True)


# ----------------------------------------------------------------------------- model, training
@dataclass(frozen=True)
class LSTMConfig(TypedConfig):
    """The Hydra group ``model``: the next-point LSTM (blindspot.traj.lstm).

    Attributes:
        window: W, points per input window (paper: 50; ETH/UCY protocol: 8).
        hidden_size: LSTM hidden units.
        num_layers: stacked LSTM layers.
        dropout: dropout between LSTM layers (only used when num_layers > 1).
        head_hidden: width of the MLP head's hidden layer; 0 = a single linear layer (no activation).
        head_activation: "relu" (paper Table 1), "tanh" or "identity".
        target: "displacement" (next - last point) or "absolute" (next point).
        translate: express each window relative to its last point.
        normalise: scale inputs and target by RMS values fitted on the training set.

    The defaults were chosen by measurement (numbers in conf/model/lstm.yaml, which holds the
    same values): translating is what matters; fitted scaling, more units or layers did not help
    in 15 epochs. The group's ``name`` (and a Hydra ``_target_``) are not read.
    """

    GROUP = "model"
    IGNORED = ("name", "_target_")

    window: int = setting(50, ge=1)
    hidden_size: int = setting(64, ge=1)
    num_layers: int = setting(1, ge=1)
    dropout: float = setting(0.0, ge=0.0, lt=1.0)
    head_hidden: int = setting(32, ge=0)
    head_activation: str = setting("relu", choices=ACTIVATIONS)
    target: str = setting("displacement", choices=TARGETS)
    translate: bool = setting(True)
    normalise: bool = setting(False)


@dataclass(frozen=True)
class TrainConfig(TypedConfig):
    """The Hydra group ``train``: optimisation of the LSTM (blindspot.traj.train).

    Attributes:
        lr: learning rate (paper: 0.001).
        epochs: passes over the training windows (paper: 15).
        batch_size: windows per optimiser step.
        optimizer: "adam" (paper) or "adamw".
        lr_schedule: "constant" (lr throughout) or "cosine" (lr * (1 + cos(pi * s / S)) / 2 at
            optimiser step s of S, decaying from lr to 0 over the run).
        seed: drives weight init, dropout and batch order.
        weight_decay: L2 penalty (Adam) / decoupled decay (AdamW).
        grad_clip: max global gradient norm, or None / 0 for no clipping.
        num_threads: torch intra-op threads during training (None = leave as is; conf/ sets 1).
        eval_batch_size: windows per forward pass when evaluating.
        resume: continue from the last checkpoint (not part of what a checkpoint must match).
        ensemble: networks trained with seeds ``seed, seed + 1, ...``; the predictor averages
            their next points (1 = one network, the paper's setting).
        jobs: worker processes training ensemble members side by side (1 = in this process).
        val_horizon_frames: future points of the validation rollout whose ADE/FDE the train
            stage reports (``blindspot.traj.train.rollout_errors``; the search's objective).
    """

    GROUP = "train"
    IGNORED = ("name",)

    lr: float = setting(1e-3, gt=0.0)
    epochs: int = setting(15, ge=0)
    batch_size: int = setting(64, ge=1)
    optimizer: str = setting("adam", choices=OPTIMIZERS)
    lr_schedule: str = setting("constant", choices=SCHEDULES)
    seed: int = setting(0, ge=0, le=SEED_MAX)       # torch.manual_seed takes a 64-bit seed
    weight_decay: float = setting(0.0, ge=0.0)
    grad_clip: float | None = setting(None, ge=0.0)
    num_threads: int | None = setting(None, ge=1)
    eval_batch_size: int = setting(4096, ge=1)
    resume: bool = setting(False)
    ensemble: int = setting(1, ge=1)
    jobs: int = setting(1, ge=1)
    val_horizon_frames: int = setting(20, ge=1)


# ----------------------------------------------------------------------------- evaluation
@dataclass(frozen=True)
class KalmanConfig(TypedConfig):
    """``eval.kalman``: the constant-velocity Kalman baseline (blindspot.traj.baselines.KalmanCV).

    Attributes:
        process_psd: white-acceleration spectral density, m^2/s^3.
        meas_std: measurement noise of a point, m (per coordinate).
    """

    # Bounds of a walking pedestrian's model: q above 1e4 m^2/s^3 (an acceleration noise of
    # ~100 m/s^2 over a second) or a position noise above 1 km describe no pedestrian and
    # overflow the covariance (meas_std**2) long before 1e300; KalmanCV.fit searches far inside.
    process_psd: float = setting(gt=0.0, le=1e4)
    meas_std: float = setting(gt=0.0, le=1e3)


@dataclass(frozen=True)
class EvalConfig(TypedConfig):
    """The Hydra group ``eval`` (conf/eval/paper.yaml): interpolation, prediction and evaluation
    of the car scenes; see that file for the meaning of every key."""

    GROUP = "eval"

    interpolation_methods: tuple[str, ...] = setting(choices=INTERPOLATION_METHODS, min_items=1)
    prediction_input: str = setting(choices=INTERPOLATION_METHODS)
    prediction_start_s: float = setting(ge=0.0)
    horizon_frames: int | None = setting(ge=1)
    prediction_methods: tuple[str, ...] = setting(choices=PREDICTION_METHODS, min_items=1)
    horizons_s: tuple[float, ...] = setting(gt=0.0, min_items=1)
    cv_fit_points: int = setting(ge=2)
    kalman: KalmanConfig = setting()
    fig06_scene: str = setting()
    fig06_frame: int = setting(ge=0)


# ----------------------------------------------------------------------------- seq2seq
SEQ2SEQ_CELLS: tuple[str, ...] = ("gru", "lstm", "mlp", "transformer")
SEQ2SEQ_FRAMES: tuple[str, ...] = ("heading", "world")
SEQ2SEQ_INPUTS: tuple[str, ...] = ("displacement", "position")
SEQ2SEQ_OUTPUTS: tuple[str, ...] = ("displacement", "position")
SEQ2SEQ_LOSSES: tuple[str, ...] = ("ade", "mse")
SEQ2SEQ_WTA_SCORES: tuple[str, ...] = ("ade", "ade_fde")
SEQ2SEQ_KEEP_BY: tuple[str, ...] = ("mean", "best_of")


@dataclass(frozen=True)
class Seq2SeqConfig(TypedConfig):
    """The direct multi-step predictor and its training (nested in the ``ethucy`` group as
    ``ethucy.seq2seq``; every field is measured in ``studies/ethucy_models.py``).

    Attributes:
        cell: the encoder of the observed history: ``"gru"`` or ``"lstm"`` (recurrent),
            ``"mlp"`` (dense, over the flattened history) or ``"transformer"`` (self-attention
            over the observed steps, a learned position embedding; its last step's output).
        attention_heads: (read when cell is ``"transformer"``) heads of each self-attention
            layer; must divide ``hidden_size``.
        hidden_size: encoder state size.
        num_layers: encoder layers.
        head_hidden: width of the dense head's hidden layer.
        obs_len: observed positions read (the ETH/UCY protocol: 8).
        horizon: future steps emitted (12).
        frame, inputs, outputs, residual, mirror, rotation_deg, scale_aug: see
            :mod:`blindspot.traj.seq2seq`.
        speed_floor: > 0: the frame is also scaled by the last step's length, floored at this
            many metres (:func:`~blindspot.traj.predictor.heading_frame`), so the network sees
            the shape of the motion whatever the walking speed; 0 = metres.
        loss: the mean's loss over all ``horizon`` steps: ``"ade"`` the mean Euclidean
            error (the score itself), ``"mse"`` the mean squared error (the Gaussian
            likelihood's, which chases the mean of a multimodal future).
        nll_weight: weight of the Gaussian NLL of the (detached) mean in the loss; 0 = no
            uncertainty head training (the covariance is then the ensemble spread only).
        epochs: training epochs; the epoch with the lowest validation ADE is kept.
        batch_size, lr, weight_decay: Adam(W) settings.
        ensemble: members trained with seeds ``seed, seed + 1, ...``.
        seed: first seed.
        threads: torch threads while training and predicting.
        neighbours: K > 0: the K pedestrians nearest at the last observed frame are context
            (their observed tracks relative to the walker's, pooled by attention,
            :class:`blindspot.traj.seq2seq.SocialAttention`); 0 = the walker alone.
        modes: M > 1: the head emits M hypotheses (each a Gaussian path) and their
            probabilities, trained winner-takes-all (:mod:`blindspot.traj.mixture`); 1 = one
            Gaussian path.
        wta_score: (read when modes > 1) what picks the winning hypothesis of a training window:
            ``"ade"`` its training loss (``loss``: its mean distance to the truth, or squared
            error), ``"ade_fde"`` its mean plus its final distance (the endpoint counted
            twice, as best-of-N FDE scores it apart).
        keep_by: which epoch is kept: ``"mean"`` the lowest val ADE of the single prediction,
            ``"best_of"`` the lowest val ADE of each window's best hypothesis (with modes = 1
            the same as ``"mean"``).
        basis_rank: k > 0: each predicted path's mean deviation from the residual base lies
            in the span of the k leading right singular vectors of the training windows'
            deviations (a low-rank prior over motion shapes, after SingularTrajectory, Bae et
            al. 2024; :class:`blindspot.traj.seq2seq.Seq2SeqNet`); 0 = any path. Needs
            ``outputs`` position and no rotation augmentation; a fine-tuned model keeps its
            ``init``'s basis.
        time_steps: (ETH/UCY) the train split's windows at each of these steps of the
            annotated grid, pooled (:func:`blindspot.traj.ethucy.resample_tracks`): 1 = as
            annotated; 5/3 = a recording labelled 0.4 s per step whose steps span 0.67 s, as
            the benchmark's eth file does. Distinct, and must hold 1.
    """

    GROUP = "ethucy.seq2seq"

    cell: str = setting("gru", choices=SEQ2SEQ_CELLS)
    hidden_size: int = setting(64, ge=1)
    num_layers: int = setting(1, ge=1)
    head_hidden: int = setting(128, ge=1)
    obs_len: int = setting(8, ge=2)
    horizon: int = setting(12, ge=1)
    frame: str = setting("heading", choices=SEQ2SEQ_FRAMES)
    inputs: str = setting("displacement", choices=SEQ2SEQ_INPUTS)
    outputs: str = setting("position", choices=SEQ2SEQ_OUTPUTS)
    residual: bool = setting(True)
    mirror: bool = setting(True)
    rotation_deg: float = setting(0.0, ge=0.0, le=180.0)
    scale_aug: float = setting(0.0, ge=0.0, le=1.0)
    speed_floor: float = setting(0.0, ge=0.0)
    loss: str = setting("ade", choices=SEQ2SEQ_LOSSES)
    nll_weight: float = setting(0.1, ge=0.0)
    epochs: int = setting(8, ge=1)
    batch_size: int = setting(512, ge=1)
    lr: float = setting(3e-3, gt=0.0)
    weight_decay: float = setting(0.0, ge=0.0)
    ensemble: int = setting(5, ge=1)
    seed: int = setting(0, ge=0)
    threads: int = setting(1, ge=1)
    neighbours: int = setting(8, ge=0)
    modes: int = setting(1, ge=1)
    wta_score: str = setting("ade", choices=SEQ2SEQ_WTA_SCORES)
    keep_by: str = setting("mean", choices=SEQ2SEQ_KEEP_BY)
    time_steps: tuple[float, ...] = setting((1.0,), ge=1.0, min_items=1)
    attention_heads: int = setting(4, ge=1)
    basis_rank: int = setting(0, ge=0)

    def validate(self) -> None:
        if self.cell == "transformer" and self.hidden_size % self.attention_heads:
            raise ConfigError("attention_heads", self.attention_heads,
                              f"a divisor of hidden_size ({self.hidden_size}) with cell "
                              "transformer")
        if self.basis_rank > 2 * self.horizon:
            raise ConfigError("basis_rank", self.basis_rank,
                              f"at most 2 x horizon ({2 * self.horizon}): the dimension of "
                              "a path")
        if self.basis_rank > 0 and self.rotation_deg > 0:
            raise ConfigError("basis_rank", self.basis_rank,
                              "0 when rotation_deg > 0 (the basis is set from the unrotated "
                              "training deviations)")
        if self.basis_rank > 0 and self.outputs != "position":
            raise ConfigError("basis_rank", self.basis_rank,
                              "0 unless outputs is position (the basis spans position "
                              "deviations)")
        if 1.0 not in self.time_steps or len(set(self.time_steps)) != len(self.time_steps):
            raise ConfigError("time_steps", list(self.time_steps),
                              "a list of distinct steps holding 1 (the windows as annotated)")
        if self.scale_aug > 0 and self.speed_floor > 0:
            raise ConfigError("scale_aug", self.scale_aug,
                              "0 when speed_floor > 0 (the speed-scaled frame divides the "
                              "scale out: scaled windows would only change the last step's "
                              "floor, inputs the network never meets at prediction time)")


@dataclass(frozen=True)
class RolloutLSTMConfig(TypedConfig):
    """The next-point LSTM of the ETH/UCY protocol (``lstm_rollout``), nested in the ``ethucy``
    group as ``ethucy.lstm_rollout`` (:class:`LSTMConfig` / :class:`TrainConfig` settings; its
    window is fixed to 8; ``seed`` and ``num_threads`` are set from the top-level ``seed`` and
    ``ethucy.threads``).

    frame ``heading``: each window in its own heading frame (origin at the last point, +x along
    the last step; :class:`~blindspot.traj.predictor.HeadingFrameRollout`), where ``residual``
    (predict the correction to constant velocity), ``mirror`` (mirrored copies, predictions
    averaged) and ``speed_floor`` (scale by the last step length, floored; None: no scaling)
    apply; ``world``: world coordinates, ``rotations`` random-rotation copies per window.
    ``ensemble`` LSTMs with seeds ``seed, seed + 1, ...`` average their next points.
    """

    GROUP = "ethucy.lstm_rollout"

    hidden_size: int = setting(64, ge=1)
    num_layers: int = setting(1, ge=1)
    head_hidden: int = setting(32, ge=0)
    target: str = setting("displacement", choices=TARGETS)
    epochs: int = setting(8, ge=1)
    batch_size: int = setting(256, ge=1)
    lr: float = setting(1e-3, gt=0.0)
    seed: int = setting(0, ge=0)
    frame: str = setting("heading", choices=("heading", "world"))
    residual: bool = setting(True)
    mirror: bool = setting(True)
    speed_floor: float | None = setting(None, gt=0.0)
    rotations: int = setting(0, ge=0)
    ensemble: int = setting(5, ge=1)
    num_threads: int | None = setting(None, ge=1)

    def validate(self) -> None:
        if self.frame == "heading" and self.rotations:
            raise ConfigError("rotations", self.rotations,
                              "0 in the heading frame (it is rotation invariant; random "
                              "rotations need frame: world)")


@dataclass(frozen=True)
class OnlineCandidatesConfig(TypedConfig):
    """The candidate settings of the online ellipses a config group chooses among, each met on
    validation streams held out of the others' prior
    (:func:`blindspot.traj.conformal.select_on_held_out_streams`,
    :func:`blindspot.traj.online.online_candidates`): the ``ethucy`` group per fold and model,
    the ``calibration`` group per scene predictor.

    Attributes:
        online_gammas / online_windows / online_rescales: every combination is a candidate of
            the sliding-window ellipses (:class:`blindspot.traj.conformal.AdaptiveConformal`):
            the ACI step size per prediction time (Gibbs & Candès 2021 use 0.005), in [0, 1);
            the revealed scores kept per step; the own outcomes after which the prior scores
            take the scene's scale (``rescale_prior_after``; 0 off).
        online_etas / online_kappas: every combination is a candidate of the scale-tracking
            ellipses (:class:`blindspot.traj.scale_tracker.ScaleTracker`): the tracker's step
            in log radius per revealed outcome and the coverage correction's gain (empty
            etas: none).
    """

    online_gammas: tuple[float, ...] = setting(ge=0.0, lt=1.0, min_items=1)
    online_windows: tuple[int, ...] = setting(ge=1, min_items=1)
    online_rescales: tuple[int, ...] = setting(ge=0, min_items=1)
    online_etas: tuple[float, ...] = setting(gt=0.0, le=1.0)
    online_kappas: tuple[float, ...] = setting(ge=0.0, le=100.0, min_items=1)


@dataclass(frozen=True)
class EthUcyConfig(OnlineCandidatesConfig):
    """The Hydra group ``ethucy`` (conf/ethucy/standard.yaml): the ETH/UCY benchmark.

    Attributes:
        data: folder of the ETH/UCY files, relative to ``paths.shared_dir`` (or absolute).
        models: predictors to score, from :data:`ETHUCY_MODELS` (``lstm`` / ``gru`` / ``mlp`` /
            ``transformer``: the direct multi-step predictor with that encoder; ``mix``: its
            multi-modal form with ``mix_cell``; ``lstm_rollout``:
            the next-point LSTM rolled out step by step).
        folds: leave-one-scene-out folds, from :data:`blindspot.traj.ethucy.FOLDS`.
        threads: torch threads.
        calibration: how forecasts are calibrated on each fold's val split: a per-step
            covariance scale (:func:`blindspot.traj.distribution.fit_step_scale`, ``"mle"`` or
            ``"quantile"``: the 90 % ellipse covers 90 % of val) or a per-step scale mixture
            of the forecast's Gaussians (``"mixture"``,
            :func:`blindspot.traj.distribution.fit_scale_mixture`: heavy tails), or one such
            mixture per class of observed speed (``"conditional"``,
            :func:`blindspot.traj.distribution.fit_conditional_scale_mixture`).
        calibration_speed_edges: the observed-speed class edges of ``"conditional"``, m/s,
            increasing.
        online_*: the candidates of the online ellipses (:class:`OnlineCandidatesConfig`);
            each fold and model chooses among them on its own val scenes.
        seq2seq: the direct predictor's model and training settings
            (:class:`blindspot.traj.seq2seq.Seq2SeqConfig`; its ``cell`` is set by the model
            key, its ``threads`` by ``threads``, its first seed by the top-level ``seed``).
        lstm_rollout: the next-point LSTM's (:class:`RolloutLSTMConfig`), the same way.
        seeds: how many seeds each learned model is trained with (the top-level ``seed``,
            ``seed + 1``, ...); the results are their mean, ``"seeds"`` their spread.
        mix_cell / mix_modes: the multi-modal model ``mix``: the direct predictor with this
            encoder and ``mix_modes`` hypotheses (:mod:`blindspot.traj.mixture`).
    """

    GROUP = "ethucy"

    data: str = setting()
    models: tuple[str, ...] = setting(choices=ETHUCY_MODELS, min_items=1)
    folds: tuple[str, ...] = setting(choices=ETHUCY_FOLDS, min_items=1)
    threads: int = setting(ge=1)
    calibration: str = setting(choices=("mle", "quantile", "mixture", "conditional"))
    calibration_speed_edges: tuple[float, ...] = setting(gt=0.0, ordered=True, min_items=1)
    seq2seq: Seq2SeqConfig = setting()
    lstm_rollout: RolloutLSTMConfig = setting()
    seeds: int = setting(1, ge=1)
    mix_cell: str = setting("mlp", choices=SEQ2SEQ_CELLS)
    mix_modes: int = setting(20, ge=2)

    def validate(self) -> None:
        heads, width = self.seq2seq.attention_heads, self.seq2seq.hidden_size
        if ("transformer" in self.models or self.mix_cell == "transformer") and width % heads:
            raise ConfigError("seq2seq.attention_heads", heads,
                              f"a divisor of seq2seq.hidden_size ({width}) when a model "
                              "uses the transformer encoder")


@dataclass(frozen=True)
class WalksConfig(TypedConfig):
    """The Hydra group ``benchmark`` (``conf/walks/scene_walks.yaml``).

    Ranges are [low, high], drawn uniformly per walk; m, s, deg. Car: ``car_center_x_m``,
    ``car_center_y_m``, ``car_length_m``, ``car_width_m``, ``car_yaw_deg`` (the other car
    settings, its RCS and bright points, are the scene's and do not reach the measurement: the
    car's static returns are removed by the chain's clutter filter). Walk: ``start_beyond_far_end_m``
    (start y past the car's far end), ``visible_before_shadow_m`` (path walked in sight before
    the car's shadow begins), ``heading_deg`` (deviation from -x), ``speed_mps``, ``turn_deg``, ``turn_radius_m``,
    ``turn_after_exit_m`` (path walked after leaving the shadow before turning),
    ``prediction_after_turn_s`` (prediction start after the turn begins). ``horizon_frames``:
    frames predicted. ``n_bootstrap`` resamples for the intervals at ``ci_level``. ``threads``: torch
    threads of the LSTM rollouts (1: a 64-unit LSTM on a few hundred windows is fastest on one
    thread, and on a busy 2-core machine two threads spin-wait: 0.64 s a step against 0.05 s).
    """

    GROUP = "walks"

    n_walks: int = setting(ge=2, le=100_000)
    car_center_x_m: tuple[float, float] = setting(ge=0.5, le=10.0, ordered=True)
    car_center_y_m: tuple[float, float] = setting(ge=2.0, le=30.0, ordered=True)
    car_length_m: tuple[float, float] = setting(ge=2.5, le=8.0, ordered=True)
    car_width_m: tuple[float, float] = setting(ge=1.2, le=3.0, ordered=True)
    car_yaw_deg: tuple[float, float] = setting(ge=-30.0, le=30.0, ordered=True)
    start_beyond_far_end_m: tuple[float, float] = setting(ge=0.3, le=5.0, ordered=True)
    visible_before_shadow_m: tuple[float, float] = setting(ge=0.1, le=10.0, ordered=True)
    heading_deg: tuple[float, float] = setting(ge=-30.0, le=30.0, ordered=True)
    speed_mps: tuple[float, float] = setting(gt=0.0, le=5.0, ordered=True)
    turn_deg: tuple[float, float] = setting(ge=-90.0, le=90.0, ordered=True)
    turn_radius_m: tuple[float, float] = setting(ge=0.0, le=5.0, ordered=True)
    turn_after_exit_m: tuple[float, float] = setting(ge=0.0, le=10.0, ordered=True)
    prediction_after_turn_s: tuple[float, float] = setting(ge=0.0, le=10.0, ordered=True)
    horizon_frames: int = setting(ge=1, le=1000)
    n_bootstrap: int = setting(ge=100, le=1_000_000)
    ci_level: float = setting(gt=0.5, lt=1.0)
    threads: int = setting(ge=1, le=256)

    def validate(self) -> None:
        if self.car_center_x_m[0] - self.car_width_m[1] / 2 <= 0.2:
            raise ConfigError("car_center_x_m", self.car_center_x_m,
                              "a car whose left side stays right of the radar's boresight "
                              "(centre x - width / 2 > 0.2 m), as in the paper's scene")


@dataclass(frozen=True)
class DirectConfig(TypedConfig):
    """The Hydra group ``direct`` (``conf/direct/scene.yaml``): the direct multi-step predictor
    of the scenes (``lstm_direct``), trained on the radar path data set.

    model: the network and its training (:class:`Seq2SeqConfig`; ``neighbours`` must be 0:
        the paper's scenes hold one walker, so there is no one to attend to);
    stride: points between the starts of two training pairs of one path;
    jobs: CPUs the ensemble's training may use; with ``jobs`` > 1 every member is trained in
        its own process, the processes confined to ``jobs`` CPUs (the same weights as in one
        process);
    pretrain_epochs: > 0: each member is first trained this many epochs on ETH/UCY walks
        resampled to the radar's frame period, their histories given the radar's own point
        errors (:func:`blindspot.traj.direct.pretraining_walks`), then fine-tuned on the radar
        pairs; 0: trained on the radar pairs alone;
    finetune: True: after pre-training, train on the radar pairs (the epochs of ``model``);
        False: the pre-trained members are the model, never trained on a radar pair (needs
        ``pretrain_epochs`` > 0). On occluded walks of the paper's scene the ETH/UCY-only
        network forecasts better (studies/pretrain_direct.py);
    pretrain_walks: at most this many ETH/UCY walks (a seeded random subset; 0 = all of them);
    pretrain_data: the ETH/UCY folder, relative to ``paths.shared_dir``.
    """

    GROUP = "direct"

    model: Seq2SeqConfig = setting()
    stride: int = setting(ge=1, le=1000)
    jobs: int = setting(ge=1)
    pretrain_epochs: int = setting(0, ge=0, le=1000)
    finetune: bool = setting(True)
    pretrain_walks: int = setting(0, ge=0)
    pretrain_data: str = setting("data/ethucy")

    def validate(self) -> None:
        if self.model.neighbours != 0:
            raise ConfigError("model.neighbours", self.model.neighbours,
                              "0 (the scenes' paths have no neighbours)")
        if not self.finetune and self.pretrain_epochs == 0:
            raise ConfigError("finetune", self.finetune,
                              "true unless pretrain_epochs > 0 (without pre-training and "
                              "fine-tuning the network would never be trained)")


@dataclass(frozen=True)
class CalibrationConfig(OnlineCandidatesConfig):
    """The Hydra group ``calibration`` (``conf/calibration/sim_paths.yaml``).

    horizon_frames: future points per pair; stride: points between pair starts;
    scale_method / scale_level: :func:`fit_step_scale`'s method and level, or ``"mixture"``:
        a per-step scale mixture (:func:`blindspot.traj.distribution.fit_scale_mixture`,
        heavy-tailed errors; ``scale_level`` unused).
    online_*: the candidates of the online ellipses (:class:`OnlineCandidatesConfig`); each
        predictor chooses among them on the validation paths, cut into ``online_val_streams``
        streams of consecutive paths, each met as a new stream with the others' scores as its
        prior (as the held-out paths are met, with all the validation scores as theirs).
    online_val_streams: how many streams the validation paths are cut into, >= 2.
    """

    GROUP = "calibration"

    horizon_frames: int = setting(ge=1, le=1000)
    stride: int = setting(ge=1, le=1000)
    scale_method: str = setting(choices=("mle", "quantile", "mixture"))
    scale_level: float = setting(gt=0.0, lt=1.0)
    online_val_streams: int = setting(ge=2)
