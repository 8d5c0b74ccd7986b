"""ETH/UCY loaders say what they left out and why (issue 9, items 4 and 5): another frame step
is refused with the numbers that show it, an empty split says why, defective rows are refused
or dropped with one warning per file, protocol exclusions are counted in a SkipReport."""

import warnings

import numpy as np
import pytest

from blindspot.traj.ethucy import (
    FOLDS,
    FRAME_STEP,
    SPLITS,
    EthUcyDataError,
    EthUcySkipWarning,
    infer_frame_step,
    load_split,
    read_scene,
    scene_tracks,
    sliding_windows,
    split_files,
)


def write_split(root, rows, name="crowds_zara01.txt", fold="zara1", split="test"):
    folder = root / fold / split
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text("\n".join("\t".join(f"{v:g}" for v in r) for r in rows) + "\n")
    return path


def walk(frames, peds, step=10):
    """Rows of pedestrians walking along x, present in every one of ``frames`` grid frames."""
    return [(step * k, p, 0.5 * k + p, float(p)) for k in frames for p in peds]


def test_a_scene_on_frame_step_20_is_refused_with_the_numbers(tmp_path):
    """The c22 case (Trajectron++ issue 67): every frame id on the step-10 grid, but each
    pedestrian only every other grid frame. It used to give 0 windows and no warning."""
    path = write_split(tmp_path, walk(range(60), (1, 2, 3), step=20))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(EthUcyDataError) as err:
            load_split(tmp_path, "zara1", "test")
    msg = str(err.value)
    assert str(path) in msg
    assert "step by 20, not the declared 10" in msg
    assert "177 of 177 consecutive-frame pairs of 3 of 3 pedestrians" in msg
    # read on purpose at its own step: 3 pedestrians x (60 - 20 + 1) starts
    assert len(load_split(tmp_path, "zara1", "test", frame_step=20)) == 123


def test_frame_step_inference_is_robust_to_gaps():
    rows = np.array(walk(range(40), (1, 2)), float)
    keep = ~((rows[:, 1] == 1) & np.isin(rows[:, 0], [100, 110, 120, 300]))   # gaps of 2 and 1
    assert infer_frame_step(rows[keep])[:2] == (10, 2)
    assert infer_frame_step(np.array([[0, 1, 0, 0], [0, 2, 1, 1]], float))[0] is None


def test_an_empty_split_says_why(tmp_path):
    # two files of step-10 tracks of 12 frames: no 20-frame window anywhere
    write_split(tmp_path, walk(range(12), (1, 2)), name="a.txt")
    write_split(tmp_path, walk(range(5), (4, 5, 6)), name="b.txt")
    with pytest.raises(EthUcyDataError) as err:
        load_split(tmp_path, "zara1", "test")
    msg = str(err.value)
    assert "no window of 20 consecutive frames" in msg and "2 files" in msg
    assert "a.txt: 2 tracks, longest 12 consecutive frames (a window needs 20)" in msg
    assert "b.txt: 3 tracks, longest 5 consecutive frames" in msg


def test_defective_rows_are_refused_by_default_and_dropped_with_one_warning(tmp_path):
    rows = walk(range(25), (1, 2))
    rows += [(30, 1, float("nan"), 0.0), (40, 2, 1.0, float("nan")),     # NaN rows
             (50, 1, 9.0, 9.0), (60, 2, 9.0, 9.0), (60, 2, 8.0, 8.0),    # repeated pairs
             (75, 1, 0.0, 0.0), (85, 2, 0.0, 0.0)]                       # off the grid
    path = write_split(tmp_path, rows)
    with pytest.raises(EthUcyDataError, match=r"2 of 57 data rows hold a non-finite value"):
        read_scene(path)
    dup = write_split(tmp_path, walk(range(3), (1,)) + [(10, 1, 5.0, 5.0)], fold="eth")
    with pytest.raises(EthUcyDataError, match=r"frame 10 lists pedestrian 1 twice \(1 repeated"):
        read_scene(dup)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        w = load_split(tmp_path, "zara1", "test", bad_rows="skip")
    skip = [str(c.message) for c in caught if issubclass(c.category, EthUcySkipWarning)]
    assert skip == [f"{path}: dropped 2 rows with a non-finite value, 3 repeated (frame, "
                    f"pedestrian) rows, 2 rows with a frame id off the grid of 57 rows"]
    report = w.skipped[0]
    assert (report.rows, report.nan_rows, report.duplicate_rows, report.off_grid_rows) == (
        57, 2, 3, 2)
    # the first row of a repeated pair is kept: frame 50 of pedestrian 1 is (0.5 * 5 + 1, 1)
    with pytest.warns(EthUcySkipWarning, match="2 rows with a non-finite value"):
        rows_kept = read_scene(path, bad_rows="skip")
    with pytest.warns(EthUcySkipWarning, match="2 rows with a frame id off the grid of 52 rows"):
        tracks = scene_tracks(rows_kept, source=str(path), bad_rows="skip")
    np.testing.assert_array_equal(tracks.xy[0, 5], [3.5, 1.0])
    # the off-grid rows alone, through scene_tracks
    with pytest.raises(EthUcyDataError, match=r"frame id 75 is not on the grid.*2 of"):
        scene_tracks(np.array([r for r in rows if np.isfinite(r[2:]).all() and r[0] not in
                               (50, 60)], float), source="s")


