"""Array snapshots of CFAR detections, for angle estimation.

Two ways to collect the L snapshots of a detection at (range bin r, Doppler bin d):

* ``cells`` (default): the range-Doppler cells of a small neighbourhood around (r, d) after both
  FFTs (half-widths ``half = (range, doppler)``; range clipped at the edges, Doppler wrapped). The
  Doppler FFT has already separated the moving pedestrian from the static car at the same range,
  so the covariance holds only what moves at that speed. The neighbours of a windowed peak carry
  the same directions (scaled), so they mostly average noise: L = 9 for (1, 1), far fewer than the
  86 elements, which is why the chain uses forward-backward averaging and spatial smoothing
  (K-element subarrays, 2 (86 - K + 1) L effective snapshots, full rank for K < ~2 (86 - K + 1) L).
* ``chirps``: the detection's range bin across the chirp loops (L = n_chirps = 64 time samples)
  from the range FFT, i.e. the paper's "antenna data along the time axis at the detected range".
  Everything at that range (the parked car included) is in it; the TDM correction is right only
  for the detection's own Doppler. With 64 < 86 snapshots the plain covariance is singular too.

Both return ``(D, n_tx, n_rx, L)`` (TX in firing order); ``VirtualArray.ula_snapshots`` then picks
the ULA elements, giving ``(D, n_ula, L)``.
"""

from __future__ import annotations

import numpy as np

from blindspot.arrays import check_same_shape, checked_array
from blindspot.dsp.config import SNAPSHOT_MODES


class SnapshotError(ValueError):
    """Range-Doppler data or detection indices of the wrong shape or kind, or out of range."""


def _indices(where: str, data: np.ndarray, frame: np.ndarray | None,
             **bins: tuple[np.ndarray, int]) -> tuple[np.ndarray | None, list[np.ndarray]]:
    """Detection indices checked: each ``name=(array, n_bins)`` (D,) integers in [0, n_bins);
    ``frame`` (D,) in [0, data.shape[0]) when given; all of one length."""
    out = []
    named = dict(bins)
    if frame is not None:
        named = {"frame": (frame, data.shape[0]), **named}
    for name, (a, n) in named.items():
        a = checked_array(a, name, SnapshotError, where=where, kind="index", ndim=1,
                          axes="a bin index per detection (D,)")
        if a.size and a.max() >= n:
            raise SnapshotError(f"{where}: {name} must index {n} bins (0..{n - 1}); found "
                                f"{a.max()}")
        out.append(a)
    check_same_shape(SnapshotError, where, "the detection indices", **dict(zip(named, out)))
    return (out[0], out[1:]) if frame is not None else (None, out)


def cell_snapshots(rd_native: np.ndarray, range_bin: np.ndarray, doppler_bin: np.ndarray,
                   half: tuple[int, int] = (1, 1), frame: np.ndarray | None = None, *,
                   elements: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Neighbourhood cells of each detection.

    rd_native : (doppler, tx, rx, range) complex (``RangeDoppler.native`` layout) or, with
                ``frame``, a batch (frames, doppler, tx, rx, range)
    range_bin, doppler_bin : (D,) ints; frame : (D,) index into the batch axis (batched only)
    elements : optional (tx index (E,), rx index (E,)) of the channels wanted, e.g. the ULA
               elements (``VirtualArray.ula_index``): only those cells are gathered (each is a
               cache miss in a frame-sized array, so the 86 ULA channels cost less than half of
               all 192)
    returns (D, tx, rx, L) with L = (2 half_r + 1)(2 half_d + 1), the centre cell first, or
    (D, E, L) with ``elements`` (the same values as ``[:, tx_index, rx_index]`` of the former)
    raises SnapshotError when ``rd_native`` is not complex-valued with 4 axes (5 with
    ``frame``) or an index is not a (D,) integer array within its axis; NaN/inf cells are left
    to the angle estimator, which names them (:class:`~blindspot.dsp.doa.DoaError`)
    """
    rd_native = checked_array(rd_native, "rd_native", SnapshotError, where="cell_snapshots",
                              kind="numeric", finite=False, ndim=4 if frame is None else 5,
                              axes="range-Doppler data (doppler, tx, rx, range)" + (
                                  "" if frame is None else " per frame: (frames, doppler, tx, "
                                  "rx, range)"))
    n_dop, _, _, n_rng = rd_native.shape[-4:]
    frame, (range_bin, doppler_bin) = _indices("cell_snapshots", rd_native, frame,
                                               range_bin=(range_bin, n_rng),
                                               doppler_bin=(doppler_bin, n_dop))
    dr, dd = np.meshgrid(np.arange(-half[0], half[0] + 1), np.arange(-half[1], half[1] + 1),
                         indexing="ij")
    dr, dd = dr.ravel(), dd.ravel()
    centre_first = np.argsort((dr != 0) | (dd != 0), kind="stable")
    dr, dd = dr[centre_first], dd[centre_first]
    rr = np.clip(np.asarray(range_bin)[:, None] + dr, 0, n_rng - 1)  # (D, L)
    ds = (np.asarray(doppler_bin)[:, None] + dd) % n_dop
    if elements is not None:
        tx, rx = (checked_array(e, name, SnapshotError, where="cell_snapshots", kind="index",
                                ndim=1, axes="a channel index per element (E,)")
                  for name, e in zip(("elements[0] (tx)", "elements[1] (rx)"), elements))
        n_tx, n_rx = rd_native.shape[-3:-1]
        if tx.shape != rx.shape or (tx.size and (tx.max() >= n_tx or rx.max() >= n_rx)):
            raise SnapshotError(f"cell_snapshots: elements must be (tx, rx) index arrays of one "
                                f"length within ({n_tx}, {n_rx}); found shapes {tx.shape}, "
                                f"{rx.shape}")
        lead = () if frame is None else (np.asarray(frame)[:, None, None],)
        # (D, L, E) -> (D, E, L)
        return rd_native[(*lead, ds[:, :, None], tx, rx, rr[:, :, None])].transpose(0, 2, 1)
    if frame is None:
        cells = rd_native[ds, :, :, rr]  # (D, L, tx, rx): advanced indices first
    else:
        cells = rd_native[np.asarray(frame)[:, None], ds, :, :, rr]
    return cells.transpose(0, 2, 3, 1)


def chirp_snapshots(range_profiles: np.ndarray, range_bin: np.ndarray,
                    frame: np.ndarray | None = None) -> np.ndarray:
    """The detections' range bins across chirps.

    range_profiles : (chirps, tx, rx, range) complex (range FFT only) or, with ``frame``,
                     (frames, chirps, tx, rx, range)
    range_bin : (D,) ints; frame : (D,) index into the batch axis (batched only)
    returns (D, tx, rx, chirps)
    raises SnapshotError as :func:`cell_snapshots`
    """
    range_profiles = checked_array(
        range_profiles, "range_profiles", SnapshotError, where="chirp_snapshots",
        kind="numeric", finite=False, ndim=4 if frame is None else 5,
        axes="range profiles (chirps, tx, rx, range)" + (
            "" if frame is None else " per frame: (frames, chirps, tx, rx, range)"))
    frame, (range_bin,) = _indices("chirp_snapshots", range_profiles, frame,
                                   range_bin=(range_bin, range_profiles.shape[-1]))
    if frame is None:
        return range_profiles[..., np.asarray(range_bin)].transpose(3, 1, 2, 0)
    # advanced indices on the first and last axes, separated by slices: they go first
    return range_profiles[np.asarray(frame), ..., np.asarray(range_bin)].transpose(0, 2, 3, 1)
