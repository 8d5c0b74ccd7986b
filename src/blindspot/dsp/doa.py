"""Angle of arrival on a linear array: MUSIC (the paper's eq. 5-6), Bartlett and Capon.

Model: element m at position ``p_m`` (wavelengths, along the array axis) sees a plane wave from
angle theta (radians from boresight, positive towards +x) with the phase ``2 pi p_m sin theta``;
the steering vector is ``a(theta) = exp(j 2 pi p sin theta)`` (unit-modulus, ``|a|^2 = M``).

Snapshots are complex ``(M, L)`` (one angle problem) or batched ``(D, M, L)`` (D detections at
once); every step is batched: covariance ``R = X X^H / L`` (D, M, M), one batched ``eigh`` (for
MUSIC only the ``n_signals`` principal eigenvectors), the scan as one matrix product against a
steering matrix cached per (array, grid), peak refinement as a few batched Newton steps.

All three methods reduce to a quadratic form ``g(u) = |B^H a(u)|^2`` of ``u = sin theta``:

* MUSIC   B = E_s (the ``n_signals`` principal eigenvectors); P = 1 / (a^H E_n E_n^H a)
          = 1 / (M - g); peak = maximum of g.
* Bartlett B = U Lambda^(1/2) (so B B^H = R); P = a^H R a / M = g / M; peak = maximum of g.
* Capon   B = U Lambda^(-1/2) (B B^H = R^-1); P = 1 / (a^H R^-1 a) = 1 / g; peak = minimum of g.

Peaks are found on the grid (local maxima, strongest first) and refined between grid points by
Newton's method on g(u) with analytic derivatives (a' = j 2 pi p a, a'' = -(2 pi p)^2 a), each
step kept inside the neighbouring grid points; near a peak g is quadratic in u to high accuracy,
so a few steps reach the exact maximiser of the pseudo-spectrum (needed to reach the Cramer-Rao
bound, whose standard deviation is far below any practical grid step).

Which peak is a detection's angle (``peak_order``): ``"spectrum"`` ranks the peaks by their
pseudo-spectrum height (the paper). A MUSIC peak's height says how nearly a direction is
orthogonal to the noise subspace, not how much power comes from it: a point-like weak return
gives a sharper, higher peak than a strong extended one (a body's parts; a car corner beside a
child in one range-Doppler cell), so the highest peak can be the weaker source.
``"power"`` takes the peaks of the ``n_signals``-source model (at least ``n_targets``) and ranks
them by their least-squares source powers, fitted jointly to the full array's snapshots: the
deterministic (conditional) signal model's amplitudes ``S = (A^H A)^-1 A^H X`` at the
estimated angles (Stoica & Moses, *Spectral Analysis of Signals*, 2005, ch. 6), with a ridge
(:data:`POWER_RIDGE`). The fit assumes no particular correlation between the sources, so
coherent ones are fitted as well as independent ones.

Coherent sources (a car's scatterers in one range-Doppler cell) make R rank-deficient in the
signal part; ``forward_backward=True`` (needs a centro-symmetric array) and spatial smoothing
(``subarray=K``: average of the covariances of all contiguous K-element subarrays of a uniform
array) restore the rank at the cost of aperture. ``loading`` adds ``loading * tr(R)/M`` to the
diagonal (needed for Capon with fewer snapshots than elements).

The subspace ``B`` is computed with numpy and scipy (LAPACK through OpenBLAS, whose kernels
:mod:`blindspot.kernels` pins), never with PyTorch: torch's complex products and ``eigh`` run in
MKL, whose AVX2 branch gives other last bits on an AMD CPU than on an Intel one (Intel documents
its conditional numerical reproducibility for Intel processors only), so an MKL-computed
subspace made the committed ``dvc.lock`` fail on a fresh AMD machine (issue 10). A torch
back-end that lived here until 2026-12-03 was also slower on the project's AMD EPYC machines
(735-902 against 585-631 us per detection for 86-element unitary MUSIC with 64-element
smoothing).

Large batches are processed in blocks of :data:`BLOCK_DETECTIONS` detections to bound memory.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from blindspot.arrays import checked_array
from blindspot.dsp.config import DOA_METHODS as METHODS
from blindspot.dsp.config import PEAK_ORDERS

DEFAULT_GRID_DEG = np.arange(-90.0, 90.0 + 0.125, 0.25)  # -90 .. 90 deg, 721 points
# peak_order "power": ridge of the joint least-squares fit, as a fraction of the Gram matrix's
# diagonal (M). It keeps the fit solvable with a missing peak (a zero steering row) and bounds
# the noise gain of nearly parallel candidates: on a 0.5013-wavelength array u = -1 aliases to
# u = +1.003, so peaks at -90, +90 and about 83 deg are nearly one steering vector, and without
# a ridge a noise peak there could be fitted several times the true source's power. It scales
# an isolated source's power by 1 / (1 + ridge)^2, the same for every peak.
POWER_RIDGE = 1e-2
# detections per block: the block's (block, M, M) covariances stay in cache (at 64, 7.6 MB for
# the 86-element ULA; at 512 they went through memory: 0.51 -> 0.44 s for 1,357 driving
# detections, the same bytes, as a detection's angle never depends on its block)
BLOCK_DETECTIONS = 64


class DoaError(ValueError):
    """Bad angle-estimation arguments."""


# ---------------------------------------------------------------------------------------------
# steering and covariance


def steering_matrix(positions: np.ndarray, angles_deg: np.ndarray) -> np.ndarray:
    """(M, G) complex128 steering vectors exp(j 2 pi p sin theta) for positions (M,) in
    wavelengths and angles (G,) in degrees from boresight. Raises DoaError for other input."""
    p = _positions(positions)
    g = checked_array(angles_deg, "angles_deg", DoaError, kind="real", ndim=1,
                      axes="an angle grid (G,) in degrees")
    u = np.sin(np.radians(g.astype(np.float64)))
    return np.exp(2j * np.pi * np.outer(p, u))


@lru_cache(maxsize=16)
def _steering_cached(p_bytes: bytes, g_bytes: bytes) -> np.ndarray:
    a = steering_matrix(np.frombuffer(p_bytes), np.frombuffer(g_bytes))
    a.setflags(write=False)
    return a


def _positions(positions: np.ndarray) -> np.ndarray:
    """(M,) float64 element positions in wavelengths, M >= 1, finite."""
    p = checked_array(positions, "positions", DoaError, kind="real", ndim=1,
                      min_lengths={0: 1}, axes="element positions (M,) in wavelengths")
    return p.astype(np.float64, copy=False)


def _as_batch(snapshots: np.ndarray, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
    p = _positions(positions)
    x = checked_array(snapshots, "snapshots", DoaError, kind="numeric", ndim=(2, 3), finite=False,
                      axes=f"array snapshots (M, L) or (D, M, L) with M = {p.size} elements")
    single = x.ndim == 2
    if single:
        x = x[None]
    if x.ndim != 3 or x.shape[1] != p.size:
        raise DoaError(
            f"snapshots must be (M, L) or (D, M, L) with M = {p.size} elements (len(positions)), "
            f"got shape {np.shape(snapshots)}"
        )
    if x.shape[2] < 1:
        raise DoaError("snapshots need at least one snapshot (L >= 1)")
    if not np.all(np.isfinite(x)):
        bad = int(np.count_nonzero(~np.isfinite(x)))
        raise DoaError(f"snapshots contain {bad} non-finite (NaN/inf) value(s) of {x.size}: "
                       "angle estimation needs finite array data")
    return x.astype(np.complex128, copy=False), p, single


def _close(a: np.ndarray, b, rtol: float = 1e-9, atol: float = 1e-12) -> bool:
    """``np.allclose(a, b, rtol, atol)`` for finite float arrays (element positions), as one
    comparison: allclose's own NaN/inf handling costs more than the test on 86 elements, and
    it runs on every call."""
    return bool(np.all(np.abs(a - b) <= atol + rtol * np.abs(b)))


def _subarray_size(p: np.ndarray, subarray: int | None) -> int:
    """K, the elements of the smoothing subarray (M without smoothing); raises DoaError for a
    size outside [2, M] or for smoothing on a non-uniform array."""
    m = p.size
    if subarray is None or subarray == m:
        return m
    if not (isinstance(subarray, (int, np.integer)) and 2 <= subarray <= m):
        raise DoaError(f"subarray must be an integer in [2, {m}] (elements), got {subarray!r}")
    step = np.diff(p)
    if not _close(step, step[0]):
        raise DoaError("spatial smoothing needs a uniform linear array (equal spacings)")
    return int(subarray)


def _check_n_signals(n_signals: int, k: int) -> None:
    if not (isinstance(n_signals, (int, np.integer)) and 1 <= n_signals < k):
        raise DoaError(f"n_signals must be an integer in [1, {k - 1}] (< elements), "
                       f"got {n_signals!r}")


def _smoothed(x: np.ndarray, p: np.ndarray, subarray: int | None
              ) -> tuple[np.ndarray | None, np.ndarray, np.ndarray | None]:
    """Snapshots x (D, M, L) -> (x, p, None) without smoothing, or (None, p_sub, R (D, K, K))
    with: the spatially smoothed covariance, the mean of the covariances of the M - K + 1
    contiguous K-element subarrays.

    R is computed as the full covariance ``x x^H / L`` (D, M, M) averaged over its diagonal K x K
    blocks (a strided view stepping down the diagonal, no copy): M^2 L + (M - K + 1) K^2
    operations per detection, against (M - K + 1) L K^2 for the covariance of the stacked
    subarray snapshots (on the MMWCAS ULA with K = 64, L = 9: 0.16 M against 0.85 M)."""
    m, n_snap = p.size, x.shape[2]
    subarray = _subarray_size(p, subarray)
    if subarray == m:
        return x, p, None
    n_sub = m - subarray + 1
    full = x @ x.conj().transpose(0, 2, 1)
    s0, s1, s2 = full.strides
    blocks = np.lib.stride_tricks.as_strided(
        full, (full.shape[0], n_sub, subarray, subarray), (s0, s1 + s2, s1, s2), writeable=False)
    return None, p[:subarray], blocks.sum(axis=1) / (n_sub * n_snap)


def _q_h(x: np.ndarray) -> np.ndarray:
    """Q^H x along axis 1 for the unitary centro-Hermitian Q of size K (Huarng & Yeh):
    Q = [[I, jI], [J, -jJ]] / sqrt(2) (K even; K odd adds a centre row/column sqrt(2))."""
    d, m = x.shape[:2]
    k = m // 2
    top, bot = x[:, :k], x[:, ::-1][:, :k]  # x1 and J x2
    out = np.empty(x.shape, dtype=np.complex128)
    r = np.sqrt(0.5)
    np.multiply(top + bot, r, out=out[:, :k])
    np.multiply(top - bot, -1j * r, out=out[:, m - k:])
    if m % 2:
        out[:, k] = x[:, k]
    return out


def _q(e: np.ndarray) -> np.ndarray:
    """Q e along axis 1 (e real (D, K, r)) -> complex (D, K, r)."""
    m = e.shape[1]
    k = m // 2
    out = np.empty(e.shape, dtype=np.complex128)
    top = (e[:, :k] + 1j * e[:, m - k:]) * np.sqrt(0.5)
    out[:, :k] = top
    out[:, m - k:] = np.conj(top)[:, ::-1]  # J (e1 - j e2) / sqrt(2)
    if m % 2:
        out[:, k] = e[:, k]
    return out


def _check_centro(p: np.ndarray) -> None:
    if not _close(p + p[::-1], p[0] + p[-1]):
        raise DoaError("forward-backward averaging needs a centro-symmetric array")


def _load(r: np.ndarray, loading: float) -> np.ndarray:
    if not loading:
        return r
    if loading < 0:
        raise DoaError(f"loading must be >= 0, got {loading!r}")
    k = r.shape[-1]
    tr = np.trace(r, axis1=1, axis2=2).real / k
    return r + (loading * tr)[:, None, None] * np.eye(k)


def covariance(snapshots: np.ndarray, positions: np.ndarray, *, forward_backward: bool = False,
               subarray: int | None = None, loading: float = 0.0
               ) -> tuple[np.ndarray, np.ndarray]:
    """Sample covariance with the optional fixes for coherent sources.

    snapshots : (D, M, L) complex
    returns (R (D, K, K) complex128, positions of the K-element (sub)array in wavelengths);
    with forward_backward, R = (R + J R* J) / 2.
    """
    x, p, _ = _as_batch(snapshots, positions)
    xs, p, r = _smoothed(x, p, subarray)
    if r is None:
        r = xs @ xs.conj().transpose(0, 2, 1) / xs.shape[2]
    if forward_backward:
        _check_centro(p)
        r = 0.5 * (r + r[:, ::-1, ::-1].conj())
    return _load(r, loading), p


def _real_fb_covariance(x: np.ndarray, p: np.ndarray, subarray: int | None, loading: float
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Q^H R_fb Q, which is real symmetric (D, K, K), computed from Q^H x with real arithmetic:
    Re(Q^H R Q) = (Yr Yr^T + Yi Yi^T) / N for Y = Q^H x. Its eigenvectors e give those of the
    forward-backward covariance as Q e (unitary MUSIC): same subspaces, a real eigh (~3x cheaper).
    With smoothing it is taken from the smoothed covariance R (:func:`_fb_real`)."""
    xs, p, r = _smoothed(x, p, subarray)
    _check_centro(p)
    if r is None:
        y = _q_h(xs)
        yy = np.concatenate([y.real, y.imag], axis=2)
        rr = yy @ yy.transpose(0, 2, 1) / xs.shape[2]
    else:
        rr = _fb_real(r)
        rr = 0.5 * (rr + rr.transpose(0, 2, 1))
    return _load(rr, loading), p


