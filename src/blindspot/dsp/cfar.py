"""Two-dimensional CFAR detectors on a range-Doppler power map.

The map is ``power`` (rows = range bins, cols = Doppler bins), |X|^2 or a non-coherent sum of
|X|^2 over channels. Around each cell under test (CUT) a rectangle of half-widths
``guard + train`` (per axis) is taken; the inner rectangle of half-widths ``guard`` (CUT included)
is excluded and the remaining *training cells* estimate the noise level.

Edges
-----
* Doppler wraps (the Doppler spectrum is periodic), so every cell has training cells on both sides
  in Doppler. The Doppler window ``2 (guard + train) + 1`` must fit in the map.
* Range does not wrap: near the first and last range bins only the training cells that exist are
  used. Their number ``N`` varies per cell and the threshold factor follows it (a CUT with fewer
  training cells gets the larger factor its smaller N needs for the same Pfa).

Threshold rules (``threshold`` always returned in power units, like ``power``)
-----------------------------------------------------------------------------
* ``pfa``: the factor for a square-law detector. With ``n_looks = K`` independent channels summed
  non-coherently each cell of pure noise is Gamma(K) distributed; K = 1 is the exponential case.
  CA: ``threshold = alpha * mean`` with ``alpha = N (Pfa^(-1/N) - 1)`` for K = 1 and, in general,
  the exact ``alpha = N c`` with ``c / (1 + c) = I^-1_{1 - Pfa}(K, N K)`` (Z / (Z + S) is Beta(K, NK)
  for a noise CUT Z and training sum S). GO/SO and OS factors are solved numerically from their
  exact false-alarm probabilities (below).
* ``scale`` with ``domain="power"``: ``threshold = scale * (training-cell mean power)``.
* ``scale`` with ``domain="db"``: the training cells are averaged in dB,
  ``mean_db = mean(10 log10(power))`` (a log-average, i.e. the geometric mean of the powers), and
  ``threshold = 10 ** (scale * mean_db / 10)``. This multiplies a dB *number*, so its meaning
  depends on the map's absolute unit (0 dB = 1 power unit): a noise floor at L dB gets a threshold
  ``(scale - 1) L`` dB above it. It is not constant-false-alarm under a change of unit; it is
  offered because the paper's weight (1.18) may be meant that way. Zero power cells are floored at
  the smallest positive value of the map before taking logs.

Variants: ``mode="ca"`` (cell averaging), ``"go"`` / ``"so"`` (greatest-of / smallest-of the two
half-window means; the halves are the training cells at lower range (plus the lower-Doppler wing of
the CUT's own row) and at higher range (plus the upper wing)), and :func:`os_cfar_2d` (ordered
statistic: the ``rank``-quantile training cell).

Everything is vectorised: window sums come from one 2-D integral image of the padded map
(zero padding on range, wrap-around on Doppler); per-cell counts from the same sums of a map of
ones; factors are computed once per distinct count (and cached per map shape).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.integrate
import scipy.optimize
import scipy.special
import scipy.stats

from blindspot.arrays import checked_array
from blindspot.dsp.config import CFAR_DOMAINS as DOMAINS, CFAR_MODES as MODES, threshold_rule


class CfarError(ValueError):
    """Bad CFAR arguments (names the argument, what was expected and what was found)."""


@dataclass(frozen=True)
class CfarResult:
    """Output of :func:`cfar_2d`; all arrays (range, doppler).

    mask      : bool, power > threshold
    threshold : float64 threshold in power units
    noise     : float64 mean power of all training cells (the noise estimate used for SNR)
    n_train   : int number of training cells that exist for each cell
    """

    mask: np.ndarray
    threshold: np.ndarray
    noise: np.ndarray
    n_train: np.ndarray


# ---------------------------------------------------------------------------------------------
# argument checking


def _pair(value, name: str) -> tuple[int, int]:
    arr = np.atleast_1d(np.asarray(value))
    if arr.size == 1:
        arr = np.repeat(arr, 2)
    if arr.shape != (2,) or not np.issubdtype(arr.dtype, np.integer) or np.any(arr < 0):
        raise CfarError(
            f"{name} must be a non-negative int or a (range, doppler) pair of non-negative ints, "
            f"got {value!r}"
        )
    return int(arr[0]), int(arr[1])


def _check_power(power: np.ndarray, where: str) -> np.ndarray:
    """``power`` as float64 (..., range, doppler): real, finite, non-negative, not empty."""
    p = checked_array(power, "power", CfarError, axes="an |X|^2 map (..., range, doppler)",
                      min_ndim=2, kind="real", nonnegative=True, where=where,
                      min_lengths={-2: 1, -1: 1})
    return p.astype(np.float64, copy=False)


def _check_threshold(pfa, scale, domain: str) -> None:
    """The threshold arguments: the rule across them (:func:`blindspot.dsp.config.threshold_rule`,
    the one CfarConfig keeps), then each value."""
    broken = threshold_rule(pfa, scale, domain)
    if broken:
        key, value, allowed = broken
        raise CfarError(f"{key}: expected {allowed}, got {value!r}")
    if domain not in DOMAINS:
        raise CfarError(f"domain must be one of {DOMAINS}, got {domain!r}")
    if pfa is not None and not (isinstance(pfa, (int, float)) and 0.0 < pfa < 1.0):
        raise CfarError(f"pfa must be a probability in (0, 1), got {pfa!r}")
    if scale is not None and not (isinstance(scale, (int, float)) and np.isfinite(scale)
                                  and scale > 0):
        raise CfarError(f"scale must be a positive finite number, got {scale!r}")


def _check_window(shape: tuple[int, ...], guard: tuple[int, int], train: tuple[int, int]) -> None:
    shape = shape[-2:]
    if train[0] == 0 and train[1] == 0:
        raise CfarError("train is (0, 0): at least one axis needs training cells")
    width = 2 * (guard[1] + train[1]) + 1
    if width > shape[1]:
        raise CfarError(
            f"the Doppler window 2*(guard+train)+1 = {width} cells is wider than the map's "
            f"{shape[1]} Doppler bins (the Doppler axis wraps, so cells would count twice)"
        )


# ---------------------------------------------------------------------------------------------
# window sums


class _BoxSummer:
    """Sums of ``x`` (..., R, D) over rectangles of offsets around every cell, from one integral
    image per map (leading batch axes, e.g. frames, are independent maps).

    The map is zero-padded by ``a`` rows on both range ends and wrap-padded by ``b`` columns on
    both Doppler ends."""

    def __init__(self, x: np.ndarray, a: int, b: int):
        self.shape = x.shape
        self.a, self.b = a, b
        n_rows, n_cols = x.shape[-2:]
        # the integral image of the padded map, built in place: the map (with its wrapped
        # Doppler columns) is cumulated down the range axis inside the image; the zero rows
        # before it stay zero and the rows after it repeat its last row (adding zeros changes
        # no bit), then the columns are cumulated. Bit for bit the cumsums of np.pad's copy.
        integral = np.zeros(x.shape[:-2] + (n_rows + 2 * a + 1, n_cols + 2 * b + 1))
        inner = integral[..., 1:, 1:]
        body = inner[..., a:a + n_rows, :]
        body[..., b:b + n_cols] = x
        if b:
            body[..., :b] = x[..., n_cols - b:]
            body[..., b + n_cols:] = x[..., :b]
        np.cumsum(body, axis=-2, out=body)
        inner[..., a + n_rows:, :] = body[..., -1:, :]
        np.cumsum(inner, axis=-1, out=inner)
        self.integral = integral

    def box(self, dr0: int, dr1: int, dd0: int, dd1: int) -> np.ndarray:
        """(..., R, D) sum over range offsets dr0..dr1 and Doppler offsets dd0..dd1 (inclusive);
        zero where the rectangle is empty."""
        R, D = self.shape[-2:]
        if dr1 < dr0 or dd1 < dd0:
            return np.zeros(self.shape)
        I = self.integral
        r_hi, r_lo = self.a + dr1 + 1, self.a + dr0
        c_hi, c_lo = self.b + dd1 + 1, self.b + dd0
        return (I[..., r_hi:r_hi + R, c_hi:c_hi + D] - I[..., r_lo:r_lo + R, c_hi:c_hi + D]
                - I[..., r_hi:r_hi + R, c_lo:c_lo + D] + I[..., r_lo:r_lo + R, c_lo:c_lo + D])

    def training(self, guard: tuple[int, int], train: tuple[int, int]) -> np.ndarray:
        gr, gd = guard
        a, b = gr + train[0], gd + train[1]
        return self.box(-a, a, -b, b) - self.box(-gr, gr, -gd, gd)

    def halves(self, guard: tuple[int, int], train: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) halves: lower range side + lower-Doppler wing of the CUT row, and the
        mirror image."""
        gr, gd = guard
        a, b = gr + train[0], gd + train[1]
        lower = self.box(-a, -1, -b, b) - self.box(-gr, -1, -gd, gd) + self.box(0, 0, -b, -gd - 1)
        upper = self.box(1, a, -b, b) - self.box(1, gr, -gd, gd) + self.box(0, 0, gd + 1, b)
        return lower, upper


