"""Training: learns constant velocity, is bit-deterministic, resumes exactly, reports RMSE as
defined, refuses bad input."""

from dataclasses import replace

import numpy as np
import pytest
import torch

from blindspot.traj.lstm import LSTMConfig
from blindspot.traj.train import (
    CHECKPOINT_NAME,
    HISTORY_COLUMNS,
    TrainConfig,
    evaluate,
    rmse_euclidean,
    rmse_per_coordinate,
    rollout_errors,
    train_lstm,
)
from blindspot.traj.windows import make_windows, split_by_path
from blindspot.typed_config import ConfigError

W = 10
TINY = LSTMConfig(window=W, hidden_size=8, head_hidden=4)


def straight_paths(n, n_points=40, seed=0):
    """Constant-velocity walkers: random start, heading, speed 0.5-2 m/s, 0.1 s steps."""
    rng = np.random.default_rng(seed)
    start = rng.uniform(-10, 10, size=(n, 1, 2)) + np.array([0.0, 15.0])
    heading = rng.uniform(-np.pi, np.pi, size=n)
    v = rng.uniform(0.5, 2.0, size=n)[:, None] * np.stack([np.sin(heading), np.cos(heading)], axis=-1)
    return start + v[:, None, :] * 0.1 * np.arange(n_points)[None, :, None]


@pytest.fixture(scope="module")
def small_data():
    ws = make_windows(straight_paths(60, seed=1), W, stride=2)  # 15 windows per path
    return split_by_path(ws, (600, 150), seed=0)


def state(result):
    return {k: v.clone() for k, v in result.predictor.model.state_dict().items()}


def assert_same_weights(a, b):
    assert a.keys() == b.keys()
    for k in a:
        assert torch.equal(a[k], b[k]), k


def test_learns_constant_velocity(small_data):
    train, val = small_data
    cfg = LSTMConfig(window=W, hidden_size=16, head_hidden=16)
    res = train_lstm(train, val, cfg, TrainConfig(epochs=8, batch_size=32, lr=1e-2, num_threads=1), progress=False)
    last_point = rmse_per_coordinate(val.x[:, -1], val.y)  # "stand still" reference, ~0.09 m here
    assert last_point > 0.05
    assert res.val_rmse_m < 0.01, res.history  # measured 0.003 m
    # and it keeps working when rolled out 10 steps (1 s) on fresh constant-velocity paths
    fresh = straight_paths(20, n_points=W + 10, seed=9)
    pred = res.predictor.predict(fresh[:, :W], horizon=10)
    rollout = np.sqrt(np.mean((pred - fresh[:, W:]) ** 2))
    stand_still = np.sqrt(np.mean((fresh[:, W - 1 : W] - fresh[:, W:]) ** 2))  # ~0.6 m
    assert rollout < 0.15 and rollout < 0.25 * stand_still  # measured 0.05 m


def test_history_and_rmse_definitions(small_data):
    train, val = small_data
    seen = []
    res = train_lstm(train, val, TINY, TrainConfig(epochs=2, num_threads=1), progress=False,
                     on_epoch=lambda e, m: seen.append((e, m)))
    assert list(res.history.columns) == list(HISTORY_COLUMNS)
    assert res.history["epoch"].tolist() == [1, 2]
    assert [e for e, _ in seen] == [1, 2] and "val_rmse_m" in seen[0][1] and "epoch" not in seen[0][1]
    pred = res.predictor.predict_next(val.x)
    assert res.val_rmse_m == pytest.approx(rmse_per_coordinate(pred, val.y), rel=1e-6)
    assert res.history["val_rmse_euclid_m"].iloc[-1] == pytest.approx(rmse_euclidean(pred, val.y), rel=1e-6)
    # per-coordinate RMSE is the Euclidean one / sqrt(2) when x and y errors are equally large
    e = np.random.default_rng(0).normal(size=(20000, 2))
    assert rmse_euclidean(e, 0 * e) / rmse_per_coordinate(e, 0 * e) == pytest.approx(np.sqrt(2), rel=1e-2)
    assert evaluate(res.predictor, val)["rmse_m"] == pytest.approx(res.val_rmse_m, rel=1e-6)


def test_deterministic_for_a_seed(small_data):
    train, val = small_data
    cfg = TrainConfig(epochs=2, seed=7, num_threads=1)
    a = train_lstm(train, val, TINY, cfg, progress=False)
    b = train_lstm(train, val, TINY, cfg, progress=False)
    assert_same_weights(state(a), state(b))
    assert a.history["train_loss"].tolist() == b.history["train_loss"].tolist()
    c = train_lstm(train, val, TINY, TrainConfig(epochs=2, seed=8, num_threads=1), progress=False)
    assert not torch.equal(state(a)["lstm.weight_hh_l0"], state(c)["lstm.weight_hh_l0"])


