"""Windows against a naive loop, NaN handling, gap interpolation, leak-free splits, Parquet I/O."""

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from blindspot.traj.windows import (
    WindowError,
    WindowSet,
    interpolate_gaps,
    last_point_measured,
    make_windows,
    paths_needed,
    split_by_path,
    windows_per_path,
)


def naive_windows(paths, window, stride):
    xs, ys, ids, starts = [], [], [], []
    for p in range(paths.shape[0]):
        for s in range(0, paths.shape[1] - window, stride):
            xs.append(paths[p, s : s + window])
            ys.append(paths[p, s + window])
            ids.append(p)
            starts.append(s)
    return np.array(xs, np.float32), np.array(ys, np.float32), np.array(ids), np.array(starts)


@pytest.mark.parametrize(("window", "stride"), [(1, 1), (4, 1), (4, 3), (7, 2), (10, 5)])
def test_matches_naive_reference(window, stride):
    paths = np.random.default_rng(0).normal(size=(3, 23, 2))
    ws = make_windows(paths, window, stride)
    x, y, ids, starts = naive_windows(paths, window, stride)
    assert ws.x.shape == (len(x), window, 2) and ws.x.dtype == np.float32 and ws.y.dtype == np.float32
    np.testing.assert_array_equal(ws.x, x)
    np.testing.assert_array_equal(ws.y, y)
    np.testing.assert_array_equal(ws.path_id, ids)
    np.testing.assert_array_equal(ws.start, starts)
    assert len(ws) == 3 * windows_per_path(23, window, stride)


def test_paper_numbers():
    assert windows_per_path(200, 50) == 150
    assert len(make_windows(np.zeros((2, 200, 2)), 50)) == 300
    # whole paths per split at stride 1: ceil(20000/150) + ceil(4000/150) + ceil(500/150)
    assert paths_needed((20000, 4000, 500), 200, 50) == 134 + 27 + 4
    assert paths_needed((20000, 4000, 500), 200, 50, stride=5) == 667 + 134 + 17


def test_nan_windows_dropped_or_refused():
    paths = np.arange(2 * 12 * 2, dtype=float).reshape(2, 12, 2)
    paths[0, 5] = np.nan
    ws = make_windows(paths, 3)
    # path 0: windows (start s covers points s..s+3) touching point 5 are s = 2..5
    np.testing.assert_array_equal(ws.start[ws.path_id == 0], [0, 1, 6, 7, 8])
    np.testing.assert_array_equal(ws.start[ws.path_id == 1], np.arange(9))
    assert np.isfinite(ws.x).all()
    with pytest.raises(ValueError, match="path 0, start 2"):
        make_windows(paths, 3, nan_policy="raise")


@pytest.mark.parametrize(
    ("args", "match"),
    [
        ((np.zeros((5, 2)), 2), r"\(P, T, 2\)"),
        ((np.zeros((1, 5, 3)), 2), r"\(P, T, 2\)"),
        ((np.zeros((1, 5, 2)), 5), "needs 6"),
        ((np.zeros((1, 5, 2)), 0), "window"),
        ((np.zeros((1, 5, 2)), 2, 0), "stride"),
        ((np.zeros((1, 5, 2)), 2, 1, "prev"), "target"),
    ],
)
def test_bad_input_errors(args, match):
    with pytest.raises(ValueError, match=match):
        make_windows(*args)


def test_windowset_validates_shapes():
    with pytest.raises(ValueError, match="WindowSet.y"):
        WindowSet(np.zeros((3, 4, 2)), np.zeros((2, 2)), np.zeros(3))
    with pytest.raises(ValueError, match="WindowSet.path_id"):
        WindowSet(np.zeros((3, 4, 2)), np.zeros((3, 2)), np.zeros(4))


def test_interpolate_gaps_is_exact_on_straight_lines():
    t = np.arange(20.0)
    line = np.stack([1.0 + 0.3 * t, 2.0 - 0.1 * t], axis=-1)
    paths = np.stack([line, 2 * line])
    gappy = paths.copy()
    gappy[0, [0, 1, 5, 6, 7, 19]] = np.nan
    gappy[1, 10, 0] = np.nan  # one NaN coordinate makes the whole row missing
    out = interpolate_gaps(gappy)
    np.testing.assert_allclose(out[0, 2:19], paths[0, 2:19], rtol=1e-12)
    np.testing.assert_allclose(out[1], paths[1], rtol=1e-12)
    assert np.isnan(out[0, [0, 1, 19]]).all()  # edges are not extrapolated
    np.testing.assert_allclose(interpolate_gaps(gappy[1]), paths[1], rtol=1e-12)


