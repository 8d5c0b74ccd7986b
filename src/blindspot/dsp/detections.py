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
* :func:`angle_peaks`: the same rule in range, Doppler and angle together. A cell is kept when,
  at the angle of its own beam peak, its beam is at least as strong as each range-Doppler
  neighbour's beam at that angle. A weak target on the flank of a stronger one at another
  angle (a child beside a parked car, at the car's range and nearly its Doppler) keeps its
  cell; the flank cells of one target at one angle are still dropped.
* :func:`detection_order`: within each frame, moving detections first, then by decreasing
  power; :func:`rank_in_frame` gives each detection's position in its frame, so the DOA budget
  (``detect.max_detections`` angles per frame) is a comparison, not a loop.
"""

from __future__ import annotations

import numpy as np
import scipy.fft

from blindspot.arrays import check_same_shape, checked_array

__all__ = ["DetectionError", "angle_peaks", "fft_beam_angle_deg", "local_maxima",
           "local_maxima_at", "detection_order", "rank_in_frame"]

ANGLE_FFT = 256         # beam-scan points of angle_peaks over sin(theta) in [-1, 1)
ANGLE_PEAK_MARGIN_DB = 13.0   # angle_peaks: a peak's least height over its beam's median


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


def angle_peaks(snapshots: np.ndarray, centre: int, spacing_wl: float, n_fft: int = ANGLE_FFT,
                margin_db: float = ANGLE_PEAK_MARGIN_DB) -> tuple[np.ndarray, np.ndarray]:
    """The range-Doppler-angle local-maximum rule of candidate cells from their neighbourhoods.

    Each candidate's neighbourhood snapshots are beam-scanned with a Hann-tapered FFT over the
    uniform linear array's elements (Bartlett beam on ``n_fft`` points of sin(theta) for a
    half-wavelength ULA; the taper holds the sidelobes near -31 dB, so a target 20-30 dB
    stronger at another angle does not mask the candidate through them; Harris 1978, Proc.
    IEEE 66(1), table 1). The candidate is kept when its own cell's beam has a peak (a local
    maximum over angle) that is

    * at least as strong as every other cell's beam of the neighbourhood at that angle: a local
      maximum in range, Doppler and angle together; a cell on the flank of a stronger target
      keeps its own target at another angle and loses the flank of the stronger one; and
    * ``margin_db`` above the median of the cell's beam over angle (the beam's noise and
      sidelobe floor). Without it the noise of a flank cell would find some angle where it
      beats its neighbours: a noise-only beam's power is exponential, and its ~60 independent
      beams exceed 13 dB over the median (20 x, i.e. 13.9 x the mean) with probability about
      60 exp(-13.9) = 5e-5.

    Args:
        snapshots: (D, E, L) complex, each candidate's L neighbourhood cells on the E ULA
            elements, TDM-compensated with the candidate's unwrapped velocity (with a wrong
            Doppler ambiguity order the TX slots' leftover phase splits a strong target's beam
            into lobes that can mask the candidate;
            :func:`blindspot.dsp.driving.angle_peak_candidates` chooses the order first).
        centre: the index of the candidate's own cell along L.
        spacing_wl: the ULA's element spacing in wavelengths (steering phase
            ``2 pi e spacing sin(theta)`` on element e).
        n_fft: beam-scan points (>= E).
        margin_db: the peak's least height over the beam's median, dB.

    Returns:
        keep (D,) bool, and angle_deg (D,): the angle of the strongest peak that qualifies
        (parabolic interpolation of the beam in dB between scan points; NaN where none does).
        A cell on a stronger target's flank is kept for its own target, whose angle this is,
        not the angle of the cell's strongest return; the chain picks the angle estimator's
        peak nearest to it.

    Raises:
        DetectionError: snapshots not a 3-D complex array of finite values, ``centre`` not an
            integer in 0..L-1, ``n_fft`` below the element count, or a spacing that is not
            positive.
    """
    x = checked_array(snapshots, "snapshots", DetectionError, where="angle_peaks", ndim=3,
                      kind="numeric", axes="neighbourhood snapshots (D, elements, cells)")
    if not np.iscomplexobj(x):
        raise DetectionError(f"angle_peaks: snapshots must be complex (the array's phases); "
                             f"found dtype {x.dtype}")
    n_el, n_l = x.shape[1:]
    if not (isinstance(centre, (int, np.integer)) and 0 <= centre < n_l):
        raise DetectionError(f"angle_peaks: centre must be an integer index of the {n_l} "
                             f"neighbourhood cells (0..{n_l - 1}); found {centre!r}")
    if n_fft < n_el:
        raise DetectionError(f"angle_peaks: n_fft must be >= the {n_el} elements; found {n_fft}")
    if not (np.isfinite(spacing_wl) and spacing_wl > 0):
        raise DetectionError(f"angle_peaks: spacing_wl must be a positive element spacing in "
                             f"wavelengths; found {spacing_wl}")
    if not x.shape[0]:
        return np.zeros(0, dtype=bool), np.zeros(0)
    taper = np.hanning(n_el + 2)[1:-1].astype(np.float32)        # no zero end weights
    tapered = np.ascontiguousarray(x.transpose(0, 2, 1), dtype=np.complex64) * taper
    z = scipy.fft.fft(tapered, n=n_fft, axis=-1)                     # (D, L, n_fft)
    beam = z.real ** 2 + z.imag ** 2
    own = beam[:, centre, :]                                         # (D, n_fft)
    local_max = (own >= np.roll(own, 1, axis=1)) & (own >= np.roll(own, -1, axis=1))
    beats_neighbours = own >= beam.max(axis=1)
    floor = np.median(own, axis=1, keepdims=True) * 10 ** (margin_db / 10)
    ok = local_max & beats_neighbours & (own >= floor)                 # (D, n_fft)
    keep = ok.any(axis=1)
    k = np.argmax(np.where(ok, own, -1.0), axis=1)                     # strongest qualifying
    rows = np.arange(len(k))
    lg = np.log(np.maximum(own, np.finfo(np.float32).tiny))
    a, b, c = lg[rows, k - 1], lg[rows, k], lg[rows, (k + 1) % n_fft]
    den = a - 2 * b + c
    delta = np.where(den < 0, 0.5 * (a - c) / np.where(den < 0, den, -1.0), 0.0)
    return keep, np.where(keep, fft_beam_angle_deg(k + delta, n_fft, spacing_wl), np.nan)


def fft_beam_angle_deg(bins: np.ndarray, n_fft: int, spacing_wl: float) -> np.ndarray:
    """(...) deg: the arrival angle of (fractional) bins of an ``n_fft``-point FFT taken over
    the elements of a uniform linear array of element spacing ``spacing_wl`` wavelengths: the
    bin is a phase step of ``bins / n_fft`` cycles per element, wrapped to [-0.5, 0.5), and
    sin(theta) = cycles / spacing (clipped to [-1, 1] where the spacing exceeds half a
    wavelength's reach)."""
    cycles = (np.asarray(bins) / n_fft + 0.5) % 1.0 - 0.5             # per element, [-0.5, 0.5)
    return np.degrees(np.arcsin(np.clip(cycles / spacing_wl, -1.0, 1.0)))


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
