"""Batch-native detection steps: CFAR over a batch of maps, the peak rule, order and budget."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from blindspot.dsp.cfar import cfar_2d, os_cfar_2d
from blindspot.dsp.detections import (
    DetectionError, detection_order, local_maxima, local_maxima_at, rank_in_frame,
)


@pytest.mark.parametrize("kwargs", [dict(pfa=1e-3), dict(scale=1.18, domain="db"),
                                    dict(pfa=1e-3, mode="go"), dict(scale=4.0, mode="so")])
def test_cfar_on_a_batch_equals_cfar_map_by_map(kwargs):
    """Leading axes are independent maps: the batch gives, bit for bit, each map's own result
    (the dB floor and the integral image are per map)."""
    rng = np.random.default_rng(0)
    maps = rng.exponential(1.0, (3, 40, 32)) * np.array([1.0, 1e3, 1e6])[:, None, None]
    maps[1, 10, 5] = 0.0
    res = cfar_2d(maps, (1, 1), (4, 3), **kwargs)
    for i in range(3):
        one = cfar_2d(maps[i], (1, 1), (4, 3), **kwargs)
        np.testing.assert_array_equal(res.mask[i], one.mask)
        np.testing.assert_array_equal(res.threshold[i], one.threshold)
        np.testing.assert_array_equal(res.noise[i], one.noise)


def test_os_cfar_on_a_batch_equals_os_cfar_map_by_map():
    rng = np.random.default_rng(1)
    maps = rng.exponential(1.0, (2, 30, 16))
    mask, thr = os_cfar_2d(maps, (1, 1), (3, 2), pfa=1e-3)
    for i in range(2):
        m1, t1 = os_cfar_2d(maps[i], (1, 1), (3, 2), pfa=1e-3)
        np.testing.assert_array_equal(mask[i], m1)
        np.testing.assert_array_equal(thr[i], t1)


def test_local_maxima_rule_and_edges():
    p = np.zeros((1, 5, 4))
    p[0, 2, 0] = 3.0       # a peak whose Doppler neighbour wraps to column 3
    p[0, 2, 3] = 2.0
    p[0, 0, 1] = 1.0       # a peak on the first range bin (beyond the edge counts as -inf)
    got = local_maxima(p)
    assert got[0, 2, 0] and got[0, 0, 1] and not got[0, 2, 3]
    # a row outside the map never wins and never beats a neighbour
    rows = np.array([[True, True, True, True, False]])
    q = p.copy()
    q[0, 4, 2] = 99.0
    got = local_maxima(q, rows)
    assert not got[0, 4].any() and got[0, 2, 0]
    with pytest.raises(ValueError, match="row_exists"):
        local_maxima(q, rows[:, :3])


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), rows=st.integers(1, 7), cols=st.integers(1, 6),
       levels=st.integers(1, 4))
def test_local_maxima_at_equals_the_whole_map_rule(seed, rows, cols, levels):
    """The chain's rule on its CFAR cells only gives, cell for cell, the whole-map rule: edges
    (first and last range row), the wrapped Doppler columns and ties (few distinct levels make
    plateaus, which count as maxima) included."""
    rng = np.random.default_rng(seed)
    p = rng.integers(0, levels, (2, rows, cols)).astype(np.float64)
    f, r, c = (a.ravel() for a in np.indices(p.shape))
    np.testing.assert_array_equal(local_maxima_at(p, f, r, c), local_maxima(p)[f, r, c])
    with pytest.raises(DetectionError, match="local_maxima_at: row"):
        local_maxima_at(p, f, r + 0.5, c)


def test_order_and_budget_per_frame():
    frame = np.array([1, 0, 1, 0, 1, 1])
    power = np.array([5.0, 1.0, 9.0, 2.0, 1.0, 7.0])
    mov = np.array([False, False, True, True, True, False])
    order = detection_order(frame, power, mov)
    # frame 0: the moving one first; frame 1: moving (9, then 1), then static (7, then 5)
    np.testing.assert_array_equal(order, [3, 1, 2, 4, 5, 0])
    np.testing.assert_array_equal(rank_in_frame(frame[order]), [0, 1, 0, 1, 2, 3])
    with pytest.raises(ValueError, match="sorted by frame"):
        rank_in_frame(frame)