def _fb_real(r: np.ndarray) -> np.ndarray:
    """``Re(Q^H R Q)`` (D, K, K) float64 of Hermitian R (D, K, K) complex (Q of :func:`_q_h`).

    K even: from the four h x h blocks of R (h = K / 2, J the exchange matrix), with
    ``A = R11 + J R22 J``, ``B = J R21 + R12 J``, ``C = Im R11 - Im J R22 J``,
    ``E = Im J R21 - Im R12 J``: ``[[Re(A + B), -(C + E)], [C - E, Re(A - B)]] / 2`` (expanding
    Q; Huarng & Yeh 1991), real arithmetic on views, no complex K x K product. K odd: the two
    products with Q written out."""
    k = r.shape[1]
    if k % 2:
        return _q_h(_q_h(r).conj().transpose(0, 2, 1)).real
    h = k // 2
    re, im = r.real, r.imag
    a = re[:, :h, :h] + re[:, h:, h:][:, ::-1, ::-1]
    b = re[:, h:, :h][:, ::-1] + re[:, :h, h:][:, :, ::-1]
    c = im[:, :h, :h] - im[:, h:, h:][:, ::-1, ::-1]
    e = im[:, h:, :h][:, ::-1] - im[:, :h, h:][:, :, ::-1]
    out = np.empty(r.shape, dtype=np.float64)
    np.add(a, b, out=out[:, :h, :h])
    np.add(c, e, out=out[:, :h, h:])
    np.negative(out[:, :h, h:], out=out[:, :h, h:])
    np.subtract(c, e, out=out[:, h:, :h])
    np.subtract(a, b, out=out[:, h:, h:])
    out *= 0.5
    return out


