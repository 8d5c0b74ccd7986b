"""Multi-modal predictions: a mixture of M Gaussian paths per track, and its scores.

A :class:`MixtureForecast` holds, for each of B tracks, M hypotheses (components): their
probabilities (B, M), mean paths (B, M, H, 2) metres and per-step covariances
(B, M, H, 2, 2) m^2. The per-step marginal of track b at step h is the Gaussian mixture
sum_m w_bm N(mu_bmh, S_bmh).

Scores (NaN truth rows are left out of every mean, as in :mod:`blindspot.traj.metrics`):

* :func:`best_of` - best-of-N ADE / FDE, the field's multi-modal score (Gupta et al. 2018,
  "Social GAN"): per track the smallest ADE over the N hypotheses and, separately, the
  smallest FDE, averaged over the tracks;
* :meth:`MixtureForecast.nll` - mean negative log-likelihood per point of the per-step
  mixture, nats;
* :meth:`MixtureForecast.coverage` - coverage of the mixture's highest-density regions (the
  smallest region holding probability p): a point is inside the p region when the mixture's
  probability of a density above its own is <= p, estimated by Monte Carlo from the mixture
  itself (seeded);
* :meth:`MixtureForecast.to_gaussian` - the moment-matched Gaussian, so the ellipse
  calibration of :mod:`blindspot.traj.distribution` and :mod:`blindspot.traj.conformal`
  serves a mixture too.

:func:`kmeans` (Lloyd's algorithm, k-means++ start, seeded) gives the anchors the multi-modal
head starts from (:mod:`blindspot.traj.seq2seq`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from blindspot.arrays import check_array, check_count
from blindspot.traj.distribution import DistributionError, GaussianForecast

__all__ = ["MixtureForecast", "best_of", "kmeans"]

_LOG_2PI = float(np.log(2 * np.pi))


def _logpdf(x: np.ndarray, mean: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """log N(x; mean, cov) of 2-D points, broadcast over the leading axes."""
    e = x - mean
    det = cov[..., 0, 0] * cov[..., 1, 1] - cov[..., 0, 1] ** 2
    d2 = (cov[..., 1, 1] * e[..., 0] ** 2 - 2 * cov[..., 0, 1] * e[..., 0] * e[..., 1]
          + cov[..., 0, 0] * e[..., 1] ** 2) / det
    return -0.5 * d2 - 0.5 * np.log(det) - _LOG_2PI


def _count(value, name: str, lo: int, hi: int | None, who: str) -> int:
    """``value`` as an int in [lo, hi] (hi None: no bound), else DistributionError naming it."""
    v = check_count(value, name, ge=lo, error=DistributionError, who=who)
    if hi is not None and v > hi:
        raise DistributionError(f"{who}: {name}: expected an integer in [{lo}, {hi}], "
                                f"found {value!r}")
    return v


def _logsumexp(a: np.ndarray, axis: int) -> np.ndarray:
    top = np.max(a, axis=axis, keepdims=True)
    return np.squeeze(top, axis) + np.log(np.sum(np.exp(a - top), axis=axis))


@dataclass(frozen=True)
class MixtureForecast:
    """M Gaussian paths per track and their probabilities.

    Attributes:
        weights: (B, M) probabilities, each row summing to 1.
        means: (B, M, H, 2) mean positions, metres.
        covs: (B, M, H, 2, 2) covariances, m^2, symmetric positive definite.

    Raises DistributionError (at construction): wrong or mismatched shapes, non-finite values,
    negative weights or rows not summing to 1, covariances not positive definite.
    """

    weights: np.ndarray
    means: np.ndarray
    covs: np.ndarray

    def __post_init__(self) -> None:
        who = "MixtureForecast"
        w = check_array(self.weights, "weights", ("B", "M"), error=DistributionError, who=who)
        mu = check_array(self.means, "means", ("B", "M", "H", 2), error=DistributionError,
                         who=who)
        c = check_array(self.covs, "covs", ("B", "M", "H", 2, 2), error=DistributionError,
                        who=who)
        if mu.shape[:2] != w.shape or c.shape[:3] != mu.shape[:3]:
            raise DistributionError(f"{who}: weights {w.shape}, means {mu.shape} and covs "
                                    f"{c.shape} must share (B, M) and (B, M, H)")
        if np.any(w < 0) or not np.allclose(w.sum(axis=1), 1.0, atol=1e-6):
            raise DistributionError(f"{who}: weights must be >= 0 with rows summing to 1, "
                                    f"found row sums in [{w.sum(1).min()}, {w.sum(1).max()}]")
        det = c[..., 0, 0] * c[..., 1, 1] - c[..., 0, 1] * c[..., 1, 0]
        if not np.all((c[..., 0, 0] > 0) & (det > 0)):
            raise DistributionError(f"{who}: covs must be positive definite; "
                                    f"{int(np.count_nonzero(~((c[..., 0, 0] > 0) & (det > 0))))}"
                                    f" of {det.size} matrices are not")
        object.__setattr__(self, "weights", w)
        object.__setattr__(self, "means", mu)
        object.__setattr__(self, "covs", 0.5 * (c + np.swapaxes(c, -1, -2)))

    @property
    def horizon(self) -> int:
        return int(self.means.shape[2])

    @property
    def modes(self) -> int:
        return int(self.means.shape[1])

    def mean(self) -> np.ndarray:
        """(B, H, 2) the mixture's mean path (probability-weighted mean of the hypotheses)."""
        return np.einsum("bm,bmhi->bhi", self.weights, self.means)

    def moment_cov(self) -> np.ndarray:
        """(B, H, 2, 2) the mixture's covariance about its mean (within plus between)."""
        return self.second_moment(self.mean())

    def second_moment(self, centre: np.ndarray) -> np.ndarray:
        """(B, H, 2, 2) E[(X - c)(X - c)^T] of the per-step mixtures about the paths
        ``centre`` (B, H, 2) (the covariance when ``centre`` is the mean)."""
        c = check_array(centre, "centre", (self.means.shape[0], self.horizon, 2),
                        error=DistributionError, who="MixtureForecast.second_moment")
        d = self.means - c[:, None]
        return np.einsum("bm,bmhij->bhij", self.weights,
                         self.covs + d[..., :, None] * d[..., None, :])

    def most_likely(self) -> np.ndarray:
        """(B, H, 2) the mean path of each track's most probable hypothesis."""
        k = np.argmax(self.weights, axis=1)
        return self.means[np.arange(len(k)), k]

    def to_gaussian(self) -> GaussianForecast:
        """The moment-matched :class:`GaussianForecast` (mean and covariance of the mixture)."""
        return GaussianForecast(self.mean(), self.moment_cov())

    def component(self, m: int) -> GaussianForecast:
        """Hypothesis ``m`` (0 <= m < M) of every track as a :class:`GaussianForecast`."""
        _count(m, "m", 0, self.modes - 1, "MixtureForecast.component")
        return GaussianForecast(self.means[:, m], self.covs[:, m])

    def truncated(self, horizon: int) -> MixtureForecast:
        """The first ``horizon`` (1..H) steps."""
        _count(horizon, "horizon", 1, self.horizon, "MixtureForecast.truncated")
        return MixtureForecast(self.weights, self.means[:, :, :horizon],
                               self.covs[:, :, :horizon])

    def transformed(self, linear: np.ndarray, origin: np.ndarray) -> MixtureForecast:
        """Every point mapped by ``p -> linear[b] @ p + origin[b]`` (linear (B, 2, 2), origin
        (B, 2); e.g. a track's frame back to the world), covariances ``A S A^T``."""
        b = self.weights.shape[0]
        a = check_array(linear, "linear", (b, 2, 2), error=DistributionError,
                        who="MixtureForecast.transformed")
        o = check_array(origin, "origin", (b, 2), error=DistributionError,
                        who="MixtureForecast.transformed")
        mu = np.einsum("bij,bmhj->bmhi", a, self.means) + o[:, None, None, :]
        c = np.einsum("bij,bmhjk,blk->bmhil", a, self.covs, a)
        return MixtureForecast(self.weights, mu, c)

    def most_probable(self, n: int) -> np.ndarray:
        """(B, n, H, 2) the mean paths of each track's ``n`` (1..M) most probable hypotheses,
        most probable first (ties in their order)."""
        _count(n, "n", 1, self.modes, "MixtureForecast.most_probable")
        order = np.argsort(-self.weights, axis=1, kind="stable")[:, :n]
        return np.take_along_axis(self.means, order[:, :, None, None], axis=1)

    def reduced(self, n: int, *, seed: int = 0, iterations: int = 25,
                weighted: bool = True) -> MixtureForecast:
        """The mixture merged into ``n`` (1..M) hypotheses per track by k-means of the M mean
        paths (each path one point of H x 2 coordinates), each cluster moment-matched: its
        summed probability, its probability-weighted mean path, its members' covariances
        plus their spread about that path (so the mixture's mean and covariance are kept).
        The aggregation step of MultiPath++ (Varadarajan et al. 2022), which merges an
        ensemble's pooled hypotheses into the few it reports.

        The clustering: the first centre is the most probable path, the others are drawn
        k-means++ style (chances in proportion to weight times squared distance to the
        nearest centre, from a generator seeded by ``seed``), then ``iterations`` + 1
        assignments, each followed by the weighted mean of every cluster. The weight is the
        probability (``weighted``) or 1 for every path (each path counted once, so unlikely
        paths pull centres too). A cluster left without probability (no member, or members of
        probability 0) keeps its centre with probability 0 and the covariance of the path it
        started at."""
        who = "MixtureForecast.reduced"
        b, m, h = self.means.shape[:3]
        _count(n, "n", 1, m, who)
        check_count(iterations, "iterations", ge=0, error=DistributionError, who=who)
        check_count(seed, "seed", ge=0, error=DistributionError, who=who)
        if not isinstance(weighted, bool):
            raise DistributionError(f"{who}: weighted: expected True or False, found "
                                    f"{weighted!r}")
        x, prob = self.means.reshape(b, m, h * 2), self.weights
        w = prob if weighted else np.ones_like(prob)
        rows, rng = np.arange(b), np.random.default_rng(seed)
        start = np.empty((b, n), dtype=int)
        start[:, 0] = np.argmax(prob, axis=1)
        d2 = ((x - x[rows, start[:, 0]][:, None]) ** 2).sum(-1)                   # (B, M)
        for j in range(1, n):
            p = w * d2
            p = np.where(p.sum(1)[:, None] > 0, p, (d2 > 0) + 1e-300)  # no weight left: any
            cum = np.cumsum(p, axis=1)
            pick = (cum < rng.random(b)[:, None] * cum[:, -1:]).sum(1)
            start[:, j] = np.minimum(pick, m - 1)
            d2 = np.minimum(d2, ((x - x[rows, start[:, j]][:, None]) ** 2).sum(-1))
        centres = x[rows[:, None], start]                                       # (B, n, D)
        for _ in range(iterations + 1):
            dist = ((x ** 2).sum(-1)[:, :, None] - 2 * np.einsum("bmd,bkd->bmk", x, centres)
                    + (centres ** 2).sum(-1)[:, None, :])
            onehot = np.eye(n)[np.argmin(dist, axis=2)]                           # (B, M, n)
            pull = onehot * w[:, :, None]
            total = pull.sum(1)                                                  # (B, n)
            moved = np.einsum("bmk,bmd->bkd", pull, x) / np.maximum(total, 1e-300)[..., None]
            centres = np.where(total[..., None] > 0, moved, centres)
        member = onehot * prob[:, :, None]                          # the clusters' probabilities
        mass = member.sum(1)                                                     # (B, n)
        share = member / np.maximum(mass, 1e-300)[:, None, :]                     # (B, M, n)
        empty = mass <= 0
        mu = np.where(empty[..., None], centres, np.einsum("bmk,bmd->bkd", share, x))
        mu = mu.reshape(b, n, h, 2)
        # sum_m share (S_m + (mu_m - c)(mu_m - c)^T) = the members' second moment less c c^T
        # (c their weighted mean), about the track's mean path: small numbers, and no
        # (B, M, n, H, 2, 2) array
        ref = self.mean()[:, None]
        d, c = self.means - ref, mu - ref
        cov = (np.einsum("bmk,bmhij->bkhij", share, self.covs + d[..., :, None] * d[..., None, :])
               - c[..., :, None] * c[..., None, :])
        if np.any(empty):
            cov[empty] = self.covs[rows[:, None], start][empty]
        return MixtureForecast(mass / mass.sum(1, keepdims=True), mu, cov)

    def _truth(self, truth: np.ndarray, who: str) -> np.ndarray:
        t = check_array(truth, "truth", ("B", "H", 2), error=DistributionError, who=who,
                        allow_nan=True)
        if t.shape != (self.means.shape[0], self.horizon, 2):
            raise DistributionError(f"{who}: truth: expected shape "
                                    f"{(self.means.shape[0], self.horizon, 2)}, found {t.shape}")
        return t

    def log_density(self, points: np.ndarray) -> np.ndarray:
        """(..., B, H) log density of the per-step mixtures at ``points`` (..., B, H, 2)."""
        # (..., B, H, M): each point against the M components of its track and step
        mu = np.moveaxis(self.means, 1, 2)                                   # (B, H, M, 2)
        cv = np.moveaxis(self.covs, 1, 2)                                    # (B, H, M, 2, 2)
        lp = _logpdf(points[..., None, :], mu, cv)
        return _logsumexp(lp + np.log(np.maximum(self.weights, 1e-300))[:, None, :], axis=-1)

    def nll(self, truth: np.ndarray) -> float:
        """Mean negative log-likelihood (nats per point) of truth (B, H, 2) under the per-step
        mixtures; NaN truth rows left out."""
        t = self._truth(truth, "MixtureForecast.nll")
        seen = np.isfinite(t).all(axis=-1)
        return float(-np.mean(self.log_density(np.nan_to_num(t))[seen]))

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """(n, B, H, 2) draws from the per-step mixtures (each step drawn on its own)."""
        check_count(n, "n", ge=1, error=DistributionError, who="MixtureForecast.sample")
        b, m, h = self.means.shape[:3]
        cum = np.cumsum(self.weights, axis=1)
        u = rng.random((n, b, h))
        k = np.minimum((u[..., None] > cum[None, :, None, :]).sum(-1), m - 1)  # (n, B, H)
        bi, hi = np.arange(b)[None, :, None], np.arange(h)[None, None, :]
        mu, cv = self.means[bi, k, hi], self.covs[bi, k, hi]
        chol = np.linalg.cholesky(cv)
        z = rng.standard_normal((n, b, h, 2))
        return mu + np.einsum("nbhij,nbhj->nbhi", chol, z)

    def coverage(self, truth: np.ndarray, levels: tuple[float, ...] = (0.5, 0.9, 0.95), *,
                 samples: int = 100, seed: int = 0, chunk: int = 500) -> np.ndarray:
        """(L,) coverage of the ``levels`` highest-density regions over the points with
        truth: a point is inside the p region when the Monte-Carlo share (``samples``
        draws per point, generator seeded by ``seed``) of draws denser than it is <= p. A
        calibrated mixture gives ``levels`` back, up to sampling error."""
        who = "MixtureForecast.coverage"
        t = self._truth(truth, who)
        lv = np.asarray(levels, dtype=float)
        if lv.ndim != 1 or not np.all((lv > 0) & (lv < 1)):
            raise DistributionError(f"{who}: levels: expected probabilities in (0, 1), "
                                    f"found {levels!r}")
        check_count(samples, "samples", ge=1, error=DistributionError, who=who)
        rng = np.random.default_rng(seed)
        seen = np.isfinite(t).all(axis=-1)
        inside = np.zeros((len(lv),) + seen.shape, dtype=bool)
        for i in range(0, t.shape[0], chunk):
            part = MixtureForecast(self.weights[i:i + chunk], self.means[i:i + chunk],
                                   self.covs[i:i + chunk])
            own = part.log_density(np.nan_to_num(t[i:i + chunk]))                # (b, H)
            draws = part.log_density(part.sample(samples, rng))                  # (S, b, H)
            above = (draws > own[None]).mean(axis=0)
            inside[:, i:i + chunk] = above[None] <= lv[:, None, None]
        n = max(int(seen.sum()), 1)
        return (inside & seen[None]).sum(axis=(1, 2)) / n


