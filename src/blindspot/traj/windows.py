"""Sliding windows over point paths: a window of W points -> the next point (paper: W = 50).

A path of T points gives ``T - W`` window/response pairs at stride 1 (200 points, W = 50: 150
pairs), ``ceil((T - W) / stride)`` at a larger stride. Windows are views built with
``numpy.lib.stride_tricks.sliding_window_view`` and copied once into float32 arrays (float64
far from the origin: :data:`FLOAT32_EXACT_M`).

Missing points (NaN rows: no detection in that frame) are never invented here: a window whose
W inputs or target contain a NaN is dropped (``nan_policy="drop"``, the default) or refused
(``"raise"``). Fill gaps first with :func:`interpolate_gaps` (linear, interior gaps only) or a
smoother if you want those windows, then drop the windows whose last input was filled
(:func:`last_point_measured`): that fill came from a point after the window. Dropping changes the number of windows per path, which is
why :func:`split_by_path` counts windows per path instead of assuming 150.

Splits (paper: 20,000 train / 4,000 validation / 500 test) are made of whole paths so no path is
in two splits; each split then keeps exactly its count by a seeded random subset of its windows
(see :func:`split_by_path`). With 200-point paths at stride 1 that takes 134 + 27 + 4 = 165 paths
(:func:`paths_needed`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from blindspot.io import atomic_path
from blindspot.arrays import check_array, check_count

_WINDOW_KEY = b"blindspot.window"


class WindowError(ValueError):
    """Paths, windows or split counts handed to this module are malformed (names the argument,
    the expected and the found shape, dtype or value)."""


#: The largest |coordinate| (m) windows are stored as float32 for: float32's spacing there is
#: 1 mm; farther from the origin (UTM: 5e5, 5e6 m) they stay float64.
FLOAT32_EXACT_M = 1e4


def _storage_dtype(*arrays: np.ndarray) -> type:
    """float32 for coordinates within :data:`FLOAT32_EXACT_M` of the origin, else float64."""
    far = any(a.size and float(np.abs(a).max()) > FLOAT32_EXACT_M for a in arrays)
    return np.float64 if far else np.float32


@dataclass(frozen=True)
class WindowSet:
    """Window/response pairs.

    Attributes:
        x: (N, W, 2) float32 input windows of (x, y) points in metres, oldest first; float64
            when a coordinate lies beyond :data:`FLOAT32_EXACT_M` of the origin (projected
            coordinates such as UTM, where float32 would round positions to decimetres before
            any model translates them).
        y: (N, 2) response of the same dtype: the point right after each window.
        path_id: (N,) int64 id of the path each window came from.
        start: (N,) int64 index (within its path) of each window's first point, or None.

    Raises:
        WindowError: an array not real (ids: whole numbers), of the wrong shape, or not finite.
    """

    x: np.ndarray
    y: np.ndarray
    path_id: np.ndarray
    start: np.ndarray | None = None

    def __post_init__(self) -> None:
        who = "WindowSet"
        x = check_array(self.x, "WindowSet.x", ("N", "W", 2), error=WindowError, who=who)
        n = x.shape[0]
        y = check_array(self.y, "WindowSet.y", (n, 2), error=WindowError, who=who)
        pid = check_array(self.path_id, "WindowSet.path_id", (n,), error=WindowError, who=who,
                          dtype=int)
        dtype = _storage_dtype(x, y)
        object.__setattr__(self, "x", x.astype(dtype, copy=False))
        object.__setattr__(self, "y", y.astype(dtype, copy=False))
        object.__setattr__(self, "path_id", pid)
        if self.start is not None:
            st = check_array(self.start, "WindowSet.start", (n,), error=WindowError, who=who,
                             dtype=int)
            object.__setattr__(self, "start", st)

    def __len__(self) -> int:
        return int(self.x.shape[0])

    @property
    def window(self) -> int:
        """W, the number of points in each input window."""
        return int(self.x.shape[1])

    def subset(self, index: np.ndarray) -> WindowSet:
        """The windows selected by an integer or boolean index array."""
        return WindowSet(
            self.x[index], self.y[index], self.path_id[index], None if self.start is None else self.start[index]
        )

    def futures(self, horizon: int) -> tuple[np.ndarray, np.ndarray]:
        """The ``horizon`` points that follow each window, where this set itself holds them.

        Every window contributes its W inputs and its target to a table of known points per path
        (index ``start + j``); a window's future is points ``start + W .. start + W + H - 1`` of
        its path. Only windows whose whole future is known are returned, so a multi-step error
        (ADE/FDE of a rollout) can be measured on the same split as the one-step error, e.g. the
        validation windows, without the paths they came from.

        Args:
            horizon: H >= 1 future points.

        Returns:
            ``(index, future)``: index (M,) int64 into this set, future (M, H, 2) float32 points
            in metres, oldest first.

        Raises:
            WindowError: ``horizon`` not an integer >= 1, or the set has no ``start`` indices
                (they locate each window in its path).
        """
        horizon = check_count(horizon, "horizon", ge=1, error=WindowError, who="WindowSet.futures")
        if self.start is None:
            raise WindowError("WindowSet.futures: the windows carry no start index (start is None),"
                              " so their futures cannot be located in their paths")
        n, w = len(self), self.window
        if n == 0:
            return np.zeros(0, dtype=np.int64), np.zeros((0, horizon, 2), dtype=self.x.dtype)
        paths, row = np.unique(self.path_id, return_inverse=True)
        length = int(self.start.max()) + w + 1
        known = np.full((len(paths), length, 2), np.nan, dtype=self.x.dtype)
        idx = self.start[:, None] + np.arange(w + 1)                        # (N, W+1)
        known[row[:, None], idx] = np.concatenate([self.x, self.y[:, None]], axis=1)
        ahead = self.start[:, None] + w + np.arange(horizon)                # (N, H)
        inside = (ahead < length).all(axis=1)
        future = np.full((n, horizon, 2), np.nan, dtype=self.x.dtype)
        future[inside] = known[row[inside, None], ahead[inside]]
        keep = np.flatnonzero(np.isfinite(future).all(axis=(1, 2)))
        return keep, future[keep]

    def save(self, path: str | Path) -> Path:
        """Write to Parquet (temporary name in the same folder, then renamed into place).

        Columns: ``path_id`` int64, ``start`` int64 (-1 when unknown), ``x`` list<float32> of the
        window flattened as x0, y0, x1, y1, ..., ``y`` list<float32> [x, y] (list<double> for
        windows far from the origin, as ``x``'s dtype); the window length is stored in the
        schema metadata.
        """
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        n, w = len(self), self.window
        x = pa.FixedSizeListArray.from_arrays(pa.array(self.x.reshape(-1)), 2 * w)
        y = pa.FixedSizeListArray.from_arrays(pa.array(self.y.reshape(-1)), 2)
        start = self.start if self.start is not None else np.full(n, -1, dtype=np.int64)
        table = pa.table({"path_id": self.path_id, "start": start, "x": x, "y": y})
        table = table.replace_schema_metadata({_WINDOW_KEY: str(w).encode()})
        with atomic_path(path) as tmp:
            pq.write_table(table, tmp)
        return path

    @classmethod
    def load(cls, path: str | Path) -> WindowSet:
        """Read a file written by :meth:`save`; raises ValueError naming the file if it is not one."""
        path = Path(path)
        table = pq.read_table(path)
        meta = table.schema.metadata or {}
        missing = {"path_id", "start", "x", "y"} - set(table.column_names)
        if _WINDOW_KEY not in meta or missing:
            raise ValueError(
                f"{path}: not a WindowSet file (expected columns path_id, start, x, y and '{_WINDOW_KEY.decode()}' "
                f"metadata; missing columns {sorted(missing)}, metadata keys {sorted(meta)})"
            )
        w = int(meta[_WINDOW_KEY])
        n = table.num_rows

        def flat(name: str, width: int) -> np.ndarray:
            col = table.column(name).combine_chunks()
            values = np.asarray(col.flatten())      # float32, or float64 far from the origin
            if values.size != n * width:
                raise ValueError(f"{path}: column {name!r} holds {values.size} values, expected {n} x {width}")
            return values

        start = table.column("start").to_numpy()
        return cls(
            x=flat("x", 2 * w).reshape(n, w, 2),
            y=flat("y", 2).reshape(n, 2),
            path_id=table.column("path_id").to_numpy(),
            start=None if n and (start < 0).all() else start,
        )


def windows_per_path(n_points: int, window: int, stride: int = 1) -> int:
    """Number of window/next-point pairs from one complete path: ceil((T - W) / stride)."""
    return max(0, math.ceil((n_points - window) / stride))


def paths_needed(counts: Sequence[int], n_points: int, window: int, stride: int = 1) -> int:
    """Fewest complete (NaN-free) paths :func:`split_by_path` needs for the given split counts."""
    per = windows_per_path(n_points, window, stride)
    if per == 0:
        raise ValueError(f"paths of {n_points} points give no windows of {window} (+1 target)")
    return sum(math.ceil(c / per) for c in counts)


def make_windows(
    paths: np.ndarray,
    window: int,
    stride: int = 1,
    target: str = "next",
    *,
    nan_policy: str = "drop",
    path_ids: np.ndarray | None = None,
) -> WindowSet:
    """All windows of ``window`` points and the point right after each, from every path.

    Window k of path p is ``paths[p, s:s+W]`` with ``s = k * stride`` and target ``paths[p, s+W]``,
    for ``s + W <= T - 1``; windows are ordered by path, then by start.

    Args:
        paths: (P, T, 2) points in metres; NaN rows are missing points.
        window: W >= 1.
        stride: step between window starts, >= 1.
        target: only ``"next"`` (the point following the window) is defined.
        nan_policy: ``"drop"`` windows (inputs or target) containing NaN, or ``"raise"``.
        path_ids: (P,) ids to store in ``path_id``; default ``arange(P)``.

    Returns:
        :class:`WindowSet` with x (N, W, 2), y (N, 2), path_id (N,), start (N,).

    Raises:
        WindowError: ``paths`` not real (P, T, 2) (NaN rows allowed, inf not), window/stride not
            integers >= 1, paths too short, an unknown option, or NaN with ``nan_policy="raise"``.
    """
    who = "make_windows"
    paths = check_array(paths, "paths", ("P", "T", 2), error=WindowError, who=who, allow_nan=True)
    window = check_count(window, "window", ge=1, error=WindowError, who=who)
    stride = check_count(stride, "stride", ge=1, error=WindowError, who=who)
    if target != "next":
        raise WindowError(f"{who}: target: expected 'next', found {target!r}")
    if nan_policy not in ("drop", "raise"):
        raise WindowError(f"{who}: nan_policy: expected 'drop' or 'raise', found {nan_policy!r}")
    n_paths, n_points, _ = paths.shape
    if n_points < window + 1:
        raise WindowError(f"{who}: paths have {n_points} points; a window of {window} plus its "
                          f"target needs {window + 1}")
    ids = (np.arange(n_paths) if path_ids is None else
           check_array(path_ids, "path_ids", (n_paths,), error=WindowError, who=who, dtype=int))

    # (P, T-W, 2, W+1) view -> every stride-th start -> (P, K, W+1, 2)
    view = np.lib.stride_tricks.sliding_window_view(paths, window + 1, axis=1)[:, ::stride]
    k = view.shape[1]
    pairs = np.ascontiguousarray(view.transpose(0, 1, 3, 2), dtype=_storage_dtype(paths)).reshape(
        n_paths * k, window + 1, 2)
    pid = np.repeat(ids, k)
    start = np.tile(np.arange(0, n_points - window, stride), n_paths)
    finite = np.isfinite(pairs).all(axis=(1, 2))
    if not finite.all():
        if nan_policy == "raise":
            bad = np.flatnonzero(~finite)
            raise WindowError(
                f"{bad.size} of {finite.size} windows contain NaN (first: path {pid[bad[0]]}, start {start[bad[0]]}); "
                "fill gaps (interpolate_gaps) or use nan_policy='drop'"
            )
        pairs, pid, start = pairs[finite], pid[finite], start[finite]
    return WindowSet(x=pairs[:, :window], y=pairs[:, window], path_id=pid, start=start)


def interpolate_gaps(paths: np.ndarray) -> np.ndarray:
    """Fill interior missing points (NaN rows) of each path by linear interpolation in time.

    A row counts as missing if either coordinate is NaN. Missing rows before a path's first or
    after its last observed point stay NaN (nothing to interpolate between).

    Args:
        paths: (P, T, 2) or (T, 2).

    Returns:
        float64 array of the same shape.

    Raises:
        WindowError: ``paths`` not real (P, T, 2) or (T, 2), or an inf value.
    """
    arr = check_array(paths, "paths", ("...", "T", 2), error=WindowError, who="interpolate_gaps",
                      allow_nan=True)
    squeeze = arr.ndim == 2
    if squeeze:
        arr = arr[None]
    if arr.ndim != 3:
        raise WindowError(f"interpolate_gaps: paths: expected shape (P, T, 2) or (T, 2), found "
                          f"{arr.shape}")
    n_points = arr.shape[1]
    valid = np.isfinite(arr).all(axis=-1)  # (P, T)
    t = np.broadcast_to(np.arange(n_points), valid.shape)
    prev = np.maximum.accumulate(np.where(valid, t, -1), axis=1)
    nxt = np.minimum.accumulate(np.where(valid, t, n_points)[:, ::-1], axis=1)[:, ::-1]
    fill = ~valid & (prev >= 0) & (nxt < n_points)
    p0 = np.take_along_axis(arr, np.clip(prev, 0, n_points - 1)[..., None], axis=1)
    p1 = np.take_along_axis(arr, np.clip(nxt, 0, n_points - 1)[..., None], axis=1)
    frac = ((t - prev) / np.maximum(nxt - prev, 1))[..., None]
    out = arr.copy()
    out[fill] = (p0 + frac * (p1 - p0))[fill]
    out[~valid & ~fill] = np.nan
    return out[0] if squeeze else out


def last_point_measured(ws: WindowSet, measured: np.ndarray) -> np.ndarray:
    """Whether each window's last input point is a radar point, not a filled gap.

    :func:`interpolate_gaps` fills a missed point from the measurements on both sides of it. At
    a window's last point the later one lies after the window, at or beyond its target, so a
    window ending in a filled gap has seen part of its own future. Keep only windows where this
    is True; interior gaps (both neighbours inside the window) and gaps at its start (filled
    from the past) are causal and stay.

    Args:
        ws: windows cut from ``measured`` (after filling), with ``start`` indices.
        measured: (P, T, 2) the paths before filling, m, NaN where the radar gave no point;
            ``ws.path_id`` indexes its rows.

    Returns:
        (N,) bool.

    Raises:
        WindowError: ``measured`` not (P, T, 2), ``ws`` without start indices, or a window
            that does not lie inside ``measured``.
    """
    who = "last_point_measured"
    m = check_array(measured, "measured", ("P", "T", 2), error=WindowError, who=who,
                    allow_nan=True)
    if ws.start is None:
        raise WindowError(f"{who}: the windows carry no start index (start is None)")
    last = ws.start + ws.window - 1
    if len(ws) and (ws.path_id.min() < 0 or ws.path_id.max() >= m.shape[0]
                    or last.max() >= m.shape[1]):
        raise WindowError(f"{who}: windows reach path {int(ws.path_id.max())}, point "
                          f"{int(last.max())}; measured has shape {m.shape}")
    return np.isfinite(m[ws.path_id, last]).all(axis=-1)


def split_by_path(
    ws: WindowSet, counts: Sequence[int] = (20000, 4000, 500), seed: int = 0
) -> tuple[WindowSet, ...]:
    """Split windows into len(counts) sets of exactly ``counts[i]`` windows, no path in two sets.

    The path ids are shuffled (``np.random.default_rng(seed)``); split 0 takes paths in that order
    until it holds at least ``counts[0]`` windows, split 1 continues from the next path, and so on.
    Each split then keeps a random subset of exactly ``counts[i]`` of its windows (in their
    original order), so at most one path per split is partly used. Leftover paths go unused.

    Raises:
        WindowError: a count not an integer >= 0, or the windows' paths cannot cover the counts
            (says how many windows were found).
    """
    counts = [check_count(c, f"counts[{i}]", error=WindowError, who="split_by_path")
              for i, c in enumerate(counts)]
    rng = np.random.default_rng(seed)
    ids, inverse = np.unique(ws.path_id, return_inverse=True)
    order = rng.permutation(ids.size)  # shuffled position -> unique path index
    rank = np.empty_like(order)
    rank[order] = np.arange(ids.size)  # unique path index -> shuffled position
    per_path = np.bincount(inverse, minlength=ids.size)[order]
    cum = np.concatenate([[0], np.cumsum(per_path)])
    out: list[WindowSet] = []
    first = 0  # shuffled position of the next unused path
    for i, need in enumerate(counts):
        last = int(np.searchsorted(cum, cum[first] + need, side="left"))  # paths [first, last) cover need
        if cum[min(last, ids.size)] - cum[first] < need:
            raise WindowError(
                f"split_by_path: {len(ws)} windows from {ids.size} paths cannot fill counts {counts} "
                f"(split {i} wants {need}, {int(cum[-1] - cum[first])} windows left); generate more paths"
            )
        members = np.flatnonzero((rank[inverse] >= first) & (rank[inverse] < last))
        keep = np.sort(rng.choice(members.size, size=need, replace=False))
        out.append(ws.subset(members[keep]))
        first = last
    return tuple(out)


def choose_windows(splits: dict[str, WindowSet], motion_of: Mapping[int, str],
                   n_points: Mapping[int, int], layout: Sequence[tuple[str, int]],
                   horizon: int) -> list[tuple[str, str, int, int]]:
    """Windows to roll out for a figure: ``(motion, split, path_id, start)`` per panel.

    splits : split name -> :class:`WindowSet` with ``start`` indices, searched in this order;
    motion_of / n_points : path id -> its motion ("approaching", ...) / its number of points;
    layout : ``(motion, number of panels)`` in panel order; horizon : rollout steps wanted.

    Deterministic: paths of the wanted motion from the first split (lowest id first), then from
    the next; when a motion has fewer paths than panels, the next panel takes the latest window
    of a path already used (then the one before it...). Every window leaves room for the
    rollout (``min(horizon, points left after the window)`` steps). Raises ``ValueError`` when a
    split has no start indices, a motion no path or a path no such window.
    """
    for name, ws in splits.items():
        if ws.start is None:
            raise ValueError(f"split {name!r} has no window start indices")
    chosen = []
    for motion, count in layout:
        candidates = [(name, int(p)) for name, ws in splits.items()
                      for p in np.unique(ws.path_id) if motion_of[p] == motion]
        if not candidates:
            raise ValueError(f"no {motion} path in the splits {list(splits)}")
        for k in range(count):
            name, pid = candidates[k % len(candidates)]
            ws = splits[name]
            room = n_points[pid] - ws.window - min(horizon, n_points[pid] - ws.window)
            starts = np.sort(ws.start[(ws.path_id == pid) & (ws.start <= room)])
            if not len(starts):
                raise ValueError(f"{name} path {pid} has no window leaving room for a rollout")
            use = k // len(candidates)  # 0: earliest window; 1: latest; then stepping back
            start = starts[0] if use == 0 else starts[max(0, len(starts) - use)]
            chosen.append((motion, name, pid, int(start)))
    return chosen