def _subspace(snapshots, positions, method: str, n_signals: int, forward_backward: bool,
              subarray: int | None, loading: float) -> tuple[np.ndarray, int, np.ndarray]:
    """(B (D, K, rank) complex, sense, positions of the K elements) of the configured method."""
    x, p, _ = _as_batch(snapshots, positions)
    if forward_backward:
        rr, p = _real_fb_covariance(x, p, subarray, loading)
        b, sense = _factor(rr, method, n_signals)
        return _q(b), sense, p
    r, p = covariance(x, p, subarray=subarray, loading=loading)
    b, sense = _factor(r, method, n_signals)
    return b, sense, p


def _factor(r: np.ndarray, method: str, n_signals: int) -> tuple[np.ndarray, int]:
    """B (D, K, rank) with g(u) = |B^H a|^2, and +1 if the peak is a maximum of g, -1 if minimum."""
    if method not in METHODS:
        raise DoaError(f"method must be one of {METHODS}, got {method!r}")
    if method == "music":  # only the n_signals principal eigenvectors
        k = r.shape[-1]
        _check_n_signals(n_signals, k)
        return _principal_eigenvectors(r, n_signals), 1
    w, v = np.linalg.eigh(r)  # ascending eigenvalues
    if method == "bartlett":
        return v * np.sqrt(np.maximum(w, 0.0))[:, None, :], 1
    floor = np.finfo(np.float64).eps * np.maximum(w[:, -1:], np.finfo(np.float64).tiny)
    if np.any(w < floor):
        raise DoaError("Capon needs a full-rank covariance: use loading > 0 or more snapshots "
                       "(or smoothing)")
    return v / np.sqrt(w)[:, None, :], -1


