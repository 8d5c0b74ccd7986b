"""LSTM model, normalisation and rollout: shapes, invariances, rollout == step-by-step loop,
history handling, save/load."""

import numpy as np
import pytest
import torch

from blindspot.typed_config import ConfigError
from blindspot.traj.lstm import (
    LSTMConfig,
    LSTMPredictor,
    LSTMRegressor,
    NormStats,
    fill_history,
)

W = 6


def tiny_predictor(seed=0, **cfg):
    torch.manual_seed(seed)
    config = LSTMConfig(window=W, hidden_size=8, head_hidden=4, **cfg)
    rng = np.random.default_rng(seed)
    x = np.cumsum(rng.normal(0.1, 0.2, size=(50, W + 1, 2)), axis=1) + rng.uniform(-10, 10, size=(50, 1, 2))
    stats = NormStats.fit(x[:, :W], x[:, W], config)
    return LSTMPredictor(LSTMRegressor(config), stats)


def histories(b=5, t=9, seed=1):
    rng = np.random.default_rng(seed)
    return np.cumsum(rng.normal(0.2, 0.1, size=(b, t, 2)), axis=1) + rng.uniform(0, 20, size=(b, 1, 2))


def test_forward_shape_and_relu_head():
    m = LSTMRegressor(LSTMConfig(window=W, hidden_size=8, head_hidden=4))
    assert m(torch.zeros(3, W, 2)).shape == (3, 2)
    assert isinstance(m.head[1], torch.nn.ReLU)  # the paper's ReLU lives in the head
    with pytest.raises(ValueError, match=r"\(B, W, 2\)"):
        m(torch.zeros(3, W))


@pytest.mark.parametrize("translate", [True, False])
@pytest.mark.parametrize("normalise", [True, False])
@pytest.mark.parametrize("target", ["displacement", "absolute"])
def test_norm_stats_round_trip(translate, normalise, target):
    cfg = LSTMConfig(window=W, translate=translate, normalise=normalise, target=target)
    rng = np.random.default_rng(2)
    x = rng.normal(5.0, 3.0, size=(40, W, 2)).astype(np.float32)
    y = rng.normal(5.0, 3.0, size=(40, 2)).astype(np.float32)
    st = NormStats.fit(x, y, cfg)
    xt, yt = torch.from_numpy(x), torch.from_numpy(y)
    torch.testing.assert_close(st.decode(xt, st.encode_target(xt, yt)), yt, rtol=0, atol=1e-5)
    if normalise:  # fitted scales make the training inputs / targets unit-RMS
        assert float(st.encode(xt).pow(2).mean().sqrt()) == pytest.approx(1.0, rel=1e-4)
        assert float(st.encode_target(xt, yt).pow(2).mean().sqrt()) == pytest.approx(1.0, rel=1e-4)
    if translate:
        assert torch.all(st.encode(xt)[:, -1] == 0)


def test_translation_invariance():
    p = tiny_predictor()
    x = histories(t=W)
    shift = np.array([7.5, -3.25])
    np.testing.assert_allclose(p.predict_next(x + shift), p.predict_next(x) + shift, atol=2e-5)


def test_batched_rollout_equals_step_by_step_loop():
    p = tiny_predictor(seed=3)
    hist = histories(b=7, t=W + 4)
    out = p.predict(hist, horizon=10)
    assert out.shape == (7, 10, 2) and out.dtype == np.float64
    for b in range(hist.shape[0]):  # reference: one track at a time, numpy sliding
        window = hist[b, -W:].copy()
        for k in range(10):
            nxt = p.predict_next(window[None])[0]
            np.testing.assert_allclose(out[b, k], nxt, atol=1e-5)
            window = np.concatenate([window[1:], nxt[None]])


def test_rollout_on_worker_threads_has_the_same_bits_as_one_thread(monkeypatch):
    """A batch runs as blocks of BLOCK_ROWS rows, the same blocks for any number of worker
    threads, each single-threaded: the same bits with 1 or 3 workers, the blocks really spread
    over threads, the predictor itself unchanged, torch's thread count restored (also when a
    block fails)."""
    import threading

    import blindspot.traj.lstm as lstm_mod

    members = [tiny_predictor(seed=s) for s in (3, 4)]
    p = LSTMPredictor.ensemble(members)
    hist = histories(b=lstm_mod.BLOCK_ROWS * 3 + 5, t=W + 2)
    threads = torch.get_num_threads()
    want = p.predict(hist, horizon=6)
    seen = []
    rows = LSTMPredictor._rows

    def spy(self, x):
        seen.append((threading.get_ident(), x.shape[0]))
        return rows(self, x)

    monkeypatch.setattr(LSTMPredictor, "_rows", spy)
    got = p.with_workers(3).predict(hist, horizon=6)
    np.testing.assert_array_equal(got, want)
    assert sorted({n for _, n in seen}) == [5, lstm_mod.BLOCK_ROWS]
    assert len({t for t, _ in seen}) > 1          # the blocks ran on several threads
    assert p.workers == 1 and torch.get_num_threads() == threads

    def fail(self, x):
        raise RuntimeError("block failed")

    monkeypatch.setattr(LSTMPredictor, "_rows", fail)
    with pytest.raises(RuntimeError, match="block failed"):
        p.with_workers(2).predict(hist, horizon=2)
    assert torch.get_num_threads() == threads
    with pytest.raises(ValueError, match="workers"):
        p.with_workers(0)
    assert LSTMPredictor.ensemble([m.with_workers(2) for m in members]).workers == 2


