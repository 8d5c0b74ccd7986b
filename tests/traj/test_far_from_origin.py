"""Precision far from the origin (issue 45): a walk in projected coordinates (UTM: 5e5 m east,
5e6 m north) gives every predictor the predictions of the same walk near the origin, moved by
the same offset; training on it gives the same network. Positions are translated before any
cast to float32 (a float32 at 5e6 m is only good to 0.5 m)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from blindspot.traj.baselines import ConstantVelocity, KalmanCV
from blindspot.traj.config import LSTMConfig, TrainConfig
from blindspot.traj.lstm import LSTMPredictor, LSTMRegressor, NormStats
from blindspot.traj.predictor import HeadingFrameRollout, NextPointRollout
from blindspot.traj.seq2seq import Seq2SeqConfig, train_seq2seq
from blindspot.traj.stationary import Stationary
from blindspot.traj.train import train_lstm
from blindspot.traj.windows import WindowSet, make_windows

W = 6
OFFSETS = st.tuples(st.sampled_from([5e5, -3e5, 6.9e5, 0.0]), st.sampled_from([5e6, 4.4e6,
                                                                               -1e6, 0.0]))


def walks(b=4, t=12, seed=0):
    rng = np.random.default_rng(seed)
    return (np.cumsum(rng.normal(0.3, 0.1, size=(b, t, 2)), axis=1)
            + rng.uniform(-5, 5, size=(b, 1, 2)))


def _lstm(translate: bool, offset=np.zeros(2)):
    torch.manual_seed(0)
    cfg = LSTMConfig(window=W, hidden_size=8, head_hidden=4, translate=translate, normalise=True)
    x = walks(40, W + 1, seed=3) + offset
    return LSTMPredictor(LSTMRegressor(cfg), NormStats.fit(x[:, :W], x[:, W], cfg))


_SEQ2SEQ = {}


def _seq2seq():
    if not _SEQ2SEQ:
        torch.manual_seed(0)
        xy = walks(80, 20, seed=5)
        cfg = Seq2SeqConfig(cell="mlp", hidden_size=8, head_hidden=8, epochs=1, batch_size=64,
                            ensemble=1, threads=1)
        _SEQ2SEQ["m"] = train_seq2seq(xy[:60], xy[60:], cfg)[0]
    return _SEQ2SEQ["m"]


PREDICTORS = {
    "cv": lambda: ConstantVelocity(),
    "kalman": lambda: KalmanCV(),
    "stationary": lambda: Stationary(),
    "lstm": lambda: _lstm(True),
    "lstm_rollout": lambda: NextPointRollout(_lstm(True)),
    "lstm_heading_frame": lambda: HeadingFrameRollout(_lstm(True), residual=False),
    "seq2seq": _seq2seq,
}


@pytest.mark.parametrize("name", sorted(PREDICTORS))
@settings(max_examples=4, deadline=None)
@given(offset=OFFSETS)
def test_every_predictor_predicts_a_far_walk_as_the_same_walk_near_the_origin(name, offset):
    predictor = PREDICTORS[name]()
    history = walks(t=8 if name == "seq2seq" else 12)
    off = np.asarray(offset, float)
    near = predictor.predict(history, 5)
    far = predictor.predict(history + off, 5) - off
    np.testing.assert_allclose(far, near, atol=1e-4)


@settings(max_examples=4, deadline=None)
@given(offset=OFFSETS)
def test_an_lstm_with_a_fitted_mean_position_is_exact_far_from_the_origin(offset):
    """translate=False (normalised) subtracts the fitted mean position: fitted on the far walks, the model
    predicts them as the near model predicts the near walks (no 0.5 m float32 steps)."""
    off = np.asarray(offset, float)
    near = _lstm(False).predict(walks(), 5)
    far = _lstm(False, off).predict(walks() + off, 5) - off
    np.testing.assert_allclose(far, near, atol=1e-4)


def test_windows_far_from_the_origin_keep_their_centimetres(tmp_path):
    paths = walks(3, 10) + [5e5, 5e6]
    ws = make_windows(paths, W)
    assert ws.x.dtype == np.float64
    np.testing.assert_array_equal(ws.x[0], paths[0, :W])
    back = WindowSet.load(ws.save(tmp_path / "w.parquet"))
    np.testing.assert_array_equal(back.x, ws.x)
    assert make_windows(walks(3, 10), W).x.dtype == np.float32        # near: as before


def test_training_far_from_the_origin_gives_the_network_of_training_near_it():
    cfg = LSTMConfig(window=W, hidden_size=8, head_hidden=4)
    tcfg = TrainConfig(epochs=2, batch_size=16, lr=1e-2, num_threads=1, seed=3)
    paths = walks(12, 14, seed=7)
    off = np.array([5e5, 5e6])
    nets = []
    for p in (paths, paths + off):
        tr, va = make_windows(p[:9], W), make_windows(p[9:], W)
        nets.append(train_lstm(tr, va, cfg, tcfg, progress=False).predictor)
    near = nets[0].predict(walks(), 4)
    far = nets[1].predict(walks() + off, 4) - off
    np.testing.assert_allclose(far, near, atol=1e-3)