def _principal_eigenvectors(r: np.ndarray, n: int) -> np.ndarray:
    """(D, K, n) eigenvectors of the n largest eigenvalues (ascending) of Hermitian r (D, K, K).

    LAPACK's ``?syevr``/``?heevr`` (MRRR) through ``scipy.linalg.eigh`` with
    ``subset_by_index``, over the batch: it reduces r to tridiagonal form as a full ``eigh``
    does but computes and back-transforms only the n wanted eigenvectors, not all K (numpy's
    batched ``eigh`` has no subset). On the chain's 64 x 64 unitary-MUSIC covariances with n = 3
    it takes about 0.6 of the time of ``numpy.linalg.eigh`` (one thread, this project's machine).
    The subspace is the same to float64 rounding (the MUSIC tests compare spectra and angles)."""
    import scipy.linalg

    k = r.shape[-1]
    if r.shape[0] == 0:
        return np.zeros((0, k, n), dtype=r.dtype)
    # one LAPACK call per detection, as scipy's own batch wrapper makes them (the same bits)
    # without its per-batch checks: 1.16 -> 0.76 ms for a frame's 3 detections (one thread)
    return np.stack([scipy.linalg.eigh(m, subset_by_index=[k - n, k - 1], driver="evr",
                                       check_finite=False)[1] for m in r])


