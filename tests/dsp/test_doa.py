"""Angle estimation against theory: the Cramer-Rao bound on the 86-element MMWCAS virtual array,
resolution below the Bartlett beamwidth, coherent sources with spatial smoothing, and the
pseudo-spectrum formulas written out directly."""

from __future__ import annotations

import numpy as np
import pytest

from blindspot.dsp.doa import (
    DEFAULT_GRID_DEG, POWER_RIDGE, DoaError, _source_powers, bartlett_angles, bartlett_spectrum,
    capon_angles, capon_spectrum, music_angles, music_spectrum,
)
from blindspot.radar.array import mmwcas_array


@pytest.fixture(scope="module")
def ula():
    pos = mmwcas_array(freq_hz=77e9).ula_positions_wl
    assert pos.size == 86
    return pos


def plane_waves(rng, pos, angles_deg, n_snap, snr_db, trials=1, coherent=False):
    """(trials, M, L) snapshots: unit-modulus random-phase sources at ``angles_deg`` plus
    circular white noise of power 10^(-snr/10) per element."""
    a = np.exp(2j * np.pi * np.outer(pos, np.sin(np.radians(angles_deg))))  # (M, S)
    n_src = len(angles_deg)
    shape = (trials, 1 if coherent else n_src, n_snap)
    s = np.exp(2j * np.pi * rng.random(shape))
    if coherent:
        s = np.repeat(s, n_src, axis=1) * np.exp(2j * np.pi * rng.random((trials, n_src, 1)))
    sigma2 = 10 ** (-snr_db / 10)
    noise = np.sqrt(sigma2 / 2) * (rng.standard_normal((trials, pos.size, n_snap))
                                   + 1j * rng.standard_normal((trials, pos.size, n_snap)))
    return a @ s + noise


def crb_deg(pos, theta_deg, snr_db, n_snap):
    """Deterministic (conditional) CRB of one source on a linear array, in degrees.

    x_l = a(theta) s_l + n_l, n ~ CN(0, s2 I), a_m = exp(j 2 pi p_m sin theta). With
    d = da/dtheta = j 2 pi cos(theta) p * a, the Fisher information is
    (2 / s2) sum_l |s_l|^2 d^H P_a_perp d, and d^H P_a_perp d = (2 pi cos theta)^2 sum (p - mean p)^2.
    With |s_l| = 1 and SNR = 1 / s2:
        var(theta) >= 1 / (2 L SNR (2 pi cos theta)^2 sum_m (p_m - mean p)^2)   [rad^2]
    (for a ULA of spacing d this is the familiar 6 / (L SNR (2 pi d cos theta)^2 M (M^2 - 1))).
    """
    snr = 10 ** (snr_db / 10)
    spread = np.sum((pos - pos.mean()) ** 2)
    var = 1.0 / (2 * n_snap * snr * (2 * np.pi * np.cos(np.radians(theta_deg))) ** 2 * spread)
    return np.degrees(np.sqrt(var))


@pytest.mark.parametrize("snr_db", [10.0, 20.0])
@pytest.mark.parametrize("n_signals", [1, 3])
def test_music_rmse_reaches_the_cramer_rao_bound(ula, snr_db, n_signals):
    rng = np.random.default_rng(int(snr_db) * 10 + n_signals)
    theta, n_snap, trials = 17.3, 64, 400
    x = plane_waves(rng, ula, [theta], n_snap, snr_db, trials)
    est = music_angles(x, ula, n_targets=1, n_signals=n_signals)[:, 0]
    rmse = np.sqrt(np.mean((est - theta) ** 2))
    bound = crb_deg(ula, theta, snr_db, n_snap)
    # the bound is also a floor: a too-small or too-large CRB formula fails one side
    assert 0.85 * bound < rmse < 1.5 * bound, f"RMSE {rmse:.3g} deg vs CRB {bound:.3g} deg"