def test_windows_ending_in_a_filled_gap_are_flagged():
    """After the whole path's fill, a window whose last input was a miss holds a point drawn
    toward its own target; the kept windows equal a fill of the path up to their end alone."""
    rng = np.random.default_rng(1)
    measured = rng.normal(size=(3, 40, 2)).cumsum(axis=1)
    measured[rng.random((3, 40)) < 0.25] = np.nan
    measured[1, 14] = np.nan                     # window at start 10 ends in a miss
    measured[1, [15, 16]] = [[1.0, 2.0], [3.0, 4.0]]
    ws = make_windows(interpolate_gaps(measured), 5)
    ok = last_point_measured(ws, measured)
    at = np.flatnonzero((ws.path_id == 1) & (ws.start == 10))
    assert at.size == 1 and not ok[at[0]]
    assert ok.any() and not ok.all()
    for i in np.flatnonzero(ok):
        p, s = ws.path_id[i], ws.start[i]
        np.testing.assert_array_equal(ws.x[i], interpolate_gaps(measured[p, :s + 5])[s:]
                                      .astype(np.float32))
    for i in np.flatnonzero(~ok):
        assert np.isnan(measured[ws.path_id[i], ws.start[i] + 4]).any()
    with pytest.raises(WindowError, match="measured has shape"):
        last_point_measured(ws, measured[:, :20])
    with pytest.raises(WindowError, match="no start index"):
        last_point_measured(WindowSet(ws.x, ws.y, ws.path_id), measured)


def _windows_from(n_paths, n_points=60, window=10, seed=0):
    paths = np.random.default_rng(seed).normal(size=(n_paths, n_points, 2))
    return make_windows(paths, window)  # 50 windows per path


def test_split_counts_exact_and_no_path_leak():
    ws = _windows_from(40)
    parts = split_by_path(ws, (700, 300, 120), seed=4)
    assert [len(p) for p in parts] == [700, 300, 120]
    ids = [set(p.path_id.tolist()) for p in parts]
    assert not (ids[0] & ids[1]) and not (ids[0] & ids[2]) and not (ids[1] & ids[2])
    # each split uses the fewest whole paths that cover it
    assert [len(s) for s in ids] == [14, 6, 3]
    for p in parts:  # windows are genuine rows of ws, kept in order
        assert (np.diff(p.path_id * 1000 + p.start) > 0).all()
    again = split_by_path(ws, (700, 300, 120), seed=4)
    for a, b in zip(parts, again, strict=True):
        np.testing.assert_array_equal(a.x, b.x)
    other = split_by_path(ws, (700, 300, 120), seed=5)
    assert not np.array_equal(other[0].path_id, parts[0].path_id)


def test_split_paper_counts_with_exact_path_count():
    ws = make_windows(np.zeros((165, 200, 2)), 50)
    parts = split_by_path(ws, (20000, 4000, 500), seed=0)
    assert [len(p) for p in parts] == [20000, 4000, 500]
    short = make_windows(np.zeros((164, 200, 2)), 50)
    with pytest.raises(ValueError, match="generate more paths"):
        split_by_path(short, (20000, 4000, 500), seed=0)


def test_save_load_round_trip(tmp_path):
    ws = _windows_from(3)
    path = ws.save(tmp_path / "sub" / "w.parquet")
    back = WindowSet.load(path)
    for name in ("x", "y", "path_id", "start"):
        np.testing.assert_array_equal(getattr(back, name), getattr(ws, name))
    assert back.window == 10
    assert [p.name for p in path.parent.iterdir()] == ["w.parquet"]  # no temp file left behind
    no_start = WindowSet(ws.x[:4], ws.y[:4], ws.path_id[:4])
    assert WindowSet.load(no_start.save(tmp_path / "n.parquet")).start is None


def test_load_rejects_other_parquet(tmp_path):
    bad = tmp_path / "other.parquet"
    pq.write_table(pa.table({"a": [1, 2]}), bad)
    with pytest.raises(ValueError, match="other.parquet"):
        WindowSet.load(bad)


def test_futures_are_the_points_after_each_window_in_its_path():
    rng = np.random.default_rng(3)
    paths = rng.normal(size=(3, 30, 2)).cumsum(axis=1)
    ws = make_windows(paths, 5, path_ids=np.array([7, 8, 9]))
    keep = rng.permutation(len(ws))[: len(ws) // 2]      # a random half, as a split keeps
    sub = ws.subset(np.sort(keep))
    index, future = sub.futures(4)
    assert len(index) > 0
    pid = sub.path_id[index] - 7
    start = sub.start[index]
    want = paths[pid[:, None], start[:, None] + 5 + np.arange(4)]
    np.testing.assert_array_equal(future, want.astype(np.float32))
    # every window left out lacks a future point the subset holds
    every, _ = ws.futures(4)
    assert len(every) == 3 * (30 - 5 - 4 + 1)  # starts 0..21 of each path: points s+5..s+8 <= 29
    with pytest.raises(WindowError, match="start"):
        WindowSet(ws.x, ws.y, ws.path_id).futures(2)
    with pytest.raises(WindowError, match="horizon"):
        ws.futures(0)