def _spectrum_from_g(g: np.ndarray, method: str, m: int) -> np.ndarray:
    if method == "music":
        return 1.0 / np.maximum(m - g, m * 1e-15)
    if method == "bartlett":
        return g / m
    return 1.0 / np.maximum(g, np.finfo(np.float64).tiny)


def _g_on_grid(b: np.ndarray, p: np.ndarray, grid_deg: np.ndarray) -> np.ndarray:
    grid = np.ascontiguousarray(grid_deg, dtype=np.float64)
    a = _steering_cached(np.ascontiguousarray(p).tobytes(), grid.tobytes())
    d, _, rank = b.shape
    # one (D * rank, M) x (M, G) GEMM: numpy's stacked matmul of the transposed view takes a
    # non-BLAS loop, 37 x slower on (3932, 3, 86) x (86, 721) (measured on this machine)
    bh = np.ascontiguousarray(np.swapaxes(b.conj(), 1, 2)).reshape(d * rank, -1)
    z = (bh @ a).reshape(d, rank, -1)  # (D, rank, G)
    return (z.real ** 2 + z.imag ** 2).sum(axis=1)


def _fb_offsets(p: np.ndarray) -> np.ndarray:
    """(K // 2,) offsets ``p_i - c / 2`` of the first half of a centro-symmetric array from its
    centre (``c = p_0 + p_(K-1)``)."""
    return p[:p.size // 2] - 0.5 * (p[0] + p[-1])


def _fb_steering(p: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The real steering vector of unitary (forward-backward) MUSIC.

    For a centro-symmetric array, ``Q^H a(u) = phi(u) r(u)`` with ``|phi| = 1`` and ``r`` real
    (Huarng & Yeh 1991; Q as in :func:`_q_h`): ``r = [sqrt(2) cos(2 pi d u); (1); sqrt(2) sin(2 pi d u)]``
    with ``d`` = :func:`_fb_offsets` (the middle 1 for odd K). So with ``B = Q E`` (E real),
    ``g(u) = |B^H a(u)|^2 = |E^T r(u)|^2``: the same function of u in real arithmetic.

    u : any shape; returns r, u.shape + (K,)."""
    ph = np.multiply.outer(u, 2 * np.pi * _fb_offsets(p))
    mid = [np.ones(u.shape + (1,))] if p.size % 2 else []  # the centre element: a_c / phi = 1
    r2 = np.sqrt(2.0)
    return np.concatenate([r2 * np.cos(ph), *mid, r2 * np.sin(ph)], axis=-1)


@lru_cache(maxsize=16)
def _fb_grid_cached(p_bytes: bytes, g_bytes: bytes) -> np.ndarray:
    """(K, G) real steering matrix ``r(u)`` of :func:`_fb_steering` on a grid (degrees)."""
    u = np.sin(np.radians(np.frombuffer(g_bytes)))
    r = np.ascontiguousarray(_fb_steering(np.frombuffer(p_bytes), u).T)
    r.setflags(write=False)
    return r


# ---------------------------------------------------------------------------------------------
# spectra


def doa_spectrum(snapshots: np.ndarray, positions: np.ndarray,
                 angles_deg: np.ndarray = DEFAULT_GRID_DEG, *, method: str = "music",
                 n_signals: int = 3, forward_backward: bool = False,
                 subarray: int | None = None, loading: float = 0.0) -> np.ndarray:
    """Pseudo-spectrum of ``method`` over ``angles_deg``: (G,) for (M, L) snapshots, (D, G) for
    (D, M, L). Linear scale (not dB)."""
    _, _, single = _as_batch(snapshots, positions)
    b, _, p = _subspace(snapshots, positions, method, n_signals, forward_backward, subarray,
                        loading)
    spec = _spectrum_from_g(_g_on_grid(b, p, angles_deg), method, p.size)
    return spec[0] if single else spec


def music_spectrum(snapshots: np.ndarray, positions: np.ndarray,
                   angles_deg: np.ndarray = DEFAULT_GRID_DEG, n_signals: int = 3, *,
                   forward_backward: bool = False, subarray: int | None = None,
                   loading: float = 0.0) -> np.ndarray:
    """MUSIC pseudo-spectrum P(theta) = 1 / (a^H E_n E_n^H a) (paper eq. 6).

    snapshots : complex (M, L) or (D, M, L); positions : (M,) wavelengths; angles_deg : scan grid
    n_signals : eigenvectors treated as signal (the paper: 3); the rest span the noise subspace
    returns (G,) or (D, G) linear pseudo-spectrum
    """
    return doa_spectrum(snapshots, positions, angles_deg, method="music", n_signals=n_signals,
                        forward_backward=forward_backward, subarray=subarray, loading=loading)


def bartlett_spectrum(snapshots: np.ndarray, positions: np.ndarray,
                      angles_deg: np.ndarray = DEFAULT_GRID_DEG, **options) -> np.ndarray:
    """Bartlett (delay-and-sum / FFT) beamformer power a^H R a / M; same shapes as MUSIC."""
    return doa_spectrum(snapshots, positions, angles_deg, method="bartlett", **options)


def capon_spectrum(snapshots: np.ndarray, positions: np.ndarray,
                   angles_deg: np.ndarray = DEFAULT_GRID_DEG, **options) -> np.ndarray:
    """Capon (MVDR) power 1 / (a^H R^-1 a); same shapes as MUSIC (use ``loading`` if L < M)."""
    return doa_spectrum(snapshots, positions, angles_deg, method="capon", **options)


# ---------------------------------------------------------------------------------------------
# peaks


def _grid_peaks(spec: np.ndarray, n_targets: int) -> np.ndarray:
    """(D, n_targets) grid indices of the strongest local maxima (end points count when strictly
    above their one neighbour, so a flat spectrum has no peak); -1 where there are fewer peaks."""
    d, g = spec.shape
    left = np.concatenate([np.full((d, 1), -np.inf), spec[:, :-1]], axis=1)
    right = np.concatenate([spec[:, 1:], np.full((d, 1), -np.inf)], axis=1)
    is_peak = (spec >= left) & (spec > right)
    is_peak[:, -1] = spec[:, -1] > spec[:, -2]
    score = np.where(is_peak, spec, -np.inf)
    if n_targets == 1:  # the first of the largest, as the stable sort below would give
        order = np.argmax(score, axis=1)[:, None]
    else:
        order = np.argsort(-score, axis=1, kind="stable")[:, :n_targets]
    found = np.take_along_axis(score, order, axis=1) > -np.inf
    return np.where(found, order, -1)


def _refine(b: np.ndarray, p: np.ndarray, u0: np.ndarray, lo: np.ndarray, hi: np.ndarray,
            sense: int, steps: int = 6) -> np.ndarray:
    """Newton steps on g(u) = |B^H a(u)|^2 from u0 (D, T), kept within [lo, hi].

    Each step evaluates ``B^H a``, ``B^H a'`` and ``B^H a''`` (a' = j 2 pi p a, a'' = j 2 pi p a')
    of every detection and target as one batched product (D, 3 T, K) x (D, K, rank); at most
    ``steps`` steps; a peak whose step moved it by at most 1e-13 (1e-11 deg) is left where it
    is from then on (so a detection's angle does not depend on the others of its batch), and
    the iteration stops when all have."""
    k = 2j * np.pi * p  # (K,)
    bc = b.conj()  # (D, K, rank): z = a @ conj(B) = B^H a for each (D, T)
    t = u0.shape[1]
    u = u0.copy()
    active = np.ones(u.shape, dtype=bool)
    for _ in range(steps):  # at most `steps` batched iterations
        a = np.exp(k * u[..., None])  # (D, T, K)
        a1 = a * k
        z = np.concatenate([a, a1, a1 * k], axis=1) @ bc  # (D, 3T, rank)
        z0, z1, z2 = z[:, :t], z[:, t:2 * t], z[:, 2 * t:]
        g1 = 2 * (z0.conj() * z1).real.sum(axis=-1)
        g2 = 2 * ((z1.real ** 2 + z1.imag ** 2).sum(axis=-1) + (z0.conj() * z2).real.sum(axis=-1))
        ok = sense * g2 < 0  # curvature of a maximum (MUSIC, Bartlett) / minimum (Capon)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.where(ok, -g1 / g2, 0.0)
        new = np.where(active, np.clip(u + step, lo, hi), u)
        active &= np.abs(new - u) > 1e-13  # converged: frozen, whatever the rest of the batch
        u = new
        if not active.any():
            break
    return u


def doa_angles(snapshots: np.ndarray, positions: np.ndarray, n_targets: int = 1,
               n_signals: int = 3, grid_deg: np.ndarray = DEFAULT_GRID_DEG, *,
               method: str = "music", forward_backward: bool = False,
               subarray: int | None = None, loading: float = 0.0,
               peak_order: str = "spectrum", return_power: bool = False,
               return_spectrum: bool = False):
    """``n_targets`` peaks of the pseudo-spectrum, refined between grid points, first the
    highest (``peak_order="spectrum"``) or the most powerful (``"power"``).

    snapshots : complex (elements M, snapshots L) or batched (detections D, M, L), array data in
                any consistent unit; positions : (M,) element positions along the array, in
                wavelengths
    peak_order : "spectrum" (highest pseudo-spectrum peak first, the paper) or "power" (the
                 ``max(n_targets, n_signals)`` highest peaks, ranked by their joint
                 least-squares source powers; module docstring)
    returns angles in degrees, (n_targets,) for (M, L) snapshots or (D, n_targets) for batched,
    in that order, NaN where the spectrum has fewer peaks (a flat spectrum has none, nor do
    all-zero snapshots); with ``return_power`` also the pseudo-spectrum values at the refined
    peaks (same shape and order: with "power" not necessarily descending); with
    ``return_spectrum`` also the pseudo-spectrum on the grid ((G,) or (D, G)). Extra outputs
    follow the angles in that order.
    raises DoaError for non-finite snapshots, bad shapes, grids or options
    """
    if not (isinstance(n_targets, (int, np.integer)) and n_targets >= 1):
        raise DoaError(f"n_targets must be a positive integer, got {n_targets!r}")
    if not isinstance(peak_order, str) or peak_order not in PEAK_ORDERS:
        raise DoaError(f"peak_order must be one of {PEAK_ORDERS}, got {peak_order!r}")
    x, p, single = _as_batch(snapshots, positions)
    grid = np.asarray(grid_deg, dtype=np.float64)
    if grid.ndim != 1 or grid.size < 3 or np.any(np.diff(grid) <= 0) or grid[0] < -90 \
            or grid[-1] > 90:
        raise DoaError("grid_deg must be an increasing 1-D grid of >= 3 angles within [-90, 90]")
    opts = dict(n_targets=n_targets, n_signals=n_signals, grid=grid, method=method,
                forward_backward=forward_backward, subarray=subarray, loading=loading,
                peak_order=peak_order)
    if x.shape[0] == 0:
        angles, peak = np.zeros((0, n_targets)), np.zeros((0, n_targets))
        spec = np.zeros((0, grid.size))
    else:  # blocks of detections bound the memory of the (D, rank, G) scan
        parts = [_angles_block(x[lo:lo + BLOCK_DETECTIONS], p, **opts)
                 for lo in range(0, x.shape[0], BLOCK_DETECTIONS)]
        angles, peak, spec = (np.concatenate(z) for z in zip(*parts))
    if single:
        angles, peak, spec = angles[0], peak[0], spec[0]
    out = (angles,) + ((peak,) if return_power else ()) + ((spec,) if return_spectrum else ())
    return out if len(out) > 1 else angles


def _angles_block(x: np.ndarray, p: np.ndarray, *, n_targets: int, n_signals: int,
                  grid: np.ndarray, method: str, forward_backward: bool, subarray: int | None,
                  loading: float, peak_order: str
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """doa_angles' work on one block x (D, M, L): (angles (D, T), peak values (D, T),
    spectrum (D, G))."""
    x_full, p_full = x, p
    if forward_backward:  # unitary MUSIC / beamformers: E real, on the grid g = |E^T r(u)|^2
        rr, p = _real_fb_covariance(x, p, subarray, loading)
        e, sense = _factor(rr, method, n_signals)
        b = _q(e)
    else:
        b, sense, p = _subspace(x, p, method, n_signals, forward_backward, subarray, loading)
    grid = np.ascontiguousarray(grid, dtype=np.float64)
    if forward_backward:
        z = e.transpose(0, 2, 1) @ _fb_grid_cached(np.ascontiguousarray(p).tobytes(),
                                                   grid.tobytes())  # (D, rank, G)
        g = (z * z).sum(axis=1)
    else:
        g = _g_on_grid(b, p, grid)
    spec = _spectrum_from_g(g, method, p.size)
    n_peaks = n_targets if peak_order == "spectrum" else max(n_targets, n_signals)
    idx = _grid_peaks(spec, n_peaks)
    # all-zero snapshots carry no direction (smoothing and forward-backward would otherwise
    # give their arbitrary eigenvectors a peak)
    idx[~np.any(x_full != 0, axis=(1, 2))] = -1
    safe = np.maximum(idx, 0)
    u_grid = np.sin(np.radians(grid))
    lo = u_grid[np.maximum(safe - 1, 0)]
    hi = u_grid[np.minimum(safe + 1, grid.size - 1)]
    u = _refine(b, p, u_grid[safe], lo, hi, sense)
    a = np.exp(2j * np.pi * p[None, None, :] * u[..., None])
    z = np.einsum("dkr,dtk->dtr", b.conj(), a)
    peak = _spectrum_from_g((z.real ** 2 + z.imag ** 2).sum(axis=-1), method, p.size)
    # the refined value can only improve on the grid value; keep strongest-first order
    rank = peak if peak_order == "spectrum" else _source_powers(x_full, p_full, u, idx >= 0)
    order = np.argsort(-np.where(idx >= 0, rank, -np.inf), axis=1, kind="stable")[:, :n_targets]
    angles = np.where(idx >= 0, np.degrees(np.arcsin(np.clip(u, -1, 1))), np.nan)
    angles = np.take_along_axis(angles, order, axis=1)
    peak = np.take_along_axis(np.where(idx >= 0, peak, np.nan), order, axis=1)
    return angles, peak, spec


def _source_powers(x: np.ndarray, p: np.ndarray, u: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """(D, T) least-squares powers of sources at ``u = sin theta`` (D, T) in snapshots x
    (D, M, L) of the array at p (M,): ``mean_l |s_tl|^2`` for ``S = (A^H A + r M I)^-1 A^H X``,
    all T sources of a detection fitted jointly (r = :data:`POWER_RIDGE`); a source where
    ``valid`` is False has a zero steering vector, so its power is 0 and it takes no part."""
    a = np.exp(2j * np.pi * u[..., None] * p) * valid[..., None]          # (D, T, M)
    ah = a.conj()
    gram = ah @ a.transpose(0, 2, 1)                                        # (D, T, T)
    gram += POWER_RIDGE * p.size * np.eye(u.shape[1])
    s = np.linalg.solve(gram, ah @ x)                                       # (D, T, L)
    return (s.real ** 2 + s.imag ** 2).mean(axis=2)


def music_angles(snapshots: np.ndarray, positions: np.ndarray, n_targets: int = 1,
                 n_signals: int = 3, grid_deg: np.ndarray = DEFAULT_GRID_DEG, **options):
    """MUSIC angles in degrees: ``n_targets`` pseudo-spectrum peaks (``peak_order``) over
    ``grid_deg`` (default -90..90 in 0.25 deg), refined between grid points.
    (M, L) -> (n_targets,); (D, M, L) -> (D, n_targets); NaN where fewer peaks exist."""
    return doa_angles(snapshots, positions, n_targets, n_signals, grid_deg, method="music",
                      **options)


def bartlett_angles(snapshots: np.ndarray, positions: np.ndarray, n_targets: int = 1,
                    grid_deg: np.ndarray = DEFAULT_GRID_DEG, **options):
    """Bartlett beamformer peak angles (deg); shapes as :func:`music_angles`."""
    return doa_angles(snapshots, positions, n_targets, 1, grid_deg, method="bartlett", **options)


def capon_angles(snapshots: np.ndarray, positions: np.ndarray, n_targets: int = 1,
                 grid_deg: np.ndarray = DEFAULT_GRID_DEG, **options):
    """Capon (MVDR) peak angles (deg); shapes as :func:`music_angles`."""
    return doa_angles(snapshots, positions, n_targets, 1, grid_deg, method="capon", **options)
