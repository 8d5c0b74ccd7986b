"""Snapshots gathered for chosen array elements only are the same numbers as the whole
neighbourhood's, picked afterwards (the chain gathers the 86 ULA elements, not all 192)."""

from __future__ import annotations

import numpy as np
import pytest

from blindspot.dsp.snapshots import SnapshotError, cell_snapshots


def test_elements_gather_equals_picking_from_all_channels():
    rng = np.random.default_rng(0)
    rd = rng.normal(size=(2, 16, 3, 4, 20)) + 1j * rng.normal(size=(2, 16, 3, 4, 20))
    # range edges (0, 19: clipped) and Doppler edges (0, 15: wrapped) included
    rb, db, fr = np.array([0, 5, 19, 7]), np.array([0, 15, 3, 8]), np.array([0, 1, 1, 0])
    tx, rx = np.array([0, 2, 1, 1]), np.array([3, 0, 2, 2])  # a repeated element too
    whole = cell_snapshots(rd, rb, db, (1, 2), frame=fr)
    some = cell_snapshots(rd, rb, db, (1, 2), frame=fr, elements=(tx, rx))
    assert some.shape == (4, 4, 15)
    np.testing.assert_array_equal(some, whole[:, tx, rx])
    one = cell_snapshots(rd[1], rb, db, elements=(tx, rx))
    np.testing.assert_array_equal(one, cell_snapshots(rd[1], rb, db)[:, tx, rx])
    with pytest.raises(SnapshotError, match="elements must be"):
        cell_snapshots(rd, rb, db, frame=fr, elements=(tx, rx + 3))
    with pytest.raises(SnapshotError, match=r"elements\[0\]"):
        cell_snapshots(rd, rb, db, frame=fr, elements=(tx - 1, rx))
