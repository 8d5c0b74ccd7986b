"""CFAR against theory (false-alarm rate, Swerling-0 detection probability) and against a
brute-force per-cell reference (edges, wrap, GO/SO/OS, dB domain)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.integrate
import scipy.stats

from blindspot.dsp.cfar import (
    CfarError, ca_cfar_2d, ca_factor, cfar_2d, os_cfar_2d, os_factor, training_mean,
)

GUARD, TRAIN = (2, 2), (4, 4)


def exp_maps(rng, n_maps, shape=(1024, 1024), looks=1):
    """Square-law noise: |complex Gaussian|^2 with unit mean per look, summed over ``looks``."""
    return rng.gamma(shape=looks, size=(n_maps, *shape))


# ------------------------------------------------------------------ brute-force reference


def reference_cells(shape, r, d, guard, train):
    """Training cells of CUT (r, d), written cell by cell: range clipped, Doppler wrapped.
    Returns (lower-half list, upper-half list) of (row, col)."""
    R, D = shape
    lower, upper = [], []
    for dr in range(-guard[0] - train[0], guard[0] + train[0] + 1):
        for dd in range(-guard[1] - train[1], guard[1] + train[1] + 1):
            if abs(dr) <= guard[0] and abs(dd) <= guard[1]:
                continue
            rr = r + dr
            if not 0 <= rr < R:
                continue
            cell = (rr, (d + dd) % D)
            (lower if (dr < 0 or (dr == 0 and dd < 0)) else upper).append(cell)
    return lower, upper


def reference_threshold(p, guard, train, rule):
    R, D = p.shape
    out = np.empty_like(p)
    for r in range(R):
        for d in range(D):
            lo, hi = reference_cells(p.shape, r, d, guard, train)
            out[r, d] = rule(np.array([p[c] for c in lo]), np.array([p[c] for c in hi]))
    return out


@pytest.fixture(scope="module")
def small_map():
    rng = np.random.default_rng(7)
    p = rng.exponential(size=(13, 11))
    p[0, 0] = 0.0  # a zero cell exercises the dB floor
    return p


def test_ca_matches_brute_force_with_edges_and_wrap(small_map):
    g, t, pfa = (1, 1), (2, 3), 1e-3

    def rule(lo, hi):
        cells = np.concatenate([lo, hi])
        n = cells.size
        return n * (pfa ** (-1 / n) - 1) * cells.mean()

    mask, thr = ca_cfar_2d(small_map, g, t, pfa=pfa)
    np.testing.assert_allclose(thr, reference_threshold(small_map, g, t, rule), rtol=1e-10)
    np.testing.assert_array_equal(mask, small_map > thr)
    # the edge row really has fewer training cells: outer 4 rows x 9 cols - 2 x 3 guard cells
    _, n = training_mean(small_map, g, t)
    assert n[0, 5] == 4 * 9 - 2 * 3 and n[6, 5] == 7 * 9 - 3 * 3


@pytest.mark.parametrize("domain", ["power", "db"])
@pytest.mark.parametrize("mode", ["ca", "go", "so"])
def test_scale_rules_match_brute_force(small_map, mode, domain):
    g, t, scale = (1, 0), (2, 2), 1.18
    floor = small_map[small_map > 0].min()
    conv = (lambda x: x) if domain == "power" else (lambda x: 10 * np.log10(np.maximum(x, floor)))

    def rule(lo, hi):
        m_all = conv(np.concatenate([lo, hi])).mean()
        m_lo = conv(lo).mean() if lo.size else np.nan
        m_hi = conv(hi).mean() if hi.size else np.nan
        level = {"ca": m_all, "go": np.nanmax([m_lo, m_hi]), "so": np.nanmin([m_lo, m_hi])}[mode]
        return scale * level if domain == "power" else 10 ** (scale * level / 10)

    _, thr = ca_cfar_2d(small_map, g, t, scale=scale, domain=domain, mode=mode)
    np.testing.assert_allclose(thr, reference_threshold(small_map, g, t, rule), rtol=1e-9)


def test_os_matches_brute_force(small_map):
    g, t, rank = (1, 1), (2, 2), 0.75

    def rule(lo, hi):
        cells = np.sort(np.concatenate([lo, hi]))
        k = int(np.clip(np.rint(rank * cells.size), 1, cells.size))
        return 2.5 * cells[k - 1]

    _, thr = os_cfar_2d(small_map, g, t, rank=rank, scale=2.5)
    np.testing.assert_allclose(thr, reference_threshold(small_map, g, t, rule), rtol=1e-12)


def test_doppler_axis_wraps():
    rng = np.random.default_rng(3)
    p = rng.exponential(size=(40, 32))
    res = cfar_2d(p, GUARD, TRAIN, pfa=1e-3)
    shifted = cfar_2d(np.roll(p, 9, axis=1), GUARD, TRAIN, pfa=1e-3)
    # a circular Doppler shift commutes with the detector only if the Doppler axis wraps
    np.testing.assert_allclose(shifted.threshold, np.roll(res.threshold, 9, axis=1), rtol=1e-10)
    # a strong target at Doppler bin 0 raises the threshold of bins at the far end (via the wrap)
    q = p.copy()
    q[20, 0] = 1e6
    r2 = cfar_2d(q, GUARD, TRAIN, pfa=1e-3)
    assert r2.threshold[20, 32 - 4] > 100 * res.threshold[20, 32 - 4]
    assert r2.threshold[20, 32 - 2] == pytest.approx(res.threshold[20, 32 - 2])  # guard cell
    assert r2.mask[20, 0]


def test_bad_arguments_are_named():
    p = np.ones((20, 20))
    with pytest.raises(CfarError, match="exactly one of pfa"):
        ca_cfar_2d(p, 1, 2)
    with pytest.raises(CfarError, match="exactly one of pfa"):
        ca_cfar_2d(p, 1, 2, pfa=1e-3, scale=2.0)
    with pytest.raises(CfarError, match="'power' when pfa is given"):
        ca_cfar_2d(p, 1, 2, pfa=1e-3, domain="db")
    with pytest.raises(CfarError, match="wider than the map"):
        ca_cfar_2d(p, (1, 5), (1, 5), pfa=1e-3)
    with pytest.raises(CfarError, match="non-negative"):
        ca_cfar_2d(-p, 1, 2, pfa=1e-3)
    with pytest.raises(CfarError, match="guard"):
        ca_cfar_2d(p, (1, 2, 3), 2, pfa=1e-3)
    with pytest.raises(CfarError, match="pfa must be"):
        ca_cfar_2d(p, 1, 2, pfa=1.5)


# ------------------------------------------------------------------ theory: false alarms


@pytest.mark.parametrize(("pfa", "n_maps"), [(1e-3, 2), (1e-4, 10)])
def test_false_alarm_rate_matches_design(pfa, n_maps):
    """Exponential noise, >= 2e6 cells (1e7 for 1e-4 so ~1000 false alarms are expected)."""
    rng = np.random.default_rng(11)
    maps = exp_maps(rng, n_maps)
    fa = sum(int(ca_cfar_2d(m, GUARD, TRAIN, pfa=pfa)[0].sum()) for m in maps)
    rate = fa / maps.size
    assert abs(rate / pfa - 1) < 0.15, f"measured Pfa {rate:.3g} vs design {pfa:g}"


def test_false_alarm_rate_holds_on_the_edge_rows():
    """Rows 0..5 of a 12-row map have 6 different training counts (76..130: range clipped);
    each row alone keeps the design Pfa (2.6e5 cells per row, ~2600 false alarms expected)."""
    rng = np.random.default_rng(12)
    pfa = 1e-2
    p = rng.exponential(size=(12, 1 << 18))
    mask, _ = ca_cfar_2d(p, GUARD, TRAIN, pfa=pfa)
    _, n = training_mean(p[:, :64], GUARD, TRAIN)
    assert len(set(n[:6, 0])) == 6 and n[0, 0] == 7 * 13 - 3 * 5
    rates = mask.mean(axis=1)
    np.testing.assert_array_less(np.abs(rates / pfa - 1), 0.1)
    # the edge row's factor is the one for its own, smaller N
    _, mean = ca_cfar_2d(p[:, :64], GUARD, TRAIN, scale=1.0)
    _, thr = ca_cfar_2d(p[:, :64], GUARD, TRAIN, pfa=pfa)
    assert thr[0, 0] / mean[0, 0] == pytest.approx(ca_factor(76, pfa))
    assert ca_factor(76, pfa) > ca_factor(144, pfa)


@pytest.mark.parametrize("looks", [4])
def test_false_alarm_rate_noncoherent_sum(looks):
    """Gamma(K) noise (K channels summed): the generalised factor keeps the Pfa."""
    rng = np.random.default_rng(13)
    maps = exp_maps(rng, 2, looks=looks)
    pfa = 1e-3
    fa = sum(int(ca_cfar_2d(m, GUARD, TRAIN, pfa=pfa, n_looks=looks)[0].sum()) for m in maps)
    assert abs(fa / maps.size / pfa - 1) < 0.15
    # the K=1 factor is far too conservative for summed channels
    fa1 = sum(int(ca_cfar_2d(m, GUARD, TRAIN, pfa=pfa)[0].sum()) for m in maps)
    assert fa1 / maps.size < 0.2 * pfa


@pytest.mark.parametrize("mode", ["go", "so"])
def test_false_alarm_rate_go_so(mode):
    rng = np.random.default_rng(14)
    maps = exp_maps(rng, 2)
    pfa = 1e-3
    fa = sum(int(ca_cfar_2d(m, GUARD, TRAIN, pfa=pfa, mode=mode)[0].sum()) for m in maps)
    assert abs(fa / maps.size / pfa - 1) < 0.15


def test_false_alarm_rate_os():
    """OS is slower (a partition per cell): 5e5 cells at Pfa 1e-2 (~5000 false alarms)."""
    rng = np.random.default_rng(15)
    p = rng.exponential(size=(512, 1024))
    pfa = 1e-2
    mask, _ = os_cfar_2d(p, (1, 1), (3, 3), rank=0.75, pfa=pfa)
    assert abs(mask.mean() / pfa - 1) < 0.1


def test_os_factor_closed_form():
    # N = 1, k = 1: Pfa = 1 / (1 + alpha)
    assert os_factor(1, 1, 0.01) == pytest.approx(99.0)
    # K > 1 numerical path agrees with K = 1 closed form when K = 1 integrand is used
    from blindspot.dsp.cfar import os_pfa
    a = os_factor(24, 18, 1e-3)
    assert os_pfa(a, 24, 18) == pytest.approx(1e-3, rel=1e-9)


# ------------------------------------------------------------------ theory: detection


def swerling0_pd(snr: float, n: int, alpha: float) -> float:
    """P(|A + w|^2 > alpha S / n): 2|A+w|^2 is noncentral chi-square (2 dof, nc 2 SNR) for
    unit-power noise w; S ~ Gamma(n) is the training sum. Integrated over S numerically."""
    def integrand(s):
        return (scipy.stats.ncx2.sf(2 * alpha * s / n, df=2, nc=2 * snr)
                * scipy.stats.gamma.pdf(s, a=n))
    val, _ = scipy.integrate.quad(integrand, 0, n + 40 * np.sqrt(n), limit=200)
    return val


def test_detection_probability_swerling0():
    rng = np.random.default_rng(21)
    pfa, step = 1e-4, 16
    snrs_db = np.array([8.0, 10.0, 12.0, 14.0])
    shape = (1024, 1024)
    rows, cols = np.meshgrid(np.arange(8, shape[0], step), np.arange(8, shape[1], step),
                             indexing="ij")
    which = (np.arange(rows.size) % snrs_db.size).reshape(rows.shape)
    hits = np.zeros(snrs_db.size)
    trials = np.zeros(snrs_db.size)
    for _ in range(3):
        noise = (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) / np.sqrt(2)
        amp = np.sqrt(10 ** (snrs_db[which] / 10)) * np.exp(2j * np.pi * rng.random(which.shape))
        noise[rows, cols] += amp
        mask, _ = ca_cfar_2d(np.abs(noise) ** 2, GUARD, TRAIN, pfa=pfa)
        np.add.at(hits, which.ravel(), mask[rows, cols].ravel())
        np.add.at(trials, which.ravel(), 1)
    measured = hits / trials
    n = (2 * 6 + 1) ** 2 - 25
    theory = np.array([swerling0_pd(10 ** (s / 10), n, ca_factor(n, pfa)) for s in snrs_db])
    assert theory[0] < 0.5 < theory[-1]  # the SNRs span the curve's knee
    sigma = np.sqrt(theory * (1 - theory) / trials)
    np.testing.assert_array_less(np.abs(measured - theory), 4 * sigma + 0.005)


def test_false_alarm_rate_os_gamma_looks():
    """OS factor for Gamma(K) cells (numerical path), measured on 5e5 cells."""
    rng = np.random.default_rng(16)
    p = rng.gamma(8, size=(512, 1024))
    mask, _ = os_cfar_2d(p, (1, 1), (3, 3), rank=0.75, pfa=1e-2, n_looks=8)
    assert abs(mask.mean() / 1e-2 - 1) < 0.1