def test_protocol_exclusions_are_counted_per_file(tmp_path):
    # ped 1: frames 0..24 (6 windows); ped 2: 0..19 with frame 12 missing (gap, too short);
    # ped 3: 30..54 alone (a full run but never a neighbour); ped 4: 0..4 (too short)
    rows = [(10 * f, 1, f, 1) for f in range(25)]
    rows += [(10 * f, 2, f, 2) for f in range(20) if f != 12]
    rows += [(10 * f, 3, f, 3) for f in range(30, 55)]
    rows += [(10 * f, 4, f, 4) for f in range(5)]
    tracks = scene_tracks(np.array(rows, float), source="s.txt")
    xy, ped, start, report = sliding_windows(tracks, 20, min_peds=1, report=True)
    assert (report.pedestrians, report.windows, report.longest_track) == (4, 12, 25)
    assert (report.peds_with_gaps, report.peds_too_short, report.peds_without_neighbour) == (
        1, 2, 0)
    _, _, _, report = sliding_windows(tracks, 20, min_peds=2, report=True)
    assert (report.windows, report.peds_too_short, report.peds_without_neighbour) == (0, 2, 2)
    assert "4 tracks, longest 25 consecutive frames (a window needs 20); 0 windows" in (
        report.summary())
    with pytest.raises(EthUcyDataError, match="seq_len: expected an integer >= 1"):
        sliding_windows(tracks, 0)


@pytest.mark.real_data
def test_every_real_benchmark_file_loads_unchanged_without_a_warning(shared_dir):
    data = shared_dir / "data" / "ethucy"
    if not (data / "eth" / "test").is_dir():
        pytest.skip(f"ETH/UCY data not found at {data}")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for fold in FOLDS:
            for split in SPLITS:
                w = load_split(data, fold, split)
                assert len(w) > 0 and len(w.skipped) == len(w.files)
                assert sum(r.windows for r in w.skipped) == len(w)
                for r in w.skipped:
                    assert r.nan_rows == r.duplicate_rows == r.off_grid_rows == 0
        for path in split_files(data, "eth", "train") + split_files(data, "eth", "test"):
            assert infer_frame_step(read_scene(path))[0] == FRAME_STEP


# --- absurd values refused before any allocation (issue 45; case t3_c11) ---------------------
from hypothesis import given, settings, strategies as st  # noqa: E402

from blindspot.traj.ethucy import MAX_GRID_CELLS, MAX_ID  # noqa: E402


@settings(max_examples=20, deadline=None)
@given(bad=st.one_of(st.floats(MAX_ID + 1, 1e300), st.floats(-1e300, -1.0),
                     st.floats(0.01, 0.99).map(lambda f: 130 + f)),
       row=st.integers(0, 119), column=st.sampled_from([0, 1]))
def test_a_corrupted_id_is_the_loaders_error_naming_the_file_and_row(tmp_path_factory, bad, row,
                                                                      column):
    # t3_c11: frame id 1e15 made scene_tracks allocate a (3, 1e14, 2) grid (4.26 PiB)
    rows = [list(r) for r in walk(range(40), [1, 2, 3])]
    rows[row][column] = bad
    path = tmp_path_factory.mktemp("c11") / "scene.txt"
    path.write_text("".join("%r\t%r\t%r\t%r\n" % tuple(r) for r in rows))
    with pytest.raises(EthUcyDataError, match=rf"{path}: data row {row + 1}: .*whole numbers"):
        read_scene(path)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        kept = read_scene(path, bad_rows="skip")
    assert len(kept) == 119 and "frame or pedestrian id" in str(seen[0].message)


def test_a_stray_frame_id_within_the_id_range_is_refused_before_the_grid():
    rows = np.array(walk(range(40), [1, 2, 3]), float)
    rows[5, 0] = 10.0 * (MAX_GRID_CELLS // 3 + 10)      # on the grid, in range, absurdly far
    with pytest.raises(EthUcyDataError, match=r"scene.txt: frame ids span .* farthest .* row 5 "):
        scene_tracks(rows, source="scene.txt")
    rows[5, 0] = 1e15                                    # arrays from elsewhere: the id rule
    with pytest.raises(EthUcyDataError, match=r"scene.txt: row 5: frame 1e\+15"):
        scene_tracks(rows, source="scene.txt")
