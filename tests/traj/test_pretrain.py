"""ETH/UCY windows at the radar's frame rate: the spline passes through the annotations and
keeps constant-velocity walks exact; every window start of a track appears once; bad periods are
refused by name."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from blindspot.traj.ethucy import EthUcyDataError
from blindspot.traj.pretrain import (
    catmull_rom_resample,
    ethucy_next_point_windows,
    ethucy_sequences,
    stretch_length,
    radar_point_errors,
    with_point_errors,
    upsampling_factor,
)


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 6), st.integers(2, 9), st.integers(0, 2**31 - 1))
def test_spline_through_the_knots_and_exact_on_straight_walks(factor, length, seed):
    rng = np.random.default_rng(seed)
    xy = rng.normal(size=(3, length, 2))
    fine = catmull_rom_resample(xy, factor)
    assert fine.shape == (3, (length - 1) * factor + 1, 2)
    np.testing.assert_allclose(fine[:, ::factor], xy, atol=1e-12)
    # a walker at constant velocity stays on the line with evenly spaced points
    v = rng.normal(size=2)
    line = xy[:1, :1] + v * np.arange(length)[None, :, None]
    np.testing.assert_allclose(catmull_rom_resample(line, factor),
                               xy[:1, :1] + v * (np.arange(fine.shape[1]) / factor)[None, :, None],
                               atol=1e-9)


def test_spline_follows_a_turn_better_than_straight_segments():
    """On a walker going round a circle (radius 3 m, 0.4 s knots at 1.3 m/s) the cubic stays
    much nearer the circle between knots than linear interpolation (chord sagitta)."""
    r, w = 3.0, 1.3 / 3.0
    t = 0.4 * np.arange(12)
    xy = r * np.stack([np.cos(w * t), np.sin(w * t)], axis=-1)[None]
    fine = catmull_rom_resample(xy, 4)[0, 4:-4]          # interior periods (central tangents)
    off_circle = np.abs(np.linalg.norm(fine, axis=-1) - r).max()
    sagitta = r * (1 - np.cos(w * 0.4 / 2))
    assert off_circle < 0.05 * sagitta


def test_factor_and_stretch_length():
    assert upsampling_factor(0.1) == 4 and upsampling_factor(0.4) == 1 and upsampling_factor(0.05) == 8
    for bad in (0.0, -0.1, 0.3, float("nan")):
        with pytest.raises(EthUcyDataError, match="dt_s"):
            upsampling_factor(bad)
    for w, r in ((50, 4), (8, 1), (3, 8), (1, 2)):
        n = stretch_length(w, r)
        assert (n - 1) * r + 1 >= w + r > (n - 2) * r + 1   # holds r windows, one frame fewer not


def _write_fold(root, fold, rows):
    folder = root / fold / "test"
    folder.mkdir(parents=True)
    np.savetxt(folder / "scene.txt", rows, fmt="%.6f", delimiter="\t")


def test_windows_tile_every_start_of_a_straight_walk_once(tmp_path):
    """One pedestrian walking straight for F annotated frames: (F - L + 1) * r windows, their
    starts every dt apart along the walk, each target one constant-velocity step past its last
    point; a second, standing pedestrian adds its own windows."""
    F, v = 30, np.array([1.2, -0.5])
    frames = 10.0 * np.arange(F)
    walker = np.column_stack([frames, np.ones(F), 1.0 + v[0] * 0.4 * np.arange(F),
                              2.0 + v[1] * 0.4 * np.arange(F)])
    stander = np.column_stack([frames[:20], 2 * np.ones(20), np.full(20, 5.0), np.full(20, 5.0)])
    _write_fold(tmp_path, "eth", np.concatenate([walker, stander]))
    W, dt = 50, 0.1
    ws = ethucy_next_point_windows(tmp_path, W, dt, folds=("eth",), rotate=False)
    L = stretch_length(W, 4)
    assert len(ws) == 4 * ((F - L + 1) + (20 - L + 1))
    moving = np.linalg.norm(ws.y - ws.x[:, -1], axis=1) > 0
    np.testing.assert_allclose(ws.y[moving] - ws.x[moving, -1], np.tile(v * dt, (moving.sum(), 1)),
                               atol=1e-5)
    first = np.sort(ws.x[moving, 0, 0])
    np.testing.assert_allclose(np.diff(first), v[0] * dt, atol=1e-5)   # one start per 0.1 s
    np.testing.assert_allclose(ws.y[~moving], 5.0)
    rotated = ethucy_next_point_windows(tmp_path, W, dt, folds=("eth",), seed=1)
    step = np.linalg.norm(rotated.y - rotated.x[:, -1], axis=1)
    np.testing.assert_allclose(np.sort(step), np.sort(np.linalg.norm(ws.y - ws.x[:, -1], axis=1)),
                               atol=1e-5)   # rotation keeps the speeds


def test_sequences_start_at_every_annotated_frame_at_the_radar_rate(tmp_path):
    """A straight walk of F annotated frames at 0.4 s: walks of 60 points at 0.1 s, one per
    stretch of ceil(59 / 4) + 1 = 16 frames, i.e. F - 15 of them, consecutive ones starting
    0.4 s apart, each stepping exactly v * 0.1 s per point."""
    F, v = 30, np.array([1.2, -0.5])
    walker = np.column_stack([10.0 * np.arange(F), np.ones(F), 1.0 + v[0] * 0.4 * np.arange(F),
                              2.0 + v[1] * 0.4 * np.arange(F)])
    _write_fold(tmp_path, "eth", walker)
    seq = ethucy_sequences(tmp_path, 60, 0.1, folds=("eth",), rotate=False)
    assert seq.shape == (F - 15, 60, 2)
    np.testing.assert_allclose(np.diff(seq, axis=1), np.broadcast_to(v * 0.1, (F - 15, 59, 2)),
                               atol=1e-9)
    np.testing.assert_allclose(np.diff(np.sort(seq[:, 0, 0])), v[0] * 0.4, atol=1e-9)
    turned = ethucy_sequences(tmp_path, 60, 0.1, folds=("eth",), seed=2)
    np.testing.assert_allclose(np.linalg.norm(np.diff(turned, axis=1), axis=-1),
                               np.linalg.norm(v) * 0.1, atol=1e-9)   # rotation keeps the speed
    with pytest.raises(EthUcyDataError, match="n_points"):
        ethucy_sequences(tmp_path, 1, 0.1, folds=("eth",))


def test_missing_data_folder_is_named(tmp_path):
    with pytest.raises(EthUcyDataError, match="test"):
        ethucy_next_point_windows(tmp_path / "nowhere", 50, 0.1, folds=("eth",))


def test_point_errors_move_history_points_by_drawn_vectors_and_leave_futures():
    walks = np.random.default_rng(0).normal(size=(50, 12, 2))
    errors = np.array([[0.1, 0.0], [0.0, -0.2], [0.3, 0.3]])
    out = with_point_errors(walks, 8, errors, np.random.default_rng(1))
    moved = (out - walks)[:, :8].reshape(-1, 2)
    match = np.isclose(moved[:, None], errors[None]).all(-1)      # (400, 3)
    assert (match.sum(1) == 1).all() and match.any(0).all()        # each one of them, all used
    np.testing.assert_array_equal(out[:, 8:], walks[:, 8:])
    with pytest.raises(EthUcyDataError, match="n_history"):
        with_point_errors(walks, 13, errors, np.random.default_rng(1))
    with pytest.raises(EthUcyDataError, match="errors"):
        with_point_errors(walks, 8, np.array([[np.nan, 0.0]]), np.random.default_rng(1))


def test_radar_point_errors_are_measured_minus_true_at_the_radar_points_only():
    truth = np.zeros((2, 3, 2))
    measured = np.array([[[0.1, 0.0], [np.nan, np.nan], [0.0, -0.2]],
                         [[np.nan, 0.0], [0.3, 0.3], [np.nan, np.nan]]])
    np.testing.assert_allclose(radar_point_errors(measured, truth),
                               [[0.1, 0.0], [0.0, -0.2], [0.3, 0.3]])
    with pytest.raises(EthUcyDataError, match="truth"):
        radar_point_errors(measured, truth[:1])
