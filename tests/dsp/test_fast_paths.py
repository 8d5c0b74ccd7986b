"""The detection chain's fast paths equal the straightforward code they replaced (kept here as the
reference): the CFAR's integral image, the 3 x 3 local maxima and the map's median, bit for bit,
on random maps of every shape the chain meets (hypothesis), including ties and a batch axis."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from blindspot.dsp.cfar import _BoxSummer, cfar_2d
from blindspot.dsp.chain import _median
from blindspot.dsp.detections import local_maxima


def integral_reference(x: np.ndarray, a: int, b: int) -> np.ndarray:
    """The integral image as it was built before: np.pad (wrap the Doppler columns, zero rows),
    then the two cumsums."""
    lead = ((0, 0),) * (x.ndim - 2)
    padded = np.pad(x, lead + ((0, 0), (b, b)), mode="wrap") if b else x
    padded = np.pad(padded, lead + ((a, a), (0, 0)), mode="constant")
    integral = np.zeros(padded.shape[:-2] + (padded.shape[-2] + 1, padded.shape[-1] + 1))
    inner = integral[..., 1:, 1:]
    np.cumsum(padded, axis=-2, out=inner)
    np.cumsum(inner, axis=-1, out=inner)
    return integral


def local_maxima_reference(p: np.ndarray) -> np.ndarray:
    """The 8-neighbour test as it was written before: -inf rows by np.pad, Doppler by np.roll."""
    lead = ((0, 0),) * (p.ndim - 2)
    padded = np.pad(p, lead + ((1, 1), (0, 0)), constant_values=-np.inf)
    n_rows = p.shape[-2]
    is_max = np.ones(p.shape, dtype=bool)
    for dr in (-1, 0, 1):
        rows = padded[..., 1 + dr:1 + dr + n_rows, :]
        for dd in (-1, 0, 1):
            if dr == 0 and dd == 0:
                continue
            is_max &= p >= np.roll(rows, -dd, axis=-1)
    return is_max


@st.composite
def maps(draw, min_cols: int = 1):
    """(frames, range, doppler) float64 power maps: exponential noise (a square-law detector's
    output), or a few distinct levels so that ties and plateaus occur."""
    frames = draw(st.integers(1, 3))
    rows = draw(st.integers(1, 40))
    cols = draw(st.integers(min_cols, 24))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    if draw(st.booleans()):
        return rng.exponential(draw(st.floats(1e-3, 1e9)), (frames, rows, cols))
    return rng.integers(0, 3, (frames, rows, cols)).astype(np.float64)


@settings(max_examples=60, deadline=None)
@given(maps(), st.integers(0, 12), st.integers(0, 11), st.data())
def test_integral_image_is_bit_for_bit_the_padded_one(p, a, b, data):
    b = min(b, (p.shape[-1] - 1) // 2)  # the CFAR's window check keeps 2b + 1 <= Doppler bins
    np.testing.assert_array_equal(_BoxSummer(p, a, b).integral, integral_reference(p, a, b))
    one = data.draw(st.integers(0, p.shape[0] - 1))
    np.testing.assert_array_equal(_BoxSummer(p[one], a, b).integral,
                                  integral_reference(p[one], a, b))


@settings(max_examples=60, deadline=None)
@given(maps(min_cols=7), st.sampled_from(["power", "db"]), st.sampled_from(["ca", "go", "so"]))
def test_cfar_mask_and_threshold_unchanged(p, domain, mode):
    """The whole CFAR on the integral images built either way: the same mask and threshold."""
    import blindspot.dsp.cfar as cfar_mod

    res = cfar_2d(p + 1.0, (1, 1), (2, 2), scale=1.5, domain=domain, mode=mode)
    new_init = cfar_mod._BoxSummer.__init__

    def old_init(self, x, a, b):
        self.shape, self.a, self.b = x.shape, a, b
        self.integral = integral_reference(x, a, b)

    cfar_mod._BoxSummer.__init__ = old_init
    try:
        ref = cfar_2d(p + 1.0, (1, 1), (2, 2), scale=1.5, domain=domain, mode=mode)
    finally:
        cfar_mod._BoxSummer.__init__ = new_init
    np.testing.assert_array_equal(res.mask, ref.mask)
    np.testing.assert_array_equal(res.threshold, ref.threshold)


@settings(max_examples=80, deadline=None)
@given(maps())
def test_local_maxima_unchanged(p):
    np.testing.assert_array_equal(local_maxima(p), local_maxima_reference(p))
    np.testing.assert_array_equal(local_maxima(p[0]), local_maxima_reference(p[0]))


@settings(max_examples=60, deadline=None)
@given(maps())
def test_median_is_numpys(p):
    assert _median(p) == float(np.median(p))
    view = np.swapaxes(p, -1, -2)  # the chain's maps are transposed views
    assert _median(view) == float(np.median(view))


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([None, 64, 41, 2]),
       st.sampled_from(["music", "bartlett", "capon"]), st.integers(1, 12))
def test_unitary_scan_equals_the_complex_steering_scan(seed, subarray, method, n_snap):
    """The grid scan of a forward-backward subspace in real arithmetic (|E^T r(u)|^2, the real
    steering of unitary MUSIC) equals the scan |B^H a(u)|^2 with the complex steering matrix
    (doa_spectrum's path), for even and odd (sub)arrays and every method."""
    from blindspot.dsp.doa import doa_angles, doa_spectrum

    rng = np.random.default_rng(seed)
    p = np.arange(86) * 0.5
    theta = rng.uniform(-70, 70, (5, 2))
    a = np.exp(2j * np.pi * p[None, :, None] * np.sin(np.radians(theta))[:, None, :])
    amp = rng.normal(size=(5, 2, n_snap)) + 1j * rng.normal(size=(5, 2, n_snap))
    x = a @ amp + 0.3 * (rng.normal(size=(5, 86, n_snap)) + 1j * rng.normal(size=(5, 86, n_snap)))
    opts = dict(method=method, forward_backward=True, subarray=subarray,
                loading=0.1 if method == "capon" else 0.0)
    _, spec = doa_angles(x, p, 1, 1, return_spectrum=True, **opts)
    ref = doa_spectrum(x, p, n_signals=1, **opts)
    if method == "music":  # compare M - g = 1 / P: P itself amplifies rounding near a peak
        k = 86 if subarray is None else subarray
        np.testing.assert_allclose(1 / spec, 1 / ref, rtol=0, atol=1e-12 * k)
    else:
        np.testing.assert_allclose(spec, ref, rtol=1e-9)


@settings(max_examples=100, deadline=None)
@given(st.integers(1, 40), st.integers(0, 2**32 - 1), st.floats(0.0, 0.3))
def test_connected_labels_are_scipys(n, seed, density):
    """Components and their numbering equal scipy's connected_components on random graphs
    (chains, isolated nodes, dense clusters)."""
    import scipy.sparse
    import scipy.sparse.csgraph

    from blindspot.dsp.points import connected_labels

    rng = np.random.default_rng(seed)
    m = int(density * n * n) + rng.integers(0, 3)
    i, j = rng.integers(0, n, m), rng.integers(0, n, m)
    if rng.random() < 0.3:  # a long chain in a random order: many propagation rounds
        perm = rng.permutation(n)
        i, j = np.r_[i, perm[:-1]], np.r_[j, perm[1:]]
    graph = scipy.sparse.csr_matrix((np.ones(i.size, dtype=bool), (i, j)), shape=(n, n))
    _, ref = scipy.sparse.csgraph.connected_components(graph, directed=False)
    np.testing.assert_array_equal(connected_labels(n, i, j), ref)