def test_rollout_uses_only_last_window_and_refuses_horizon_zero():
    p = tiny_predictor()
    hist = histories(t=W + 5)
    longer = np.concatenate([np.full((5, 3, 2), 1e3), hist], axis=1)
    np.testing.assert_array_equal(p.predict(hist, 4), p.predict(longer, 4))
    np.testing.assert_array_equal(p.predict(hist, 4), p.predict(hist[:, -W:], 4))
    with pytest.raises(ValueError, match=r"horizon: expected an integer >= 1, found 0"):
        p.predict(hist, 0)      # as every predictor (issue 45): no empty forecast


def test_history_gaps():
    p = tiny_predictor()
    hist = histories(t=W + 3)
    gappy = hist.copy()
    gappy[:, 4] = np.nan
    gappy[0, :2] = np.nan  # leading gap: held at the first observed point
    filled = fill_history(gappy)
    np.testing.assert_allclose(filled[:, 4], 0.5 * (hist[:, 3] + hist[:, 5]))
    np.testing.assert_array_equal(filled[0, :2], np.repeat(hist[0, 2:3], 2, axis=0))
    np.testing.assert_allclose(p.predict(gappy, 3), p.predict(filled, 3), atol=0)
    trailing = hist.copy()
    trailing[2, -2:] = np.nan
    with pytest.raises(ValueError, match="track 2 ends with 2 missing"):
        p.predict(trailing, 3)
    with pytest.raises(ValueError, match="no observed point"):
        p.predict(np.full((1, W, 2), np.nan), 1)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda p: p.predict_next(np.zeros((2, W + 1, 2))), rf"\(B, {W}, 2\)"),
        (lambda p: p.predict_next(np.zeros((2, W, 3))), rf"\(B, {W}, 2\)"),
        (lambda p: p.predict_next(np.full((1, W, 2), np.nan)), "NaN"),
        (lambda p: p.predict(np.zeros((2, W - 1, 2)), 3), f"window={W}"),
        (lambda p: p.predict(np.zeros((W, 2)), 3), r"\(B, T, 2\)"),
        (lambda p: p.predict(np.zeros((1, W, 2)), -1), "horizon"),
    ],
)
def test_clear_errors(call, match):
    with pytest.raises(ValueError, match=match):
        call(tiny_predictor())


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [
        ({"hidden_size": 0}, "hidden_size"),
        ({"target": "velocity"}, "target"),
        ({"head_activation": "gelu"}, "head_activation"),
        ({"dropout": 1.0}, "dropout"),
        ({"normalise": "yes"}, "normalise"),
    ],
)
def test_config_errors(kwargs, key):
    with pytest.raises(ConfigError, match=key):
        LSTMConfig(**kwargs)


def test_config_from_mapping():
    assert LSTMConfig.from_mapping({"name": "lstm", "hidden_size": 16}).hidden_size == 16
    with pytest.raises(ConfigError, match=r"model\.hiden_size"):
        LSTMConfig.from_mapping({"hiden_size": 16})
    with pytest.raises(ConfigError, match=r"model\.window"):
        LSTMConfig.from_mapping({"window": 0})


def test_save_load_round_trip(tmp_path):
    p = tiny_predictor(seed=4, translate=False, target="absolute")
    path = p.save(tmp_path / "m" / "lstm.pt")
    q = LSTMPredictor.load(path)
    assert q.config == p.config and q.stats == p.stats and q.name == "lstm"
    hist = histories()
    np.testing.assert_array_equal(q.predict(hist, 5), p.predict(hist, 5))
    assert [f.name for f in path.parent.iterdir()] == ["lstm.pt"]
    torch.save({"something": 1}, tmp_path / "other.pt")
    with pytest.raises(ValueError, match="other.pt"):
        LSTMPredictor.load(tmp_path / "other.pt")