@pytest.mark.parametrize("schedule", ["constant", "cosine"])
def test_resume_gives_same_weights_as_uninterrupted(small_data, tmp_path, schedule):
    train, val = small_data
    cfg_model = LSTMConfig(window=W, hidden_size=8, head_hidden=4, num_layers=2, dropout=0.2)  # dropout uses the RNG
    cfg = TrainConfig(epochs=3, seed=1, num_threads=1, lr_schedule=schedule)
    full = train_lstm(train, val, cfg_model, cfg, progress=False)

    class Interrupted(Exception):
        pass

    def stop_after_two(epoch, _metrics):
        if epoch == 2:
            raise Interrupted

    with pytest.raises(Interrupted):
        train_lstm(train, val, cfg_model, cfg, progress=False, checkpoint_dir=tmp_path, on_epoch=stop_after_two)
    assert (tmp_path / CHECKPOINT_NAME).exists()
    resumed_epochs = []
    resumed = train_lstm(train, val, cfg_model, cfg, progress=False, checkpoint_dir=tmp_path, resume=True,
                         on_epoch=lambda e, m: resumed_epochs.append(e))
    assert resumed_epochs == [3]
    assert_same_weights(state(full), state(resumed))
    np.testing.assert_array_equal(full.history["train_loss"], resumed.history["train_loss"])
    np.testing.assert_array_equal(full.history["val_rmse_m"], resumed.history["val_rmse_m"])

    with pytest.raises(ValueError, match="different train"):
        train_lstm(train, val, cfg_model, replace(cfg, lr=0.01), progress=False,
                   checkpoint_dir=tmp_path, resume=True)
    with pytest.raises(ValueError, match="different data"):
        train_lstm(train.subset(np.arange(100)), val, cfg_model, cfg, progress=False, checkpoint_dir=tmp_path,
                   resume=True)


def test_cosine_schedule_changes_training_and_pins_epochs(small_data, tmp_path):
    train, val = small_data
    const = train_lstm(train, val, TINY, TrainConfig(epochs=2, num_threads=1), progress=False)
    cos = train_lstm(train, val, TINY, TrainConfig(epochs=2, num_threads=1, lr_schedule="cosine"), progress=False,
                     checkpoint_dir=tmp_path)
    assert not torch.equal(state(const)["head.0.weight"], state(cos)["head.0.weight"])
    # a cosine run cannot be extended: its learning rate depends on the planned epoch count
    with pytest.raises(ValueError, match="different train"):
        train_lstm(train, val, TINY, TrainConfig(epochs=3, num_threads=1, lr_schedule="cosine"), progress=False,
                   checkpoint_dir=tmp_path, resume=True)


def test_global_torch_settings_restored(small_data):
    train, val = small_data
    threads, det = torch.get_num_threads(), torch.are_deterministic_algorithms_enabled()
    train_lstm(train, val, TINY, TrainConfig(epochs=1, num_threads=1), progress=False)
    assert torch.get_num_threads() == threads and torch.are_deterministic_algorithms_enabled() == det