def _sanitize(sums: np.ndarray) -> np.ndarray:
    # integral-image differences of non-negative data can come out as -1e-12; clip those
    return np.maximum(sums, 0.0)


@lru_cache(maxsize=32)
def _counts(shape: tuple[int, int], guard: tuple[int, int], train: tuple[int, int]):
    a, b = guard[0] + train[0], guard[1] + train[1]
    ones = _BoxSummer(np.ones(shape), a, b)
    n = np.rint(ones.training(guard, train)).astype(np.int64)
    lo, hi = ones.halves(guard, train)
    n.setflags(write=False)
    lo, hi = np.rint(lo).astype(np.int64), np.rint(hi).astype(np.int64)
    lo.setflags(write=False)
    hi.setflags(write=False)
    return n, lo, hi


def training_mean(power: np.ndarray, guard, train) -> tuple[np.ndarray, np.ndarray]:
    """(mean training-cell power (..., R, D), training-cell count (R, D)) with the edge rules
    above; leading axes of ``power`` (e.g. frames) are independent maps."""
    p = _check_power(power, "training_mean")
    g, t = _pair(guard, "guard"), _pair(train, "train")
    _check_window(p.shape, g, t)
    n, _, _ = _counts(p.shape[-2:], g, t)
    s = _sanitize(_BoxSummer(p, g[0] + t[0], g[1] + t[1]).training(g, t))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, s / np.maximum(n, 1), np.nan), n


