"""Synthetic pedestrian path kinematics for the training data set (paper section III).

The paper draws "random range, velocity and angle" for a target and records 200 points per path.
This module produces the *clean truth* of such paths: a start position (range, angle), a constant
walking speed, an initial heading chosen to make the path approach the radar, recede from it or
cross its boresight, and a constant (gentle) turn rate. The radar chain (another module) turns each
truth point into a measured point with the radar's real error; :func:`radar_like_noise` is only a
simple stand-in for tests and benchmarks.

Geometry (project convention): radar at the origin, boresight +y, x to the right, angles positive
towards +x, so a point at range R and angle theta is ``(R sin theta, R cos theta)``. A heading psi
is measured the same way, so the walking velocity is ``v (sin psi, cos psi)``.

Motion classes (heading psi0 relative to the start's own bearing theta0):

- approaching: ``psi0 = theta0 + pi + U(-s, s)`` (towards the radar, slope up to ``s``),
- receding: ``psi0 = theta0 + U(-s, s)`` (away from the radar),
- perpendicular: ``psi0 = theta0 +- pi/2 + U(-p, p)`` (across the line of sight),

with ``s = heading_spread_deg`` and ``p = perpendicular_spread_deg``. Paths that leave the field
of view (``min_range_m <= R <= max_range_m`` and ``|theta| <= max_abs_angle_deg``) at any point are
redrawn, so the kept distribution is the drawn one *conditioned on staying visible*: approaching
paths, which would otherwise run through the radar, are biased towards slower speeds and larger
start ranges. :func:`random_path_set` returns the per-path draws so callers can check this.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import pandas as pd

from blindspot.arrays import check_array, check_count
from blindspot.traj.config import PathSpec
from blindspot.typed_config import ConfigError

MOTIONS: tuple[str, ...] = ("approaching", "receding", "perpendicular")


class PathDataError(ValueError):
    """A path table or path array is not what the paths stage writes / a function expects."""


class PathSkipWarning(UserWarning):
    """Paths of a path table were dropped (``bad_paths="skip"``); one warning per table."""


@dataclass(frozen=True)
class PathSet:
    """Clean synthetic paths with the draws that made them.

    Attributes:
        xy: (P, T, 2) float64 truth positions (x, y) in metres.
        motion: (P,) int index into :data:`MOTIONS`.
        speed_mps: (P,) walking speed.
        heading0_rad: (P,) initial heading (from +y towards +x).
        turn_rate_rad_s: (P,) constant turn rate.
    """

    xy: np.ndarray
    motion: np.ndarray
    speed_mps: np.ndarray
    heading0_rad: np.ndarray
    turn_rate_rad_s: np.ndarray


def integrate_constant_turn(
    start_xy: np.ndarray,
    speed_mps: np.ndarray,
    heading0_rad: np.ndarray,
    turn_rate_rad_s: np.ndarray,
    n_points: int,
    dt_s: float,
) -> np.ndarray:
    """Exact positions of walkers moving at constant speed and constant turn rate.

    Over one step the heading changes by ``w dt``; the chord of that arc has length
    ``v dt sinc(w dt / 2)`` (sinc(u) = sin u / u) and points along the mid-step heading, so the
    cumulative sum of chords is exact on the arc (and a straight line when w = 0).

    Args:
        start_xy: (P, 2) first positions.
        speed_mps, heading0_rad, turn_rate_rad_s: (P,) per walker.
        n_points: T, number of positions per path.
        dt_s: time step.

    Returns:
        (P, T, 2) positions.

    Raises:
        PathDataError: an array not finite real numbers of its shape, n_points not an integer
            >= 1, dt_s not > 0.
    """
    who = "integrate_constant_turn"
    start_xy = check_array(start_xy, "start_xy", ("P", 2), error=PathDataError, who=who)
    P = start_xy.shape[0]
    speed_mps, heading0_rad, turn_rate_rad_s = (
        check_array(v, name, (P,), error=PathDataError, who=who) for v, name in (
            (speed_mps, "speed_mps"), (heading0_rad, "heading0_rad"),
            (turn_rate_rad_s, "turn_rate_rad_s")))
    n_points = check_count(n_points, "n_points", ge=1, error=PathDataError, who=who)
    _check_period(dt_s, who)
    k = np.arange(n_points - 1)
    mid_heading = heading0_rad[:, None] + turn_rate_rad_s[:, None] * (k + 0.5) * dt_s  # (P, T-1)
    chord = speed_mps * dt_s * np.sinc(turn_rate_rad_s * dt_s / (2.0 * np.pi))  # np.sinc(x)=sin(pi x)/(pi x)
    steps = chord[:, None, None] * np.stack([np.sin(mid_heading), np.cos(mid_heading)], axis=-1)
    xy = np.empty((start_xy.shape[0], n_points, 2))
    xy[:, 0] = start_xy
    xy[:, 1:] = start_xy[:, None, :] + np.cumsum(steps, axis=1)
    return xy


def _check_period(dt_s, who: str) -> None:
    dt = check_array(dt_s, "dt_s", (), error=PathDataError, who=who)
    if not dt > 0:
        raise PathDataError(f"{who}: dt_s: expected a time step > 0 s, found {dt_s!r}")


def _draw(spec: PathSpec, motion: int, n: int, rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    """Draw n candidate paths of one motion class: (xy, speed, heading0, turn_rate)."""
    r0 = rng.uniform(*spec.start_range_m, size=n)
    th0 = np.deg2rad(rng.uniform(*spec.start_angle_deg, size=n))
    speed = rng.uniform(*spec.speed_mps, size=n)
    turn = np.deg2rad(rng.uniform(*spec.turn_rate_deg_s, size=n))
    spread = np.deg2rad(spec.heading_spread_deg)
    if motion == 0:  # approaching
        psi0 = th0 + np.pi + rng.uniform(-spread, spread, size=n)
    elif motion == 1:  # receding
        psi0 = th0 + rng.uniform(-spread, spread, size=n)
    else:  # perpendicular, either way across
        side = np.where(rng.random(n) < 0.5, -1.0, 1.0)
        p = np.deg2rad(spec.perpendicular_spread_deg)
        psi0 = th0 + side * np.pi / 2 + rng.uniform(-p, p, size=n)
    psi0 = np.angle(np.exp(1j * psi0))  # wrap to (-pi, pi]
    start = np.stack([r0 * np.sin(th0), r0 * np.cos(th0)], axis=-1)
    xy = integrate_constant_turn(start, speed, psi0, turn, spec.points_per_path, spec.frame_period_s)
    sharp = rng.random(n) < spec.sharp_turn_prob
    angle = np.deg2rad(rng.uniform(*spec.sharp_turn_deg, size=n)) * np.where(rng.random(n) < 0.5, -1.0, 1.0)
    duration = rng.uniform(*spec.sharp_turn_duration_s, size=n)
    at = rng.uniform(0.2, 0.9, size=n) * (spec.points_per_path - 1) * spec.frame_period_s
    if sharp.any():
        xy[sharp] = add_sharp_turn(xy[sharp], at[sharp], angle[sharp], duration[sharp], spec.frame_period_s)
    return xy, speed, psi0, turn


def add_sharp_turn(xy: np.ndarray, at_s: np.ndarray, angle_rad: np.ndarray, duration_s: np.ndarray,
                   dt_s: float) -> np.ndarray:
    """Paths (P, T, 2) with one extra turn each: from time ``at_s`` the heading swings by
    ``angle_rad`` (positive = clockwise, like the turn rate) at a constant rate over ``duration_s``.

    Each step of the path is rotated by the extra heading reached at its mid-time, so speed and
    the gentle turn already in the path are kept; the path before ``at_s`` is unchanged.
    ``at_s``, ``angle_rad``, ``duration_s``: (P,). Raises PathDataError for an array that is not
    finite real numbers of its shape, or dt_s not > 0.
    """
    who = "add_sharp_turn"
    xy = check_array(xy, "xy", ("P", "T", 2), error=PathDataError, who=who)
    P = xy.shape[0]
    at_s, angle_rad, duration_s = (
        check_array(v, name, (P,), error=PathDataError, who=who) for v, name in (
            (at_s, "at_s"), (angle_rad, "angle_rad"), (duration_s, "duration_s")))
    _check_period(dt_s, who)
    steps = np.diff(xy, axis=1)                                           # (P, T-1, 2)
    t_mid = (np.arange(steps.shape[1]) + 0.5) * dt_s
    frac = np.clip((t_mid[None, :] - at_s[:, None]) / np.maximum(duration_s[:, None], 1e-9), 0.0, 1.0)
    extra = angle_rad[:, None] * frac                                     # (P, T-1)
    c, s = np.cos(extra), np.sin(extra)
    # heading measured from +y towards +x: a clockwise turn by a maps (sx, sy) -> R(-a) (sx, sy)
    rot = np.stack([c * steps[..., 0] + s * steps[..., 1], -s * steps[..., 0] + c * steps[..., 1]], axis=-1)
    out = np.empty_like(xy)
    out[:, 0] = xy[:, 0]
    out[:, 1:] = xy[:, :1] + np.cumsum(rot, axis=1)
    return out


def in_field_of_view(xy: np.ndarray, spec: PathSpec) -> np.ndarray:
    """(P,) True where every point of a (P, T, 2) path lies inside the spec's field of view.

    Raises PathDataError when ``xy`` is not a finite real (P, T, 2) array."""
    xy = check_array(xy, "xy", ("P", "T", 2), error=PathDataError, who="in_field_of_view")
    rng_m = np.hypot(xy[..., 0], xy[..., 1])
    ang = np.degrees(np.arctan2(xy[..., 0], xy[..., 1]))
    ok = (rng_m >= spec.min_range_m) & (rng_m <= spec.max_range_m) & (np.abs(ang) <= spec.max_abs_angle_deg)
    return ok.all(axis=-1)


def random_path_set(n_paths: int, spec: PathSpec | None = None, seed: int = 0, *, max_rounds: int = 200) -> PathSet:
    """Draw ``n_paths`` clean pedestrian paths that stay in the field of view.

    The number of paths per motion class is multinomial with ``spec.motion_weights``; each class
    is filled by vectorised rejection sampling (candidates drawn in batches, those leaving the
    field of view dropped). The output order is shuffled. Same seed, same bytes.

    Args:
        n_paths: P >= 0.
        spec: drawing settings (default :class:`PathSpec`).
        seed: seeds ``np.random.default_rng``.
        max_rounds: give up (ValueError) if a class is still not filled after this many batches,
            which means the settings leave almost no path inside the field of view.

    Returns:
        :class:`PathSet` with ``xy`` of shape (P, spec.points_per_path, 2).
    """
    spec = spec or PathSpec()
    if int(n_paths) != n_paths or n_paths < 0:
        raise ConfigError("n_paths", n_paths, "an integer >= 0")
    rng = np.random.default_rng(seed)
    w = np.asarray(spec.motion_weights)
    per_class = rng.multinomial(int(n_paths), w / w.sum())
    parts: list[tuple[np.ndarray, ...]] = []
    labels: list[np.ndarray] = []
    for motion, need in enumerate(per_class):
        got: list[tuple[np.ndarray, ...]] = []
        have = 0
        for _ in range(max_rounds):
            if have >= need:
                break
            cand = _draw(spec, motion, max(64, 2 * (need - have)), rng)
            keep = in_field_of_view(cand[0], spec)
            got.append(tuple(c[keep] for c in cand))
            have += int(keep.sum())
        if have < need:
            raise ValueError(
                f"{MOTIONS[motion]} paths: only {have} of {need} stayed in the field of view after {max_rounds} "
                f"rounds; widen max_range_m/max_abs_angle_deg or shorten/slow the paths ({spec})"
            )
        if got:
            parts.append(tuple(np.concatenate([g[i] for g in got])[:need] for i in range(4)))
        else:
            parts.append((np.empty((0, spec.points_per_path, 2)), np.empty(0), np.empty(0), np.empty(0)))
        labels.append(np.full(need, motion, dtype=np.int64))
    order = rng.permutation(int(n_paths))
    xy, speed, psi0, turn = (np.concatenate([p[i] for p in parts])[order] for i in range(4))
    motion = np.concatenate(labels)[order]
    return PathSet(xy=xy, motion=motion, speed_mps=speed, heading0_rad=psi0, turn_rate_rad_s=turn)


def random_paths(n_paths: int, spec: PathSpec | None = None, seed: int = 0) -> np.ndarray:
    """(P, spec.points_per_path, 2) clean truth paths; see :func:`random_path_set`."""
    return random_path_set(n_paths, spec, seed).xy


def radar_like_noise(
    paths: np.ndarray,
    *,
    seed: int = 0,
    range_step_m: float = 0.5,
    range_mode: str = "quantise",
    angle_std_deg: float = 1.0,
    miss_prob: float = 0.05,
) -> np.ndarray:
    """A simple measurement model for tests and benchmarks (NOT the radar chain).

    Each point is converted to (range, angle); the range is either rounded to the nearest
    multiple of ``range_step_m`` (``range_mode="quantise"``, like an FFT peak bin: error uniform in
    +-step/2, std step/sqrt(12) = 0.144 m for 0.5 m, but correlated along a path) or perturbed by an
    independent uniform error of the same width (``"uniform"``); the angle gets Gaussian noise of
    ``angle_std_deg``; each point is missed (set to NaN) with probability ``miss_prob``.

    Args:
        paths: (P, T, 2) clean positions.

    Returns:
        (P, T, 2) float64 measured positions with NaN rows for missed points.

    Raises:
        PathDataError: ``paths`` not a finite real (P, T, 2) array, or a setting out of range.
    """
    paths = check_array(paths, "paths", ("P", "T", 2), error=PathDataError, who="radar_like_noise")
    if not (range_step_m >= 0 and angle_std_deg >= 0 and 0.0 <= miss_prob <= 1.0
            and np.isfinite([range_step_m, angle_std_deg]).all()):
        raise PathDataError(
            f"radar_like_noise: expected range_step_m >= 0, angle_std_deg >= 0, 0 <= miss_prob <= 1; "
            f"found {range_step_m}, {angle_std_deg}, {miss_prob}"
        )
    rng = np.random.default_rng(seed)
    r = np.hypot(paths[..., 0], paths[..., 1])
    th = np.arctan2(paths[..., 0], paths[..., 1])
    if range_step_m > 0:
        if range_mode == "quantise":
            r = np.round(r / range_step_m) * range_step_m
        elif range_mode == "uniform":
            r = r + rng.uniform(-range_step_m / 2, range_step_m / 2, size=r.shape)
        else:
            raise PathDataError(f"range_mode: expected 'quantise' or 'uniform', found {range_mode!r}")
    th = th + np.deg2rad(angle_std_deg) * rng.standard_normal(th.shape)
    out = np.stack([r * np.sin(th), r * np.cos(th)], axis=-1)
    out[rng.random(r.shape) < miss_prob] = np.nan
    return out


TABLE_COLUMNS = ("path_id", "point", "motion", "x_true_m", "y_true_m", "x_m", "y_m")


def table_to_arrays(table: pd.DataFrame, *, source: str = "path table",
                    bad_paths: str = "raise") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(truth (P, T, 2), measured (P, T, 2), motion (P,)) of the path table the ``paths`` stage
    writes (:func:`blindspot.synth.path_dataset.path_table`: one row per path point, columns
    path_id, point, motion, x_true_m, y_true_m, x_m, y_m, ...; metres); measured points are NaN
    where the radar gave none. Paths are ordered by ``path_id``, points by ``point``.

    A path is defective when a (path_id, point) pair appears twice, its points are not
    0 .. T-1 with T the longest path's length (missing or extra points), a truth coordinate is
    not finite, or a measured coordinate is infinite.

    Args:
        table: the long table (any row order).
        source: the file name used in messages.
        bad_paths: "raise" (default: the table is a stage output, a defect is a bug upstream)
            or "skip": drop the defective paths with one :class:`PathSkipWarning` giving the
            count for each reason.

    Raises:
        PathDataError: a missing column, an empty table, a defective path (with "raise"), or no
            path left (with "skip"); the message names ``source`` and the counts.
    """
    if bad_paths not in ("raise", "skip"):
        raise PathDataError(f"bad_paths: expected 'raise' or 'skip', found {bad_paths!r}")
    missing = [c for c in TABLE_COLUMNS if c not in table.columns]
    if missing:
        raise PathDataError(f"{source}: expected the columns {list(TABLE_COLUMNS)}, "
                            f"missing {missing}")
    if len(table) == 0:
        raise PathDataError(f"{source}: the table holds no rows")
    t = table.sort_values(["path_id", "point"], kind="stable")
    pid, point = t.path_id.to_numpy(), t.point.to_numpy()
    truth = t[["x_true_m", "y_true_m"]].to_numpy(dtype=float)
    meas = t[["x_m", "y_m"]].to_numpy(dtype=float)
    ids, inv, counts = np.unique(pid, return_inverse=True, return_counts=True)
    # defects, one boolean per path (vectorised over rows with bincount)
    repeat = np.zeros(len(t), bool)
    repeat[1:] = (pid[1:] == pid[:-1]) & (point[1:] == point[:-1])
    distinct = np.bincount(inv, weights=~repeat).astype(np.int64)   # distinct points per path
    n = int(distinct.max())
    # rank of each distinct row within its path (0, 1, ...): must equal its point index
    seen = np.cumsum(~repeat)
    rank = seen - 1 - np.repeat(seen[np.cumsum(counts) - 1] - distinct, counts)
    reasons = {
        "repeated (path_id, point) rows": np.bincount(inv, weights=repeat) > 0,
        f"points not 0..{n - 1}": (distinct != n) | (np.bincount(
            inv, weights=(point != rank) & ~repeat) > 0),
        "non-finite truth": np.bincount(inv, weights=~np.isfinite(truth).all(axis=1)) > 0,
        "infinite measured points": np.bincount(inv, weights=np.isinf(meas).any(axis=1)) > 0,
    }
    bad = np.logical_or.reduce(list(reasons.values()))
    if bad.any():
        counted = ", ".join(f"{int(v.sum())} with {k}" for k, v in reasons.items() if v.any())
        what = f"{int(bad.sum())} of {ids.size} paths are defective ({counted})"
        if bad_paths == "raise" or bad.all():
            first = ids[np.flatnonzero(bad)[0]].item()
            raise PathDataError(f"{source}: {what}; the first is path_id {first!r}"
                                + ("" if bad.all() else "; pass bad_paths='skip' to drop them"))
        warnings.warn(f"{source}: dropped {what}", PathSkipWarning, stacklevel=2)
    keep = ~bad[inv]
    p = int((~bad).sum())
    motion = t.motion.to_numpy()[keep][::n]
    return truth[keep].reshape(p, n, 2), meas[keep].reshape(p, n, 2), motion
