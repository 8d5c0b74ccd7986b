"""The static-environment evidence grid (blindspot.track.moving.static_evidence) on the
geometry of a parked car passed by the ego car: a cluster sliding along the car's face stays on
the car's past static hits, a child stepping out of a gap and walking into the lane leaves them,
and the count is causal (later points never change it)."""

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from blindspot.track.moving import static_evidence

FRAMES = np.arange(40)


def _car_face_points(x_face=2.0, y0=0.0, length=4.5, step=0.3):
    """The lane-side face of a car parked from y0 to y0 + length, hit every frame at points
    every ``step`` m along the part visible to an ego car approaching from -y: the face's
    near end is seen first, more of it as the ego gets closer (the visible part changes)."""
    rows = []
    ys = np.arange(y0, y0 + length + 1e-9, step)
    for f in FRAMES:
        visible = ys[: 1 + min(len(ys) - 1, f // 3)]
        rows.append(pd.DataFrame({"scene": "s", "frame": f, "x_m": x_face, "y_m": visible,
                                  "static": True}))
    return pd.concat(rows, ignore_index=True)


def _track(xs, ys, frames):
    return pd.DataFrame({"group": "s", "frame": frames, "x_m": xs, "y_m": ys})


def test_cluster_sliding_along_a_parked_car_face_stays_on_static_evidence():
    pts = _car_face_points()
    f = np.arange(10, 40)
    slide = _track(np.full(len(f), 2.0), 0.1 * (f - 10), f)     # 1 m/s along the face
    ev = static_evidence(slide, pts, cell_m=0.5, lag_frames=10)
    assert (ev >= 1).all()


def test_child_stepping_out_of_a_gap_into_the_lane_leaves_the_evidence():
    # two cars parked at x = 2 (lane-side faces), a 1.5 m gap between y = 4.5 and y = 6
    pts = pd.concat([_car_face_points(), _car_face_points(y0=6.0)], ignore_index=True)
    f = np.arange(20, 40)
    x = 3.0 - 0.14 * (f - 20)              # 1.4 m/s (Euro NCAP child, 5 km/h) towards -x
    child = _track(x, np.full(len(f), 5.25), f)
    # its own points look static too (a tangential crossing has ~0 radial speed): worst case
    own = pd.DataFrame({"scene": "s", "frame": f, "x_m": x, "y_m": 5.25, "static": True})
    ev = static_evidence(child, pd.concat([pts, own], ignore_index=True), cell_m=0.5,
                         lag_frames=10)
    # in the gap (x > 2.5) and in the lane once 1 m past the faces: no static evidence
    assert (ev[x > 2.5] == 0).all()
    assert (ev[x < 1.0] == 0).all()
    assert (ev[x < 1.0]).size >= 5         # the child is a moving object within 8 frames


def test_count_is_causal_and_lagged():
    pts = _car_face_points()
    row = _track([2.0], [0.0], [20])
    base = static_evidence(row, pts, cell_m=0.5, lag_frames=5)
    # frames 16.. are not yet evidence at frame 20 with a 5-frame lag
    assert static_evidence(row, pts[pts.frame <= 15], cell_m=0.5, lag_frames=5)[0] == base[0]
    assert static_evidence(row, pts[pts.frame <= 14], cell_m=0.5, lag_frames=5)[0] < base[0]
    # every hit of frames 0..15 closer than one cell in both axes counts, none two cells away
    early = pts[pts.frame <= 15]
    d = np.maximum(np.abs(early.x_m - 2.0), np.abs(early.y_m))
    assert (d < 0.5).sum() <= base[0] <= (d < 1.0).sum()
    assert (d < 0.5).sum() > 0


def test_a_later_or_foreign_point_does_not_move_an_earlier_count():
    """Causality of the grid itself: a point of a later frame or of another scene, anywhere
    (here far below every other coordinate), changes no row's count; a NaN point is ignored."""
    pts = _car_face_points()
    rows = _track([2.0, 2.2, 1.9], [0.0, 1.1, 2.4], [20, 21, 22])
    base = static_evidence(rows, pts, cell_m=0.5, lag_frames=5)
    for extra in ({"scene": "s", "frame": 30, "x_m": -57.3, "y_m": -91.7, "static": True},
                  {"scene": "other", "frame": 1, "x_m": -13.1, "y_m": -0.26, "static": True},
                  {"scene": "s", "frame": 1, "x_m": np.nan, "y_m": 0.0, "static": True}):
        more = pd.concat([pts, pd.DataFrame([extra])], ignore_index=True)
        np.testing.assert_array_equal(static_evidence(rows, more, cell_m=0.5, lag_frames=5),
                                      base)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**31 - 1), st.floats(0.2, 2.0), st.integers(1, 8))
def test_matches_the_direct_count_over_cells(seed, cell, lag):
    rng = np.random.default_rng(seed)
    n = 60
    pts = pd.DataFrame({"scene": rng.choice(["a", "b"], n), "frame": rng.integers(0, 20, n),
                        "x_m": rng.uniform(-3, 3, n), "y_m": rng.uniform(-3, 3, n),
                        "static": rng.random(n) < 0.7})
    tr = pd.DataFrame({"group": rng.choice(["a", "b"], 15), "frame": rng.integers(0, 20, 15),
                       "x_m": rng.uniform(-3, 3, 15), "y_m": rng.uniform(-3, 3, 15)})
    got = static_evidence(tr, pts, cell_m=cell, lag_frames=lag)
    s = pts[pts.static]
    cx = lambda v: np.floor(v / cell)                   # noqa: E731  the fixed world grid
    cy = cx
    want = np.array([((s.scene == r.group) & (s.frame <= r.frame - lag)
                      & (np.abs(cx(s.x_m) - cx(r.x_m)) <= 1)
                      & (np.abs(cy(s.y_m) - cy(r.y_m)) <= 1)).sum() for r in tr.itertuples()])
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("kw, key", [({"cell_m": 0.0, "lag_frames": 1}, "cell_m"),
                                     ({"cell_m": 0.5, "lag_frames": 0}, "lag_frames")])
def test_bad_settings_are_named(kw, key):
    with pytest.raises(ValueError, match=key):
        static_evidence(_track([0.0], [0.0], [1]), _car_face_points(), **kw)


def test_missing_column_is_named():
    with pytest.raises(ValueError, match="static"):
        static_evidence(_track([0.0], [0.0], [1]),
                        _car_face_points().drop(columns="static"), cell_m=0.5, lag_frames=1)