def test_music_resolves_inside_the_bartlett_beamwidth(ula):
    rng = np.random.default_rng(3)
    # Bartlett half-power beamwidth ~ 0.886 / (M d) rad = 1.18 deg for 86 x 0.501 wavelengths
    hpbw = np.degrees(0.886 / (ula.size * (ula[1] - ula[0])))
    truth = np.array([10.0, 10.0 + 0.6 * hpbw / np.cos(np.radians(10))])
    x = plane_waves(rng, ula, truth, 64, 15.0, trials=20)
    music = np.sort(music_angles(x, ula, n_targets=2), axis=1)
    assert np.all(np.abs(music - truth) < 0.1), music
    bart = np.sort(bartlett_angles(x, ula, n_targets=2), axis=1)
    resolved = np.all(np.abs(bart - truth) < 0.3, axis=1)
    assert not resolved.any(), bart  # Bartlett merges the two into one lobe
    merged = bartlett_angles(x, ula, n_targets=1)[:, 0]
    assert np.all((merged > truth[0]) & (merged < truth[1]))


def test_spatial_smoothing_separates_coherent_sources(ula):
    """Two fully coherent returns (like two scatterers of one car in one cell)."""
    rng = np.random.default_rng(4)
    truth = np.array([0.0, 0.8])  # inside the beamwidth
    x = plane_waves(rng, ula, truth, 32, 20.0, trials=10, coherent=True)
    plain = np.sort(music_angles(x, ula, n_targets=2, n_signals=2), axis=1)
    smooth = np.sort(music_angles(x, ula, n_targets=2, n_signals=2, subarray=60,
                                  forward_backward=True), axis=1)
    assert np.all(np.abs(smooth - truth) < 0.05), smooth
    # without smoothing the rank-1 signal part misplaces the peaks in most trials
    assert np.mean(np.abs(plain - truth).max(axis=1) > 0.3) >= 0.5, plain


def test_music_spectrum_formula_and_batching(ula):
    rng = np.random.default_rng(5)
    x = plane_waves(rng, ula, [-20.0, 35.0], 100, 5.0, trials=3)
    grid = np.linspace(-60, 60, 97)
    spec = music_spectrum(x, ula, grid, n_signals=3)
    assert spec.shape == (3, grid.size)
    for i in range(3):  # written out for one detection at a time
        r = x[i] @ x[i].conj().T / x.shape[2]
        _, v = np.linalg.eigh(r)
        en = v[:, :-3]
        a = np.exp(2j * np.pi * np.outer(ula, np.sin(np.radians(grid))))
        ref = 1.0 / np.sum(np.abs(en.conj().T @ a) ** 2, axis=0)
        np.testing.assert_allclose(spec[i], ref, rtol=1e-6)
        np.testing.assert_allclose(music_spectrum(x[i], ula, grid), spec[i], rtol=1e-12)
    bart = bartlett_spectrum(x[0], ula, grid)
    a = np.exp(2j * np.pi * np.outer(ula, np.sin(np.radians(grid))))
    np.testing.assert_allclose(bart, np.mean(np.abs(a.conj().T @ x[0]) ** 2, axis=1) / ula.size,
                               rtol=1e-9)
    r = x[0] @ x[0].conj().T / x.shape[2]
    capon = capon_spectrum(x[0], ula, grid)
    ref = 1 / np.real(np.einsum("mg,mg->g", a.conj(), np.linalg.solve(r, a)))
    np.testing.assert_allclose(capon, ref, rtol=1e-6)


def test_angles_refine_off_grid_and_capon_agrees(ula):
    rng = np.random.default_rng(6)
    truth = -33.337  # far from any 0.25-deg grid point
    x = plane_waves(rng, ula, [truth], 200, 30.0)
    assert music_angles(x, ula)[0] == pytest.approx(truth, abs=0.005)
    assert capon_angles(x, ula)[0] == pytest.approx(truth, abs=0.005)
    assert bartlett_angles(x, ula)[0] == pytest.approx(truth, abs=0.005)
    assert DEFAULT_GRID_DEG[0] == -90 and DEFAULT_GRID_DEG[-1] == 90


