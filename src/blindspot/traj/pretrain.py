"""ETH/UCY walks at the radar's frame rate, to pre-train the scene LSTM (next-point windows) and
the direct multi-step LSTM (whole walks, :func:`ethucy_sequences`).

Issue 10 asks whether real pedestrians help the radar scenes: the scene LSTM (a next-point model
on ``W`` = 50 points at the radar's frame period, 0.1 s) is trained on windows of the radar
path data set; here the same kind of windows are cut from the ETH/UCY annotations (2.5 fps,
Pellegrini et al. 2009, Lerner et al. 2007) so the network can first learn how people walk and
then be fine-tuned on the radar windows (``blindspot.traj.train.train_lstm(init_from=...)``).

Resampling. ETH/UCY positions come every 0.4 s; the radar sees one every ``dt_s``. Each
annotated stretch of ``L`` frames is resampled onto the finer grid with a uniform Catmull-Rom
spline (a cubic Hermite curve through every annotation whose tangent at a knot is the central
difference of its neighbours, one-sided at the ends; Catmull & Rom 1974): it passes through the
annotations, keeps velocity continuous, and needs no fit, so it runs on all stretches at once.
Linear interpolation would hand the network straight 0.4 s segments with velocity jumps at the
knots, which no radar path has.

Windows. A stretch of ``L`` annotated frames holds ``(L - 1) * r + 1`` resampled points
(``r`` = 0.4 s / dt_s, an integer); the windows of ``W`` points plus their next point start at
the first ``r`` offsets of the stretch, so consecutive stretches (stride one annotated frame)
tile every start exactly once. ``L = ceil((W + r - 1) / r) + 1`` is the shortest stretch that
holds ``r`` windows (:func:`stretch_length`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from blindspot.arrays import check_array, check_count
from blindspot.traj.ethucy import FOLDS, FRAME_PERIOD_S, EthUcyDataError, load_split, random_rotations
from blindspot.traj.windows import WindowSet

__all__ = ["catmull_rom_resample", "upsampling_factor", "stretch_length", "ethucy_next_point_windows",
           "ethucy_sequences", "radar_point_errors", "with_point_errors"]


def upsampling_factor(dt_s: float, period_s: float = FRAME_PERIOD_S) -> int:
    """The integer ``r`` with ``period_s = r * dt_s`` (ETH/UCY 0.4 s over the radar's 0.1 s: 4).

    Raises:
        EthUcyDataError: ``dt_s`` not positive, or ``period_s / dt_s`` not an integer (within
            1e-6): the windows would mix two frame periods.
    """
    if not (isinstance(dt_s, int | float) and math.isfinite(dt_s) and dt_s > 0):
        raise EthUcyDataError(f"dt_s: expected a frame period > 0 s, found {dt_s!r}")
    r = period_s / dt_s
    if abs(r - round(r)) > 1e-6 or round(r) < 1:
        raise EthUcyDataError(f"dt_s: the ETH/UCY period {period_s} s must be a whole multiple of "
                              f"the radar frame period, found {period_s} / {dt_s} = {r:.6g}")
    return int(round(r))


def stretch_length(window: int, factor: int) -> int:
    """Annotated frames ``L`` whose resampled stretch holds ``factor`` windows of ``window``
    points and their next points: the smallest L with ``(L - 1) * factor + 1 >= window + factor``."""
    window = check_count(window, "window", ge=1, error=EthUcyDataError, who="stretch_length")
    factor = check_count(factor, "factor", ge=1, error=EthUcyDataError, who="stretch_length")
    return math.ceil((window + factor - 1) / factor) + 1


def catmull_rom_resample(xy: np.ndarray, factor: int) -> np.ndarray:
    """Resample stretches of positions ``factor`` times more finely with a uniform Catmull-Rom
    spline through every given point.

    Args:
        xy: (N, L, 2) positions in metres at a uniform period, L >= 2, finite.
        factor: r >= 1 output points per input period.

    Returns:
        (N, (L - 1) * r + 1, 2) float64 positions; every r-th point is an input point.

    Raises:
        EthUcyDataError: ``xy`` not a finite real (N, L, 2) array with L >= 2, or ``factor`` not an
            integer >= 1.
    """
    xy = check_array(xy, "xy", ("N", "L", 2), error=EthUcyDataError, who="catmull_rom_resample")
    factor = check_count(factor, "factor", ge=1, error=EthUcyDataError, who="catmull_rom_resample")
    n, length, _ = xy.shape
    if length < 2:
        raise EthUcyDataError(f"catmull_rom_resample: xy has {length} point(s) per stretch; a "
                              "spline needs at least 2")
    p = xy.astype(np.float64)
    tangent = np.empty_like(p)                       # (N, L, 2) per input period
    tangent[:, 1:-1] = 0.5 * (p[:, 2:] - p[:, :-2])
    tangent[:, 0] = p[:, 1] - p[:, 0]
    tangent[:, -1] = p[:, -1] - p[:, -2]
    s = np.arange(factor) / factor                   # (r,) position inside one period
    h00 = 2 * s**3 - 3 * s**2 + 1
    h10 = s**3 - 2 * s**2 + s
    h01 = -2 * s**3 + 3 * s**2
    h11 = s**3 - s**2
    # (N, L-1, r, 2): every period's r points, then the last knot
    seg = (h00[:, None] * p[:, :-1, None] + h10[:, None] * tangent[:, :-1, None]
           + h01[:, None] * p[:, 1:, None] + h11[:, None] * tangent[:, 1:, None])
    return np.concatenate([seg.reshape(n, (length - 1) * factor, 2), p[:, -1:]], axis=1)


def ethucy_next_point_windows(data_dir: str | Path, window: int, dt_s: float, *,
                              folds: tuple[str, ...] = FOLDS, rotate: bool = True,
                              seed: int = 0) -> WindowSet:
    """Next-point windows of ``window`` points at ``dt_s`` from every ETH/UCY recording.

    Each fold's ``test`` split is one whole recording, so the five folds' test splits are the
    data set once, without the overlap of the train/val splits. Every pedestrian stretch of
    :func:`stretch_length` annotated frames (stride one frame, any number of pedestrians in the
    scene) is resampled (:func:`catmull_rom_resample`) and cut into its first ``r`` windows. With
    ``rotate`` each stretch is turned by its own uniform random angle (the standard ETH/UCY
    augmentation, :func:`blindspot.traj.ethucy.random_rotations`): the scene LSTM translates
    each window to its last point but does not rotate it, and the recordings' walking directions
    are few.

    Args:
        data_dir: folder holding ``eth/ hotel/ univ/ zara1/ zara2/`` (the data README's layout).
        window: W, points per window (the scene model's ``model.window``).
        dt_s: the radar's frame period (``radar.frame_period_s``); 0.4 s must be a multiple.
        folds: which recordings (fold names) to use.
        rotate: random rotation per stretch; seed: its generator's seed.

    Returns:
        :class:`WindowSet` with x (N, W, 2), y (N, 2) in metres, path_id (N,) the stretch a window
        came from, start (N,) its offset inside the resampled stretch.

    Raises:
        EthUcyDataError: see :func:`upsampling_factor`, :func:`blindspot.traj.ethucy.load_split`.
    """
    factor = upsampling_factor(dt_s)
    fine = _resampled_stretches(data_dir, stretch_length(window, factor), factor, folds, rotate,
                                seed)                                     # (S, (L-1) r + 1, 2)
    n_stretch = fine.shape[0]
    offsets = np.arange(factor)
    idx = offsets[:, None] + np.arange(window + 1)[None, :]              # (r, W+1)
    pairs = fine[:, idx].reshape(-1, window + 1, 2)                       # (S * r, W+1, 2)
    return WindowSet(x=pairs[:, :window], y=pairs[:, window],
                     path_id=np.repeat(np.arange(n_stretch), factor),
                     start=np.tile(offsets, n_stretch))


def ethucy_sequences(data_dir: str | Path, n_points: int, dt_s: float, *,
                     folds: tuple[str, ...] = FOLDS, rotate: bool = True,
                     seed: int = 0) -> np.ndarray:
    """Walks of ``n_points`` points at ``dt_s`` from every ETH/UCY recording, one starting at
    every annotated frame (0.4 s apart) of every pedestrian: the (history, future) pairs of a
    direct multi-step model (:mod:`blindspot.traj.direct`) at the radar's frame rate.

    Each fold's ``test`` split (one whole recording) is read; every stretch of
    ``ceil((n_points - 1) / r) + 1`` annotated frames is turned by its own random angle about its
    first point (``rotate``; :func:`blindspot.traj.ethucy.random_rotations`) and resampled with
    :func:`catmull_rom_resample`; its first ``n_points`` points are the walk.

    Args:
        data_dir: folder holding ``eth/ hotel/ univ/ zara1/ zara2/``.
        n_points: points per walk (obs_len + horizon), >= 2.
        dt_s: the radar's frame period; 0.4 s must be a whole multiple of it.
        folds, rotate, seed: as :func:`ethucy_next_point_windows`.

    Returns:
        (S, n_points, 2) float64, metres, oldest first.

    Raises:
        EthUcyDataError: ``n_points`` < 2, see :func:`upsampling_factor`,
            :func:`blindspot.traj.ethucy.load_split`.
    """
    n_points = check_count(n_points, "n_points", ge=2, error=EthUcyDataError,
                           who="ethucy_sequences")
    factor = upsampling_factor(dt_s)
    length = math.ceil((n_points - 1) / factor) + 1
    return _resampled_stretches(data_dir, length, factor, folds, rotate, seed)[:, :n_points]


def _resampled_stretches(data_dir: str | Path, length: int, factor: int,
                         folds: tuple[str, ...], rotate: bool, seed: int) -> np.ndarray:
    """(S, (length - 1) * factor + 1, 2): every stretch of ``length`` annotated frames of the
    folds' test recordings, each rotated about its first point (``rotate``), resampled."""
    stretches = np.concatenate([load_split(data_dir, fold, "test", seq_len=length, min_peds=1).xy
                                for fold in folds])                       # (S, L, 2)
    if rotate:
        # about each stretch's first point, so the rotation does not move it across the scene
        origin = stretches[:, :1]
        stretches = random_rotations(stretches - origin, 1, np.random.default_rng(seed)) + origin
    return catmull_rom_resample(stretches, factor)


def radar_point_errors(measured: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """(K, 2) measured minus true position, metres, at every radar point of the paths
    (measured, truth: (P, T, 2); measured NaN where the radar gave no point): what
    :func:`with_point_errors` draws from."""
    m = check_array(measured, "measured", ("P", "T", 2), error=EthUcyDataError,
                    who="radar_point_errors", allow_nan=True)
    t = check_array(truth, "truth", m.shape, error=EthUcyDataError, who="radar_point_errors")
    return (m - t)[np.isfinite(m).all(axis=-1)]


def with_point_errors(walks: np.ndarray, n_history: int, errors: np.ndarray,
                      rng: np.random.Generator) -> np.ndarray:
    """The walks with each of their first ``n_history`` points moved by an error vector drawn
    at random (with replacement, independently per point) from ``errors``: ETH/UCY histories
    made to look like radar histories, heavy tails and all, their futures left as annotated.

    Args:
        walks: (S, T, 2) metres.
        n_history: points of each walk that are history, 0 <= n_history <= T.
        errors: (K, 2) measured-minus-true positions of radar points, metres, K >= 1.
        rng: the draws' generator.

    Returns:
        (S, T, 2) float64, a new array.

    Raises:
        EthUcyDataError: shapes as above violated, or a non-finite error vector.
    """
    who = "with_point_errors"
    w = check_array(walks, "walks", ("S", "T", 2), error=EthUcyDataError, who=who)
    e = check_array(errors, "errors", ("K", 2), error=EthUcyDataError, who=who)
    n_history = check_count(n_history, "n_history", ge=0, error=EthUcyDataError, who=who)
    if n_history > w.shape[1] or len(e) == 0:
        raise EthUcyDataError(f"{who}: need 0 <= n_history <= {w.shape[1]} and at least one "
                              f"error vector, found n_history {n_history}, {len(e)} vectors")
    out = np.array(w, dtype=float)
    out[:, :n_history] += e[rng.integers(0, len(e), (w.shape[0], n_history))]
    return out
