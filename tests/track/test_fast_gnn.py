"""The vectorised GNN step (blindspot.track.tracker._gnn_stage) against Stone Soup's
GNNWith2DAssignment with the gated hypothesiser (the reference path, ``_Parts.fast`` False):
the same tracks, ids and bytes on random scenes of movers, static objects and clutter, with and
without the Doppler gate, the Doppler-first initiation, the field of view and empty frames."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from blindspot.track import tracker as T
from tests.track.test_tracker import config


def _scene(seed: int, n_frames: int = 40) -> pd.DataFrame:
    """Points of a moving sensor passing static objects (a few points each), walkers and
    uniform clutter, with radial speeds, the sensor's pose and a few frames without points."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_frames) * 0.1
    sensor = np.column_stack([np.zeros(n_frames), 3.0 * t])           # driving along +y
    statics = rng.uniform([-6, 0], [6, 30], (rng.integers(10, 40), 2))
    walkers = [(rng.uniform(-5, 5, 2) + [0, 10], rng.normal(0, 1.2, 2))
               for _ in range(rng.integers(1, 4))]
    rows = []
    for f in range(n_frames):
        if rng.random() < 0.05:                                        # a frame without points
            rows.append((f, t[f], np.nan, np.nan, np.nan))
            continue
        objs = [(p, np.zeros(2)) for p in statics] + [(p0 + v * t[f], v) for p0, v in walkers]
        for p, v in objs:
            if rng.random() < 0.15:                                    # missed this frame
                continue
            for _ in range(rng.integers(1, 4)):
                q = p + rng.normal(0, 0.1, 2)
                los = q - sensor[f]
                u = los / max(np.hypot(*los), 1e-9)
                rows.append((f, t[f], q[0], q[1], float(u @ v) + rng.normal(0, 0.2)))
        for q in rng.uniform([-8, 0], [8, 35], (rng.integers(0, 6), 2)):
            rows.append((f, t[f], q[0], q[1], rng.normal(0, 2.0)))
    df = pd.DataFrame(rows, columns=["frame", "time_s", "x_m", "y_m",
                                     "velocity_over_ground_mps"])
    df["sensor_x_m"] = sensor[df.frame, 0]
    df["sensor_y_m"] = sensor[df.frame, 1]
    df["sensor_heading_deg"] = 0.0
    return df


def _both(points: pd.DataFrame, cfg) -> tuple[pd.DataFrame, pd.DataFrame]:
    fast = T.track_points(points, cfg)
    make = T._parts
    try:
        T._parts = lambda c: dataclasses.replace(make(c), fast=False)
        ref = T.track_points(points, cfg)
    finally:
        T._parts = make
    return fast, ref


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("changes", [
    {},
    {"doppler_std_mps": 0.3},
    {"doppler_std_mps": 0.3, "init_doppler_std_mps": 0.3, "init_doppler_along_std_mps": 0.3,
     "field_of_view_deg": 120.0},
    {"confirm_m": 1, "max_misses": 2},
    {"doppler_std_mps": 0.3, "priority_max_coast_frames": 1},
    {"priority_max_coast_frames": None},
])
def test_the_vectorised_gnn_step_gives_stone_soups_tracks(seed, changes):
    cfg = config("gnn_cv", **changes)
    fast, ref = _both(_scene(seed), cfg)
    assert len(ref) > 100 and ref.track_id.nunique() > 10      # the scene exercises the tracker
    pd.testing.assert_frame_equal(fast, ref, check_exact=True)


def test_the_reference_path_is_stone_soups_objects():
    """The switch is real: the reference path keeps Stone Soup tracks, the fast one does not."""
    seen = []
    state = T._state_arrays

    def spy(track):
        seen.append(type(track).__name__)
        return state(track)
    T._state_arrays = spy
    try:
        _both(_scene(0, 12), config("gnn_cv"))
    finally:
        T._state_arrays = state
    assert {"_Track", "Track"} <= set(seen)