def test_missing_peaks_are_nan_and_bad_input_is_named(ula):
    x = plane_waves(np.random.default_rng(7), ula[:4], [0.0], 10, 30.0)[0]
    ang = bartlett_angles(x, ula[:4], n_targets=5, grid_deg=np.linspace(-30, 30, 31))
    assert np.isnan(ang[-1]) and np.isfinite(ang[0])
    with pytest.raises(DoaError, match="M = 86"):
        music_angles(np.ones((10, 5), complex), ula)
    with pytest.raises(DoaError, match="n_signals"):
        music_spectrum(x, ula[:4], n_signals=4)
    with pytest.raises(DoaError, match="full-rank"):
        capon_spectrum(x[:, :2], ula[:4])
    with pytest.raises(DoaError, match="uniform"):
        music_spectrum(x, np.array([0, 0.5, 1.5, 2.0]), subarray=3)


def extended_and_point(rng, pos, trials, strong_deg=7.0, spread_deg=0.2, n_parts=3,
                       weak_deg=14.0, weak_db=-10.0, n_snap=9, snr_db=30.0):
    """(trials, M, L): a unit-power source spread over ``n_parts`` points within
    +-``spread_deg`` of ``strong_deg`` (a body's parts, a car's corner) and a point source
    ``weak_db`` below it at ``weak_deg``; independent random phases, white noise."""
    ang = np.concatenate([strong_deg + np.linspace(-spread_deg, spread_deg, n_parts), [weak_deg]])
    amp = np.concatenate([np.full(n_parts, n_parts ** -0.5), [10 ** (weak_db / 20)]])
    a = np.exp(2j * np.pi * np.outer(pos, np.sin(np.radians(ang))))
    s = amp[:, None] * np.exp(2j * np.pi * rng.random((trials, ang.size, n_snap)))
    sigma = np.sqrt(10 ** (-snr_db / 10) / 2)
    noise = sigma * (rng.standard_normal((trials, pos.size, n_snap))
                     + 1j * rng.standard_normal((trials, pos.size, n_snap)))
    return a @ s + noise


def test_power_order_takes_the_strong_extended_source_the_spectrum_misses(ula):
    """A point source 10 dB down has the sharper MUSIC peak than a strong source spread over
    0.4 deg, so the pseudo-spectrum's first peak is the weak one; ranked by least-squares
    power the strong one comes first (the chain's child beside a car's corner)."""
    x = extended_and_point(np.random.default_rng(11), ula, 60)
    opts = dict(n_signals=3, forward_backward=True, subarray=64)
    by_spectrum = music_angles(x, ula, **opts, peak_order="spectrum")[:, 0]
    by_power = music_angles(x, ula, **opts, peak_order="power")[:, 0]
    assert np.mean(np.abs(by_spectrum - 14.0) < 0.5) > 0.9       # the failure, as measured
    np.testing.assert_allclose(by_power, 7.0, atol=0.3)   # every trial: inside the strong one
    # two peaks asked for: the strong one first, then (but for a split of the spread source in
    # one trial of 60) the weak one
    both = music_angles(x, ula, 2, **opts, peak_order="power")
    np.testing.assert_array_equal(both[:, 0], by_power)
    assert np.mean(np.abs(both[:, 1] - 14.0) < 0.1) >= 0.95


