"""blindspot.traj.windows.choose_windows: the deterministic choice of the rollout cases."""

import numpy as np
import pandas as pd
import pytest

from blindspot.traj.windows import WindowSet, choose_windows


def _split(path_ids, starts, window=5):
    n = len(path_ids)
    return WindowSet(np.zeros((n, window, 2)), np.zeros((n, 2)), np.array(path_ids),
                     np.array(starts))


MOTION = pd.Series({1: "approaching", 2: "receding", 3: "approaching", 4: "perpendicular"})
N_POINTS = pd.Series({1: 20, 2: 20, 3: 20, 4: 20})


def test_test_split_first_lowest_id_then_validation():
    splits = {"test": _split([3, 3, 2], [0, 4, 1]), "val": _split([1, 4], [2, 0])}
    got = choose_windows(splits, MOTION, N_POINTS, [("approaching", 2), ("perpendicular", 1)], 10)
    assert got == [("approaching", "test", 3, 0), ("approaching", "val", 1, 2),
                   ("perpendicular", "val", 4, 0)]


def test_few_paths_reuse_the_latest_window_leaving_room():
    # path 2 has 20 points, window 5, horizon 10: a start must be <= 5
    splits = {"test": _split([2, 2, 2, 2], [0, 3, 5, 9])}
    got = choose_windows(splits, MOTION, N_POINTS, [("receding", 3)], 10)
    assert got == [("receding", "test", 2, 0), ("receding", "test", 2, 5),
                   ("receding", "test", 2, 3)]


def test_missing_motion_or_room_or_starts_raise():
    splits = {"test": _split([2], [0])}
    with pytest.raises(ValueError, match="no perpendicular path"):
        choose_windows(splits, MOTION, N_POINTS, [("perpendicular", 1)], 10)
    with pytest.raises(ValueError, match="no window leaving room"):
        choose_windows({"test": _split([2], [12])}, MOTION, N_POINTS, [("receding", 1)], 10)
    no_starts = WindowSet(np.zeros((1, 5, 2)), np.zeros((1, 2)), np.array([2]))
    with pytest.raises(ValueError, match="no window start"):
        choose_windows({"val": no_starts}, MOTION, N_POINTS, [("receding", 1)], 10)