def best_of(means: np.ndarray, truth: np.ndarray, n: int | None = None) -> tuple[float, float]:
    """Best-of-N ADE and FDE (m): per track the smallest ADE over its first ``n`` hypotheses
    (all when None) and, on its own, the smallest FDE, each averaged over the tracks.

    means: (B, M, H, 2) hypotheses (samples or a mixture's component means), metres; truth:
    (B, H, 2) metres, NaN rows missing (left out of a track's ADE; a track without its last
    point is left out of the FDE).
    """
    who = "best_of"
    mu = check_array(means, "means", ("B", "M", "H", 2), error=DistributionError, who=who)
    t = check_array(truth, "truth", ("B", "H", 2), error=DistributionError, who=who,
                    allow_nan=True)
    if t.shape != (mu.shape[0], mu.shape[2], 2):
        raise DistributionError(f"{who}: truth: expected shape {(mu.shape[0], mu.shape[2], 2)}"
                                f", found {t.shape}")
    if n is not None:
        _count(n, "n", 1, mu.shape[1], who)
        mu = mu[:, :n]
    err = np.linalg.norm(mu - t[:, None], axis=-1)                          # (B, M, H)
    with np.errstate(invalid="ignore"):
        ade_k = np.nanmean(err, axis=-1)                                     # (B, M)
    ok = np.isfinite(ade_k).all(axis=1)
    last = np.isfinite(t[:, -1]).all(axis=-1)
    return float(np.min(ade_k[ok], axis=1).mean()), float(np.min(err[last, :, -1], axis=1).mean())