def test_source_powers_are_the_joint_least_squares_amplitudes(ula):
    """Against the powers the snapshots were made with: a source 20 dB down on the first
    sidelobe of a strong one (64 snapshots, 30 dB SNR). Fitted alone, |a^H x / M|^2, the weak
    one reads the strong one's sidelobe (several times its power); fitted jointly it reads its
    own power, scaled as every isolated source by the ridge's 1 / (1 + r)^2. A missing peak
    (valid False) gets 0 and changes nothing."""
    rng = np.random.default_rng(12)
    u0 = 0.0
    grid = np.linspace(0.001, 0.1, 2000)                   # the strong one's first sidelobe
    beam = np.abs(np.exp(2j * np.pi * np.outer(grid, ula)).sum(axis=1)) / ula.size
    side = grid[np.flatnonzero((beam[1:-1] > beam[:-2]) & (beam[1:-1] > beam[2:]))[0] + 1]
    u = np.array([u0, side])
    amp = np.array([1.0, 0.1])
    a = np.exp(2j * np.pi * np.outer(ula, u))
    s = amp[:, None] * np.exp(2j * np.pi * rng.random((2, 64)))
    x = a @ s + 0.0224 * (rng.standard_normal((86, 64)) + 1j * rng.standard_normal((86, 64)))
    alone = np.mean(np.abs(a.conj().T @ x / ula.size) ** 2, axis=1)
    assert alone[1] > 2 * amp[1] ** 2                     # the sidelobe, not the source
    cand = np.array([[u0, side, np.sin(np.radians(40.0))]])
    pw = _source_powers(x[None], ula, cand, np.array([[True, True, False]]))
    np.testing.assert_allclose(pw[0, :2], amp ** 2 / (1 + POWER_RIDGE) ** 2, rtol=0.03)
    assert pw[0, 2] == 0.0
    two = _source_powers(x[None], ula, cand[:, :2], np.array([[True, True]]))
    np.testing.assert_allclose(two, pw[:, :2], rtol=1e-12)


def test_power_order_is_not_won_by_aliased_end_fire_peaks(ula):
    """On the 0.5013-wavelength array u = -1 aliases to u = +1.003: candidates at -90, +90 and
    83.8 deg are nearly one steering vector. With one source at 30 deg and -5 dB SNR per
    element (9 snapshots) an unridged fit gives that pair many times the source's power from
    noise alone; the ridge keeps the source first in every draw."""
    rng = np.random.default_rng(14)
    n = 300
    a = np.exp(2j * np.pi * ula * np.sin(np.radians(30.0)))
    x = (a[None, :, None] * np.exp(2j * np.pi * rng.random((n, 1, 9)))
         + np.sqrt(10 ** 0.5 / 2) * (rng.standard_normal((n, 86, 9))
                                     + 1j * rng.standard_normal((n, 86, 9))))
    cand = np.sin(np.radians(np.array([[30.0, 83.8, -90.0]]))).repeat(n, axis=0)
    pw = _source_powers(x, ula, cand, np.ones(cand.shape, dtype=bool))
    assert np.all(pw.argmax(axis=1) == 0)


def test_peak_order_is_checked(ula):
    x = plane_waves(np.random.default_rng(13), ula, [5.0], 9, 20.0)[0]
    with pytest.raises(DoaError, match="peak_order must be one of .*'loudest'"):
        music_angles(x, ula, peak_order="loudest")
    with pytest.raises(DoaError, match="peak_order must be one of"):
        music_angles(x, ula, peak_order=np.array(["power"]))


@pytest.mark.parametrize("peak_order", ["spectrum", "power"])
def test_all_zero_snapshots_have_no_angle_with_smoothing(ula, peak_order):
    """Smoothing and forward-backward leave a zero covariance's eigenvectors arbitrary; a
    detection without signal still has no angle (NaN), beside one that has."""
    x = plane_waves(np.random.default_rng(15), ula, [5.0], 9, 20.0)
    x = np.concatenate([x, np.zeros_like(x)])
    ang = music_angles(x, ula, 2, forward_backward=True, subarray=64, peak_order=peak_order)
    assert np.all(np.isnan(ang[1])) and abs(ang[0, 0] - 5.0) < 0.1


