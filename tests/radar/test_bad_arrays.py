"""The radar room's array functions refuse bad arrays with their module's own error.

Property-based (hypothesis), as ``tests/dsp/test_bad_arrays.py``: arrays of every element kind and
small shapes, NaN/inf planted at random, go to the occlusion geometry, the radar equation, the
simulator's quantiser and int16 codecs and the virtual array's ULA selection; only the documented
error comes out, and what is accepted has the documented shape.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given

from blindspot.radar import occlusion, radar_equation, simulator
from blindspot.radar.array import ArrayShapeError, ula_array
from tests.dsp._synth import mmwcas
from tests.dsp.test_bad_arrays import _only, arrays

RADAR, _ = mmwcas()


@given(arrays(max_ndim=3, fits=(None, 2)), arrays(max_ndim=2, fits=(4, 2)))
def test_occlusion_takes_finite_points_and_a_polygon(points, polygon):
    res = _only(occlusion.GeometryError, occlusion.segment_crosses_polygon, points, polygon)
    if res is not None:
        assert res.shape == points.shape[:-1] and res.dtype == bool
        assert polygon.shape[0] >= 3 and np.isfinite(points.astype(float)).all()
    res = _only(occlusion.GeometryError, occlusion.point_in_polygon, points, polygon)
    if res is not None:
        assert res.shape == points.shape[:-1]


@given(arrays(max_ndim=2, fits=(3,)), arrays(max_ndim=2, fits=(3,)))
def test_radar_equation_takes_finite_rcs_and_positive_ranges(rcs, rng_m):
    res = _only(radar_equation.RadarEquationError, radar_equation.received_power_w, RADAR, rcs,
                rng_m)
    if res is not None:
        assert np.shape(res) == np.broadcast_shapes(rcs.shape, rng_m.shape)
        assert np.isfinite(res).all() and (np.asarray(res) >= 0).all()


@given(arrays(fits=(None, 2), kinds=("int", "complex64", "float", "str")))
def test_adc_codecs_take_codes_or_integer_valued_samples(x):
    res = _only(simulator.SimulationError, simulator.quantise, x, 12)
    if res is not None:
        assert res.shape == x.shape and x.dtype == np.complex64
    codes = _only(simulator.SimulationError, simulator.to_int16_iq, x)
    if codes is not None:
        assert codes.shape == (*x.shape, 2) and codes.dtype == np.int16
        assert np.array_equal(simulator.from_int16_iq(codes), x.astype(np.complex64))
    back = _only(simulator.SimulationError, simulator.from_int16_iq, x)
    if back is not None:
        assert back.shape == x.shape[:-1] and x.dtype.kind in "iu"


@given(arrays(fits=(None, 2, 3, None)))
def test_ula_selection_takes_channels_of_the_array(x):
    array = ula_array(2, 3)
    res = _only(ArrayShapeError, array.ula_snapshots, x)
    if res is not None:
        assert res.shape == (*x.shape[:-3], array.n_ula, x.shape[-1])
