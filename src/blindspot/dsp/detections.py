"""From CFAR cells to the detections whose angles are estimated: peak cells, order and budget.

Batch-native: every function takes the cells of many frames (or patches) at once, identified by
a frame index, so the full chain (:class:`~blindspot.dsp.chain.DetectionChain`, frames of a
capture) and the reduced measurement of the synthesis room (patches of thousands of frames) run
the same steps.

* :func:`local_maxima`: the ``peak_only`` rule, a cell is kept when it is at least as strong as
  its 8 neighbours (Doppler wraps; rows beyond the first and last range bin count as -inf), so
  one target gives one detection per spectral peak rather than its whole window main lobe.
  :func:`local_maxima_at` applies the same rule to given cells only (the CFAR cells of a
  batch: tens of cells instead of a whole map).
* :func:`detection_order`: within each frame, moving detections first, then by decreasing
  power; :func:`rank_in_frame` gives each detection's position in its frame, so the DOA budget
  (``detect.max_detections`` angles per frame) is a comparison, not a loop.
"""

from __future__ import annotations

import numpy as np

from blindspot.arrays import check_same_shape, checked_array

__all__ = ["DetectionError", "local_maxima", "local_maxima_at", "detection_order",
           "rank_in_frame"]


class DetectionError(ValueError):
    """A detection map or per-detection array of the wrong shape or kind, or holding NaN/inf."""


def local_maxima(power: np.ndarray, row_exists: np.ndarray | None = None) -> np.ndarray:
    """Cells at least as strong as each of their 8 neighbours.

    Args:
        power: (..., range, doppler) detection map(s), any leading batch axes (frames).
        row_exists: optional (..., range) bool: False for rows that lie outside the full map
            (a patch that hangs over the first or last range bin); those rows count as -inf,
            exactly as the rows beyond the map's edges do.

    Returns:
        (..., range, doppler) bool. Doppler wraps (its spectrum is periodic); range does not.

    Raises:
        DetectionError: ``power`` is not a real map of at least 2 axes without NaN (inf is a
            valid strongest cell), or ``row_exists`` is not a bool array of its leading shape.
    """
    p = checked_array(power, "power", DetectionError, where="local_maxima",
                      axes="a detection map (..., range, doppler)", min_ndim=2, kind="real",
                      finite=False).astype(np.float64, copy=False)  # -inf padding needs floats
    if np.isnan(p).any():
        raise DetectionError(f"local_maxima: power must be a detection map without NaN; found "
                             f"{int(np.isnan(p).sum())} NaN cell(s) of {p.size}")
    if row_exists is not None:
        rows_ok = checked_array(row_exists, "row_exists", DetectionError, where="local_maxima",
                                axes=f"a mask {p.shape[:-1]} (..., range)", kind="bool",
                                ndim=p.ndim - 1)
        if rows_ok.shape != p.shape[:-1]:
            raise DetectionError(f"local_maxima: row_exists must be {p.shape[:-1]} (..., range), "
                                 f"found {rows_ok.shape}")
        p = np.where(rows_ok[..., None], p, -np.inf)
    if p.size == 0:  # an empty map has no cells (and no column to wrap)
        return np.zeros(p.shape, dtype=bool)
    # one padded copy: -inf rows beyond both range ends, the Doppler columns wrapped round
    n_rows, n_cols = p.shape[-2:]
    q = np.empty(p.shape[:-2] + (n_rows + 2, n_cols + 2))
    q[..., (0, -1), :] = -np.inf
    q[..., 1:-1, 1:-1] = p
    q[..., 1:-1, 0] = p[..., -1]
    q[..., 1:-1, -1] = p[..., 0]
    is_max = np.ones(p.shape, dtype=bool)
    for dr in (-1, 0, 1):  # the 8 neighbours, each one whole-batch comparison of a shifted view
        for dd in (-1, 0, 1):
            if dr == 0 and dd == 0:
                continue
            is_max &= p >= q[..., 1 + dr:1 + dr + n_rows, 1 + dd:1 + dd + n_cols]
    if row_exists is not None:
        is_max &= rows_ok[..., None]
    return is_max


_NEIGHBOURS = np.array([(dr, dd) for dr in (-1, 0, 1) for dd in (-1, 0, 1) if dr or dd])


def local_maxima_at(power: np.ndarray, frame: np.ndarray, row: np.ndarray,
                    col: np.ndarray) -> np.ndarray:
    """:func:`local_maxima` of the cells (frame, row, col) only, without ``row_exists``:
    ``local_maxima(power)[frame, row, col]``, at the cost of gathering 8 neighbours per cell.

    Args:
        power: (frames, range, doppler) detection maps, no NaN (the chain's map is checked
            finite where it is made).
        frame, row, col: (D,) integer indices of the cells.

    Returns:
        (D,) bool. Raises DetectionError for a map that is not 3-D real, or indices that are
        not (D,) integers of one length.
    """
    p = checked_array(power, "power", DetectionError, where="local_maxima_at",
                      axes="detection maps (frames, range, doppler)", ndim=3, kind="real",
                      finite=False)
    f, r, c = _per_detection("local_maxima_at", frame=(frame, "index"), row=(row, "index"),
                             col=(col, "index"))
    n_rows, n_cols = p.shape[1:]
    rr = r[:, None] + _NEIGHBOURS[:, 0]                      # (D, 8)
    cc = (c[:, None] + _NEIGHBOURS[:, 1]) % n_cols           # Doppler wraps
    inside = (rr >= 0) & (rr < n_rows)                       # rows beyond the map: -inf
    nb = p[f[:, None], np.clip(rr, 0, n_rows - 1), cc]
    return np.all((p[f, r, c][:, None] >= nb) | ~inside, axis=1)


def detection_order(frame: np.ndarray, power: np.ndarray, is_moving: np.ndarray) -> np.ndarray:
    """Permutation that sorts detections by frame, then moving before static, then by
    decreasing power (stable: equal keys keep their input order).

    frame, power, is_moving: (D,) -> (D,) int indices. Raises DetectionError for arrays that
    are not (D,) of one length (frame: integers, power: finite reals, is_moving: booleans)."""
    f, p, m = _per_detection("detection_order", frame=(frame, "index"), power=(power, "real"),
                             is_moving=(is_moving, "bool"))
    return np.lexsort((-p, ~m, f))


def _per_detection(where: str, **arrays: tuple[np.ndarray, str]) -> list[np.ndarray]:
    """Each ``name=(array, kind)`` checked as (D,) of its kind, all of one length D."""
    out = [checked_array(a, name, DetectionError, where=where, axes="one value per detection (D,)",
                         ndim=1, kind=kind) for name, (a, kind) in arrays.items()]
    check_same_shape(DetectionError, where, "the per-detection arrays", **dict(zip(arrays, out)))
    return out


def rank_in_frame(frame_sorted: np.ndarray) -> np.ndarray:
    """Position of each detection within its frame, for detections sorted by frame.

    frame_sorted: (D,) non-decreasing frame indices -> (D,) int64 (0 for the first of each
    frame). Raises DetectionError when ``frame_sorted`` is not (D,) sorted integers."""
    (f,) = _per_detection("rank_in_frame", frame_sorted=(frame_sorted, "integer"))
    if f.size and np.any(np.diff(f) < 0):
        raise DetectionError("rank_in_frame: detections must be sorted by frame")
    return np.arange(f.size, dtype=np.int64) - np.searchsorted(f, f, side="left")