@pytest.mark.parametrize("m", [8, 9])
@pytest.mark.parametrize("subarray", [None, 6])
def test_real_valued_forward_backward_equals_the_complex_one(m, subarray):
    """The unitary transform path (real eigh) gives the same spectra as forward-backward
    averaging written out in complex arithmetic."""
    from blindspot.dsp.doa import _factor, _spectrum_from_g, covariance

    rng = np.random.default_rng(8)
    pos = 0.5 * np.arange(m)
    x = plane_waves(rng, pos, [-20.0, 10.0], 7, 10.0, trials=3)
    grid = np.linspace(-80, 80, 161)
    for method in ("music", "bartlett", "capon"):
        r, p = covariance(x, pos, forward_backward=True, subarray=subarray, loading=0.01)
        b, _ = _factor(r, method, 2)
        a = np.exp(2j * np.pi * np.outer(p, np.sin(np.radians(grid))))
        g = (np.abs(b.conj().transpose(0, 2, 1) @ a) ** 2).sum(axis=1)
        ref = _spectrum_from_g(g, method, p.size)
        got = {"music": music_spectrum, "bartlett": bartlett_spectrum,
               "capon": capon_spectrum}[method](x, pos, grid, forward_backward=True,
                                                subarray=subarray, loading=0.01,
                                                **({"n_signals": 2} if method == "music" else {}))
        np.testing.assert_allclose(got, ref, rtol=1e-7)


def test_blocks_do_not_change_results(ula):
    """Many detections (several blocks of BLOCK_DETECTIONS) give the same angles as one at a
    time."""
    from blindspot.dsp import doa

    rng = np.random.default_rng(3)
    p = np.arange(8) * 0.5
    d = doa.BLOCK_DETECTIONS + 7
    th = rng.uniform(-50, 50, d)
    x = np.exp(2j * np.pi * p[None, :, None] * np.sin(np.radians(th))[:, None, None]) \
        * (rng.normal(size=(d, 1, 6)) + 1j * rng.normal(size=(d, 1, 6)))
    x = x + 0.05 * (rng.normal(size=x.shape) + 1j * rng.normal(size=x.shape))
    whole = doa.music_angles(x, p, n_signals=1)[:, 0]
    one = np.array([doa.music_angles(x[i], p, n_signals=1)[0] for i in (0, d - 1)])
    np.testing.assert_array_equal(whole[[0, d - 1]], one)
    assert np.max(np.abs(whole - th)) < 1.0


@pytest.mark.parametrize("method", ["music", "bartlett"])
def test_non_finite_snapshots_are_named_and_flat_spectra_have_no_angle(method):
    """One NaN is a DoaError naming the array (not numpy's 'Eigenvalues did not converge');
    all-zero snapshots give a flat spectrum, which has no peak: NaN, not the grid's edge."""
    p = np.arange(8) * 0.5
    x = np.ones((8, 4), complex)
    x[3, 1] = np.nan
    with pytest.raises(DoaError, match="snapshots contain 1 non-finite"):
        doa_angles_fn(method)(x, p)
    angle = doa_angles_fn(method)(np.zeros((8, 4), complex), p)
    assert np.isnan(angle).all()


def doa_angles_fn(method):
    from blindspot.dsp import doa

    return {"music": lambda x, p: doa.music_angles(x, p, n_signals=1),
            "bartlett": doa.bartlett_angles}[method]


@pytest.mark.parametrize("k", [2, 8, 64])
def test_real_fb_covariance_is_the_unitary_transform_of_r(k):
    """The real forward-backward covariance from R's blocks (the smoothed covariance of unitary
    MUSIC) is Re(Q^H R Q) with the explicit unitary centro-Hermitian
    Q = [[I, jI], [J, -jJ]] / sqrt(2) (Huarng & Yeh 1991), and, as that theory says, R and its
    forward-backward average (R + J R* J) / 2 share it."""
    from blindspot.dsp.doa import _fb_real

    rng = np.random.default_rng(5)
    y = rng.normal(size=(6, k, 9)) + 1j * rng.normal(size=(6, k, 9))
    r = y @ np.conj(np.swapaxes(y, 1, 2))
    eye, j = np.eye(k // 2), np.eye(k // 2)[::-1]
    q = np.block([[eye, 1j * eye], [j, -1j * j]]) / np.sqrt(2.0)
    ref = np.real(q.conj().T @ r @ q)
    np.testing.assert_allclose(_fb_real(r), ref, atol=1e-12 * np.abs(ref).max())
    jk = np.eye(k)[::-1]
    fb = 0.5 * (r + jk @ r.conj() @ jk)
    np.testing.assert_allclose(q.conj().T @ fb @ q, ref, atol=1e-12 * np.abs(ref).max())