def kmeans(x: np.ndarray, k: int, *, seed: int = 0, iterations: int = 25) -> np.ndarray:
    """(k, D) centres of points x (N, D), N >= k: k-means++ start (Arthur & Vassilvitskii
    2007) from a generator seeded by ``seed``, then ``iterations`` Lloyd steps (an empty
    cluster keeps its centre)."""
    who = "kmeans"
    pts = check_array(x, "x", ("N", "D"), error=DistributionError, who=who)
    _count(k, "k", 1, pts.shape[0], who)
    check_count(iterations, "iterations", ge=0, error=DistributionError, who=who)
    rng = np.random.default_rng(seed)
    centres = [pts[rng.integers(len(pts))]]
    d2 = ((pts - centres[0]) ** 2).sum(1)
    for _ in range(1, k):
        total = d2.sum()
        i = rng.choice(len(pts), p=d2 / total) if total > 0 else rng.integers(len(pts))
        centres.append(pts[i])
        d2 = np.minimum(d2, ((pts - pts[i]) ** 2).sum(1))
    c = np.array(centres)
    for _ in range(iterations):
        lab = np.argmin((pts ** 2).sum(1)[:, None] - 2 * pts @ c.T + (c ** 2).sum(1)[None],
                        axis=1)
        for j in range(k):
            if np.any(lab == j):
                c[j] = pts[lab == j].mean(axis=0)
    return c