def test_bad_input(small_data):
    train, val = small_data
    with pytest.raises(ValueError, match="model.window is 12"):
        train_lstm(train, val, LSTMConfig(window=12), TrainConfig(epochs=1), progress=False)
    bad = train.subset(np.arange(10))
    bad.x[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        train_lstm(bad, val, TINY, TrainConfig(epochs=1), progress=False)
    with pytest.raises(ValueError, match="checkpoint_dir"):
        train_lstm(train, val, TINY, TrainConfig(epochs=1), progress=False, resume=True)
    with pytest.raises(ConfigError, match="lr"):
        TrainConfig(lr=0)
    with pytest.raises(ConfigError, match="lr_schedule"):
        TrainConfig(lr_schedule="step")
    with pytest.raises(ConfigError, match=r"train\.optimizer"):
        TrainConfig.from_mapping({"optimizer": "sgd"})
    with pytest.raises(ConfigError, match=r"train\.epoch"):
        TrainConfig.from_mapping({"epoch": 3})


def test_repo_configs_build():
    """conf/model/lstm.yaml and conf/train/paper.yaml are valid and hold the paper's Table 1 values."""
    from blindspot.config import compose
    from tests.conftest import REPO_ROOT

    cfg = compose(["seed=3"], config_dir=REPO_ROOT / "conf")  # the paper profile
    mc = LSTMConfig.from_mapping(cfg.model)
    tc = TrainConfig.from_mapping(cfg.train)
    assert (mc.window, mc.head_activation) == (50, "relu")
    assert (tc.lr, tc.epochs, tc.optimizer, tc.seed) == (0.001, 15, "adam", 3)


def test_seed_ensemble_members_are_the_single_runs_and_average_them(small_data, tmp_path):
    """Member i of train_ensemble is train_lstm with seed + i, whether trained in this process
    or in worker processes (three members on two CPUs: one process each); the ensemble's step
    is the mean of its members', and it survives save/load."""
    from blindspot.traj.lstm import LSTMPredictor
    from blindspot.traj.train import train_ensemble

    train, val = small_data
    cfg = TrainConfig(epochs=1, batch_size=64, num_threads=1, seed=3, ensemble=3)
    seq = train_ensemble(train, val, TINY, cfg, progress=False)
    par = train_ensemble(train, val, TINY, replace(cfg, jobs=2), progress=False,
                         checkpoint_dir=tmp_path / "ck")
    alone = train_lstm(train, val, TINY, replace(cfg, seed=4, ensemble=1), progress=False)
    assert seq.seeds == [3, 4, 5] and seq.predictor.n_members == 3
    assert_same_weights(state(alone), {k: v.clone() for k, v in seq.members[1].predictor.model.state_dict().items()})
    for a, b in zip(seq.members, par.members):
        assert_same_weights(state(a), state(b))
    assert len(par.members) == 3 and (tmp_path / "ck" / "member2" / CHECKPOINT_NAME).exists()
    x = torch.from_numpy(val.x[:7])
    mean = sum(m.predictor.step(x) for m in seq.members) / 3
    assert torch.allclose(seq.predictor.step(x), mean)
    back = LSTMPredictor.load(seq.predictor.save(tmp_path / "model.pt"))
    assert back.n_members == 3 and torch.equal(back.step(x), seq.predictor.step(x))
    assert set(seq.history["member"]) == {0, 1, 2} and list(seq.history.columns[:2]) == ["member", "seed"]


def test_rollout_errors_on_the_windows_own_futures(small_data):
    """Constant velocity rolls a straight walk out exactly; standing still is off by the
    distance walked, |v| k dt at step k, so its ADE is |v| dt (H + 1) / 2 and its FDE |v| dt H."""
    from blindspot.traj.baselines import ConstantVelocity

    _, val = small_data
    cv = rollout_errors(ConstantVelocity(), val, 6)
    assert cv["n_windows"] > 0 and cv["ade_m"] < 1e-4 and cv["fde_m"] < 1e-4

    class StandStill:
        def predict(self, history, horizon):
            return np.repeat(history[:, -1:], horizon, axis=1)

    index, _ = val.futures(6)
    speed = np.linalg.norm(val.x[index, -1] - val.x[index, -2], axis=-1)  # m per 0.1 s step
    still = rollout_errors(StandStill(), val, 6)
    assert still["ade_m"] == pytest.approx(speed.mean() * 3.5, rel=1e-4)
    assert still["fde_m"] == pytest.approx(speed.mean() * 6, rel=1e-4)


def test_fine_tuning_starts_from_the_given_network(small_data, tmp_path):
    """init_from: zero epochs give back the starting weights exactly; training on continues from
    them (not from a fresh draw), a checkpoint of one start does not resume another, and a network
    of another shape is refused by name."""
    train, val = small_data
    net = LSTMConfig(window=W, hidden_size=16, head_hidden=16)
    fast = TrainConfig(epochs=6, batch_size=32, lr=1e-2, seed=3, num_threads=1)
    pre = train_lstm(train, val, net, fast, progress=False)
    assert pre.val_rmse_m < 0.02                      # learnt constant velocity (measured 0.005)
    same = train_lstm(train, val, net, replace(fast, epochs=0, seed=9), progress=False,
                      init_from=pre.predictor)
    assert_same_weights(state(pre), state(same))
    assert evaluate(same.predictor, val)["rmse_m"] == pytest.approx(pre.val_rmse_m, rel=1e-6)
    one = replace(fast, epochs=1, seed=9, lr=1e-3)
    tuned = train_lstm(train, val, net, one, progress=False, init_from=pre.predictor)
    fresh = train_lstm(train, val, net, one, progress=False)
    # one gentle epoch keeps what the start knew; from a fresh draw it is still far off
    assert tuned.val_rmse_m < 0.03 < fresh.val_rmse_m, (tuned.val_rmse_m, fresh.val_rmse_m)
    train_lstm(train, val, net, one, progress=False, init_from=pre.predictor, checkpoint_dir=tmp_path)
    with pytest.raises(ValueError, match="init"):
        train_lstm(train, val, net, replace(one, epochs=2), progress=False, checkpoint_dir=tmp_path,
                   resume=True)
    with pytest.raises(ValueError, match="hidden_size"):
        train_lstm(train, val, replace(net, hidden_size=6), one, progress=False,
                   init_from=pre.predictor)