# ---------------------------------------------------------------------------------------------
# threshold factors from Pfa


def ca_factor(n_train, pfa: float, n_looks: int = 1) -> np.ndarray:
    """CA-CFAR factor alpha (threshold = alpha * training mean) for N = ``n_train`` cells.

    K = ``n_looks`` = 1: alpha = N (Pfa^(-1/N) - 1). General K: alpha = N x / (1 - x) with
    x = I^-1(K, N K; upper tail Pfa) (Z/(Z+S) ~ Beta(K, NK) for a Gamma(K) noise CUT Z and a
    Gamma(NK) training sum S)."""
    n = np.asarray(n_train, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        if n_looks == 1:
            alpha = n * (pfa ** (-1.0 / n) - 1.0)
        else:
            x = scipy.special.betainccinv(float(n_looks), n * n_looks, pfa)
            alpha = n * x / (1.0 - x)
    return np.where(n > 0, alpha, np.inf)


def _mean_grid(n1: int, n2: int, k: int, points: int = 6001) -> np.ndarray:
    """Integration grid covering both half-window means (Gamma(n k, scale 1/n)) to 1e-14."""
    lo = min(scipy.special.gammaincinv(n * k, 1e-14) / n for n in (n1, n2))
    hi = max(scipy.special.gammainccinv(n * k, 1e-14) / n for n in (n1, n2))
    return np.linspace(lo, hi, points)


@lru_cache(maxsize=256)
def _go_so_pfa(alpha: float, n1: int, n2: int, k: int, mode: str) -> float:
    """P(Z > alpha * max|min(U, V)) for Z ~ Gamma(k) and U, V the means of n1, n2 Gamma(k) cells:
    the integral of P(Z > alpha m) against the density of max (GO) or min (SO) of U and V
    (Simpson rule on a fine grid)."""
    m = _mean_grid(n1, n2, k)
    cdf_u, cdf_v = (scipy.special.gammainc(n * k, n * m) for n in (n1, n2))
    pdf_u, pdf_v = (scipy.stats.gamma.pdf(m, a=n * k, scale=1.0 / n) for n in (n1, n2))
    if mode == "go":
        dens = pdf_u * cdf_v + cdf_u * pdf_v
    else:
        dens = pdf_u * (1 - cdf_v) + (1 - cdf_u) * pdf_v
    return float(scipy.integrate.simpson(scipy.special.gammaincc(k, alpha * m) * dens, x=m))


@lru_cache(maxsize=256)
def _go_so_factor(n1: int, n2: int, pfa: float, k: int, mode: str) -> float:
    if n1 == 0 or n2 == 0:  # one half missing: plain CA on the other
        return float(ca_factor(max(n1, n2), pfa, k))
    # the GO/SO factor lies between the CA factors of N/2 (SO: lower Pfa per alpha) and of ~N/4
    f = lambda la: np.log(max(_go_so_pfa(float(np.exp(la)), n1, n2, k, mode), 1e-300)) - np.log(pfa)
    return float(np.exp(scipy.optimize.brentq(f, np.log(1e-3), np.log(1e6), xtol=1e-10)))


def os_pfa(alpha: float, n: int, rank: int, n_looks: int = 1) -> float:
    """False-alarm probability of OS-CFAR: threshold alpha * (rank-th smallest of n cells).

    K = 1: prod_{i=0}^{rank-1} (n - i) / (n - i + alpha) (Rohling 1983). K > 1: the Gamma(K) tail
    integrated over the density of the order statistic (Simpson rule on a fine grid)."""
    if n_looks == 1:
        i = np.arange(rank)
        return float(np.prod((n - i) / (n - i + alpha)))
    k = float(n_looks)
    x = np.linspace(scipy.special.gammaincinv(k, 1e-14), scipy.special.gammainccinv(k, 1e-14),
                    8001)
    logc = (scipy.special.gammaln(n + 1) - scipy.special.gammaln(rank)
            - scipy.special.gammaln(n - rank + 1))
    cdf = scipy.special.gammainc(k, x)
    with np.errstate(divide="ignore"):
        log_density = (logc + (rank - 1) * np.log(cdf) + (n - rank) * np.log1p(-cdf)
                       + scipy.stats.gamma.logpdf(x, a=k))
    integrand = np.exp(log_density) * scipy.special.gammaincc(k, alpha * x)
    return float(scipy.integrate.simpson(integrand, x=x))


@lru_cache(maxsize=512)
def os_factor(n: int, rank: int, pfa: float, n_looks: int = 1) -> float:
    """OS-CFAR factor alpha solving os_pfa(alpha, n, rank) = pfa."""
    if n == 0:
        return np.inf
    f = lambda la: np.log(max(os_pfa(float(np.exp(la)), n, rank, n_looks), 1e-300)) - np.log(pfa)
    return float(np.exp(scipy.optimize.brentq(f, np.log(1e-6), np.log(1e9), xtol=1e-12)))


def _per_unique(keys: np.ndarray, fn) -> np.ndarray:
    """Apply scalar ``fn`` once per distinct row of ``keys`` (..., m) and scatter the results."""
    flat = keys.reshape(-1, keys.shape[-1])
    uniq, inverse = np.unique(flat, axis=0, return_inverse=True)
    vals = np.array([fn(*map(int, row)) for row in uniq], dtype=np.float64)
    return vals[inverse.ravel()].reshape(keys.shape[:-1])


# ---------------------------------------------------------------------------------------------
# detectors


def _db_floor(p: np.ndarray) -> np.ndarray:
    """The smallest positive power of each map (..., R, D) -> (..., 1, 1) (1.0 for a map of
    zeros)."""
    positive = np.where(p > 0, p, np.inf).min(axis=(-2, -1), keepdims=True)
    return np.where(np.isfinite(positive), positive, 1.0)


def _to_db(x: np.ndarray, floor: float) -> np.ndarray:
    """10 log10(x), with x floored at ``floor`` (the smallest positive power of the map)."""
    return 10.0 * np.log10(np.maximum(x, floor))


def cfar_2d(power: np.ndarray, guard, train, *, pfa: float | None = None,
            scale: float | None = None, domain: str = "power", mode: str = "ca",
            n_looks: int = 1) -> CfarResult:
    """CA / GO / SO CFAR on a (range, doppler) power map; see the module docstring.

    power : (..., R, D) real non-negative; leading axes (e.g. frames) are independent maps
    guard, train : int or (range, doppler) half-widths in cells
    returns :class:`CfarResult` (mask, threshold in power units, noise mean: (..., R, D);
    training counts (R, D))
    """
    p = _check_power(power, "cfar_2d")
    g, t = _pair(guard, "guard"), _pair(train, "train")
    _check_threshold(pfa, scale, domain)
    _check_window(p.shape, g, t)
    if mode not in MODES:
        raise CfarError(f"mode must be one of {MODES}, got {mode!r}")
    if not (isinstance(n_looks, (int, np.integer)) and n_looks >= 1):
        raise CfarError(f"n_looks must be a positive integer, got {n_looks!r}")

    a, b = g[0] + t[0], g[1] + t[1]
    n, n_lo, n_hi = _counts(p.shape[-2:], g, t)
    lin = _BoxSummer(p, a, b)
    with np.errstate(invalid="ignore", divide="ignore"):
        noise = np.where(n > 0, _sanitize(lin.training(g, t)) / np.maximum(n, 1), np.nan)

    summer = lin if domain == "power" else _BoxSummer(_to_db(p, _db_floor(p)), a, b)
    with np.errstate(invalid="ignore", divide="ignore"):
        if mode == "ca":
            level = noise if domain == "power" else summer.training(g, t) / np.maximum(n, 1)
        else:
            s_lo, s_hi = summer.halves(g, t)
            if domain == "power":
                s_lo, s_hi = _sanitize(s_lo), _sanitize(s_hi)
            m_lo = np.where(n_lo > 0, s_lo / np.maximum(n_lo, 1), np.nan)
            m_hi = np.where(n_hi > 0, s_hi / np.maximum(n_hi, 1), np.nan)
            pick = np.fmax if mode == "go" else np.fmin
            level = pick(m_lo, m_hi)

    if pfa is not None:
        if mode == "ca":
            factor = ca_factor(n, pfa, n_looks)
        else:
            keys = np.stack([n_lo, n_hi], axis=-1)
            factor = _cached_factor_map(keys.tobytes(), keys.shape, pfa, n_looks, mode)
        threshold = factor * level
    elif domain == "power":
        threshold = scale * level
    else:
        threshold = 10.0 ** (scale * level / 10.0)
    threshold = np.where(n > 0, threshold, np.inf)
    return CfarResult(mask=p > threshold, threshold=threshold, noise=noise, n_train=n)


@lru_cache(maxsize=32)
def _cached_factor_map(key_bytes: bytes, shape: tuple, pfa: float, k: int, mode: str) -> np.ndarray:
    keys = np.frombuffer(key_bytes, dtype=np.int64).reshape(shape)
    out = _per_unique(keys, lambda n1, n2: _go_so_factor(n1, n2, pfa, k, mode))
    out.setflags(write=False)
    return out


def ca_cfar_2d(power: np.ndarray, guard, train, *, pfa: float | None = None,
               scale: float | None = None, domain: str = "power", mode: str = "ca",
               n_looks: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Cell-averaging CFAR (``mode`` "ca", or greatest-of "go" / smallest-of "so").

    power : (..., R, D) |X|^2 map, rows = range bins, cols = Doppler bins (Doppler wraps);
            leading axes (e.g. frames) are independent maps
    guard, train : int or (range, doppler) half-widths in cells
    pfa : design false-alarm probability per cell (square-law detector; ``n_looks`` channels
          summed non-coherently, 1 = plain |X|^2)
    scale : multiplier of the training-cell mean in ``domain`` "power" or "db"
    returns (mask bool (..., R, D), threshold float64 (..., R, D) in power units)
    """
    res = cfar_2d(power, guard, train, pfa=pfa, scale=scale, domain=domain, mode=mode,
                  n_looks=n_looks)
    return res.mask, res.threshold


def os_cfar_2d(power: np.ndarray, guard, train, *, rank: float = 0.75, pfa: float | None = None,
               scale: float | None = None, domain: str = "power",
               n_looks: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Ordered-statistic CFAR: the level is the k-th smallest training cell, k = round(rank * N)
    (clipped to 1..N) for each cell's own N; threshold = alpha * level (``pfa``, alpha from
    :func:`os_factor`), ``scale * level`` (power) or ``10**(scale * level_db / 10)`` (db).

    power : (..., R, D), leading axes (e.g. frames) independent maps.
    Memory: gathers a (..., rows, D, N_max) window stack per block of range rows.
    returns (mask (..., R, D), threshold (..., R, D) in power units)
    """
    p = _check_power(power, "os_cfar_2d")
    g, t = _pair(guard, "guard"), _pair(train, "train")
    _check_threshold(pfa, scale, domain)
    _check_window(p.shape, g, t)
    if not (0.0 < rank <= 1.0):
        raise CfarError(f"rank must be a quantile in (0, 1], got {rank!r}")
    a, b = g[0] + t[0], g[1] + t[1]
    n, _, _ = _counts(p.shape[-2:], g, t)
    k = np.clip(np.rint(rank * n), 1, np.maximum(n, 1)).astype(np.int64)

    lead = ((0, 0),) * (p.ndim - 2)
    padded = np.pad(np.pad(p, lead + ((0, 0), (b, b)), mode="wrap"), lead + ((a, a), (0, 0)),
                    constant_values=np.inf)
    win = np.lib.stride_tricks.sliding_window_view(padded, (2 * a + 1, 2 * b + 1),
                                                   axis=(-2, -1))
    dr, dd = np.meshgrid(np.arange(-a, a + 1), np.arange(-b, b + 1), indexing="ij")
    is_train = ~((np.abs(dr) <= g[0]) & (np.abs(dd) <= g[1]))
    kth = np.unique(k) - 1
    level = np.empty_like(p)
    n_maps = int(np.prod(p.shape[:-2], dtype=np.int64))
    rows = max(1, (1 << 22) // max(1, n_maps * p.shape[-1] * int(is_train.sum())))  # ~32 MB
    for r0 in range(0, p.shape[-2], rows):  # blocks of rows bound the memory, not a per-cell loop
        # (..., rows, D, N_max); missing range cells are +inf and order last
        stack = np.partition(win[..., r0:r0 + rows, :, :, :][..., is_train], kth, axis=-1)
        kk = np.broadcast_to((k[r0:r0 + rows] - 1)[..., None], stack.shape[:-1] + (1,))
        level[..., r0:r0 + rows, :] = np.take_along_axis(stack, kk, axis=-1)[..., 0]

    if pfa is not None:
        keys = np.stack([n, k], axis=-1)
        factor = _per_unique(keys, lambda nn, kk: os_factor(nn, kk, float(pfa), int(n_looks)))
        threshold = factor * level
    elif domain == "power":
        threshold = scale * level
    else:
        threshold = 10.0 ** (scale * _to_db(level, _db_floor(p)) / 10.0)
    threshold = np.where(n > 0, threshold, np.inf)
    return p > threshold, threshold
