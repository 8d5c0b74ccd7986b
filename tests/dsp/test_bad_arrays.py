"""Every public function of the detection chain refuses bad arrays with its module's own error.

Property-based (hypothesis): arrays of every element kind (bool, int, float, complex, str,
object), 0 to 5 axes, NaN/inf planted at a random place, are handed to each public function.
Only the documented error class may come out, never a bare numpy/scipy/torch exception; what is
accepted gives the documented output shape. Plus the physics the range-Doppler check rests on:
one NaN sample anywhere in a cube makes the chain say so (one output bin per channel sees every
sample, see ``blindspot.dsp.range_doppler``).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import event, given
from hypothesis import strategies as st

from blindspot.arrays import count_nonfinite
from blindspot.dsp import cfar, detections, doa, points, snapshots
from blindspot.dsp.doppler_compensation import CompensationError, compensate_tdm
from blindspot.dsp.range_doppler import RangeDoppler, RangeDopplerError, detection_map
from tests.dsp.test_chain import paper  # noqa: F401  (module fixture: the paper's chain)

KINDS = ("bool", "int", "float", "complex", "complex64", "str", "object")


@st.composite
def arrays(draw, max_ndim: int = 5, max_side: int = 6, fits: tuple | None = None,
           kinds: tuple[str, ...] = KINDS):
    """Any small array: a kind, a shape, and maybe one NaN or inf at a random place.

    ``fits``: a shape template the function accepts (None = any size in 1..max_side); half the
    draws take it, so the accepted path is exercised as well as the refusals."""
    kind = draw(st.sampled_from(kinds))
    if fits is not None and draw(st.booleans()):
        shape = tuple(draw(st.integers(1, max_side)) if n is None else n for n in fits)
    else:
        shape = tuple(draw(st.lists(st.integers(0, max_side), max_size=max_ndim)))
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    x = np.array(rng.normal(size=shape) * 10)  # np.array: a 0-d array stays an array
    if kind in ("bool", "int", "str", "object"):
        return {"bool": lambda: x > 0, "int": lambda: x.astype(np.int64),
                "str": lambda: x.astype(str), "object": lambda: x.astype(object)}[kind]()
    if kind.startswith("complex"):
        dtype = np.complex64 if kind == "complex64" else np.complex128
        x = (x + 1j * np.array(rng.normal(size=shape))).astype(dtype)
    bad = draw(st.sampled_from((None, np.nan, np.inf, -np.inf)))
    if bad is not None and x.size:
        x.flat[draw(st.integers(0, x.size - 1))] = bad
    return np.array(x)


def _only(error: type[Exception], fn, *args, **kwargs):
    """fn(*args) returns, or raises ``error``; anything else fails the test. The outcome is a
    hypothesis event (``pytest --hypothesis-show-statistics`` tallies them)."""
    name = getattr(fn, "__name__", type(fn).__name__)
    try:
        out = fn(*args, **kwargs)
    except error as exc:
        event(f"{name}: {type(exc).__name__}")
        return None
    event(f"{name}: accepted")
    return out


@given(arrays(fits=(None, 8, 8), kinds=("float", "int", "complex", "str")))
def test_cfar_takes_a_real_finite_non_negative_map_or_says_why(x):
    res = _only(cfar.CfarError, cfar.cfar_2d, x, (1, 1), (2, 2), pfa=1e-3)
    if res is not None:
        assert res.mask.shape == x.shape and x.dtype.kind in "biuf"
        assert count_nonfinite(x) == 0 and (x >= 0).all()
    res = _only(cfar.CfarError, cfar.os_cfar_2d, x, (1, 1), (2, 2), pfa=1e-3)
    if res is not None:
        assert res[0].shape == x.shape


@given(arrays(fits=(None, None)))
def test_local_maxima_takes_a_real_map_without_nan(x):
    res = _only(detections.DetectionError, detections.local_maxima, x)
    if res is not None:
        assert res.shape == x.shape and res.dtype == bool and x.ndim >= 2
        assert not np.isnan(x.astype(float)).any()


@given(arrays(max_ndim=2, fits=(3,), kinds=("int", "float")), arrays(max_ndim=2, fits=(3,)),
       arrays(max_ndim=2, fits=(3,), kinds=("bool", "int")))
def test_detection_order_takes_one_value_per_detection(frame, power, is_moving):
    res = _only(detections.DetectionError, detections.detection_order, frame, power, is_moving)
    if res is not None:
        assert res.shape == frame.shape == power.shape == is_moving.shape and frame.ndim == 1


@given(arrays(fits=(None, None, None, None)))
def test_detection_map_takes_finite_range_doppler_data(x):
    res = _only(RangeDopplerError, detection_map, x)
    if res is not None:
        assert res.shape == x.shape[:-2] and np.isfinite(res).all()
        assert count_nonfinite(x) == 0


@given(arrays(max_side=8, fits=(None, 4, None, None, 8)))
def test_range_doppler_takes_a_finite_cube_of_its_profile(x):
    rd = RangeDoppler(4, 8)
    res = _only(RangeDopplerError, rd, x)
    if res is not None:
        assert res.shape == (*x.shape[:-4], 8, 4, *x.shape[-3:-1]) and np.isfinite(res).all()
        assert count_nonfinite(x) == 0
    prof = _only(RangeDopplerError, rd.range_profiles, x)
    if prof is not None:
        assert prof.shape == x.shape and count_nonfinite(x) == 0
    cut = RangeDoppler(4, 8, n_range=3)
    res = _only(RangeDopplerError, cut.doppler, x)
    if res is not None:
        assert res.shape == (*x.shape[:-1], 3) and np.isfinite(res).all()


@given(arrays(max_ndim=3, fits=(None, 4, None)), arrays(max_ndim=2, fits=(4,)))
def test_doa_takes_finite_snapshots_and_positions(x, positions):
    res = _only(doa.DoaError, doa.doa_angles, x, positions, 1, 1, method="bartlett")
    if res is not None:
        assert np.asarray(res).shape[0] == (1 if x.ndim == 2 else x.shape[0])


@given(arrays(max_ndim=2, fits=(3,)), arrays(max_ndim=2, fits=(3,)))
def test_points_take_finite_values_and_nan_only_for_a_missing_angle(r, a):
    res = _only(points.PointError, points.to_cartesian, r, a)
    if res is not None:
        assert res[0].shape == r.shape == a.shape
        assert np.isfinite(r.astype(float)).all() and not np.isinf(a.astype(float)).any()
    d = r.shape[0] if r.ndim == 1 else 0
    res = _only(points.PointError, points.group_points, np.zeros(d, np.int64), r,
                np.ones(d), a, np.zeros(d), 0.1, 0.5)
    if res is not None:
        assert res["frame"].shape == res["x_m"].shape and res["frame"].size <= 1


@given(arrays(max_ndim=5, fits=(None, None, None, 6)), arrays(max_ndim=2, fits=(2,), kinds=("int",)))
def test_snapshots_take_complex_data_and_bins_within_it(rd, bins):
    res = _only(snapshots.SnapshotError, snapshots.cell_snapshots, rd, bins, bins)
    if res is not None:
        assert res.shape == (bins.size, *rd.shape[1:3], 9)
    res = _only(snapshots.SnapshotError, snapshots.chirp_snapshots, rd, bins)
    if res is not None:
        assert res.shape == (bins.size, *rd.shape[1:3], rd.shape[0])


@given(arrays(max_ndim=4, fits=(2, 2, None, None)), arrays(max_ndim=2, fits=(2,), kinds=("int",)))
def test_tdm_compensation_takes_finite_channels_and_bins(x, bins):
    res = _only(CompensationError, compensate_tdm, x, bins, 8, 1e-4, np.array([0.0, 3e-5]))
    if res is not None:
        assert res.shape == x.shape and np.isfinite(res).all()


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, complex(np.nan, 0.0)])
@pytest.mark.parametrize("cropped", [False, True])
def test_one_bad_sample_anywhere_in_a_frame_is_named(paper, bad, cropped):  # noqa: F811
    """The cheap finiteness check (one output bin per channel) sees a NaN/inf at any sample of
    any chirp, TX, RX, at full range (FFTW) and with a range window (scipy)."""
    radar, _, chain = paper
    rng = np.random.default_rng(7)
    rd = RangeDoppler(radar.n_chirps, radar.n_samples, n_range=100 if cropped else None)
    cube = np.zeros((2, radar.n_chirps, radar.n_tx, radar.n_rx, radar.n_samples), np.complex64)
    for _ in range(3):
        cube[:] = 0
        where = tuple(int(rng.integers(n)) for n in cube.shape)
        cube[where] = bad
        with pytest.raises(RangeDopplerError, match=r"cube must hold finite samples; found 1 "):
            rd.native(cube)
        with pytest.raises(RangeDopplerError, match=r"cube must hold finite samples; found 1 "):
            rd.range_profiles(cube)
        profiles = np.zeros_like(cube)  # a bad range bin the Doppler FFT uses (< n_range)
        profiles[where[:-1] + (int(rng.integers(rd.n_range or radar.n_samples)),)] = bad
        with pytest.raises(RangeDopplerError, match=r"range_profiles must hold finite samples; "
                                                    r"found 1 NaN/inf"):
            rd.doppler(profiles)
    if not cropped:
        with pytest.raises(RangeDopplerError, match=r"process_batch|cube must hold finite"):
            chain.process_batch(cube)


def test_chain_names_a_cube_of_another_profile(paper):  # noqa: F811
    radar, _, chain = paper
    cube = np.zeros((radar.n_chirps, radar.n_tx, radar.n_rx - 1, radar.n_samples), np.complex64)
    with pytest.raises(RangeDopplerError, match=rf"rx={radar.n_rx}.*found complex64 array of "
                                                rf"shape \(64, 12, 15, 256\)"):
        chain.process(cube)
    with pytest.raises(RangeDopplerError, match=r"cubes must be .*\(5 axes\)"):
        chain.process_batch(cube)
