"""The scenes' direct multi-step predictor (blindspot.traj.direct): the path splits, pairs of
measured history and true future, and a trained model that looks through radar-like noise where
constant velocity cannot."""

from dataclasses import replace

import numpy as np
import pytest

from blindspot.traj.baselines import ConstantVelocity
from blindspot.traj.calibration import CalibrationError
from blindspot.traj.config import DirectConfig, Seq2SeqConfig
from blindspot.traj.direct import (NAME, check_fits, direct_pairs, direct_scores, path_splits,
                                   pretraining_walks, train_direct)
from blindspot.traj.windows import WindowSet
from blindspot.typed_config import ConfigError


def walks(rng, n, T=60, dt=0.1, noise_m=0.1, miss=0.05):
    """Straight walks at 1.0-1.5 m/s in any direction (truth) and their measurements: Gaussian
    position noise of ``noise_m`` per axis (the radar point's order of size) and a fraction
    ``miss`` of missed points (NaN)."""
    speed = rng.uniform(1.0, 1.5, (n, 1, 1))
    heading = rng.uniform(0, 2 * np.pi, (n, 1))
    step = speed * dt * np.stack([np.cos(heading), np.sin(heading)], -1)
    truth = rng.uniform(-5, 5, (n, 1, 2)) + step * np.arange(T)[None, :, None]
    measured = truth + rng.normal(0.0, noise_m, truth.shape)
    measured[rng.random((n, T)) < miss] = np.nan
    return truth, measured


def _windows(path_ids):
    n = len(path_ids)
    return WindowSet(np.zeros((n, 3, 2), np.float32), np.zeros((n, 2), np.float32),
                     np.asarray(path_ids, np.int64))


def test_path_splits_are_disjoint_and_hold_every_other_path_out():
    ids = path_splits(10, _windows([0, 0, 3, 5]), _windows([1, 1, 7]))
    assert ids["train"].tolist() == [0, 3, 5] and ids["val"].tolist() == [1, 7]
    assert ids["test"].tolist() == [2, 4, 6, 8, 9]
    with pytest.raises(ValueError, match="outside the 4 paths"):
        path_splits(4, _windows([0, 6]), _windows([1]))


def test_pairs_are_the_measured_history_then_the_true_future():
    rng = np.random.default_rng(0)
    truth, measured = walks(rng, 3, T=30, miss=0.0)
    xy = direct_pairs(measured, truth, obs_len=10, horizon=5, stride=5)
    assert xy.shape == (3 * 4, 15, 2)           # starts 0, 5, 10, 15 of each path
    np.testing.assert_array_equal(xy[0, :10], measured[0, :10])
    np.testing.assert_array_equal(xy[0, 10:], truth[0, 10:15])


def test_direct_model_looks_through_the_noise_constant_velocity_follows():
    """Noisy straight walks: CV fitted on the last 5 points carries the noise of its velocity
    into the future; the direct model, trained against the true future, must be clearly better
    over 1 s, and must equal its own scores' numbers."""
    rng = np.random.default_rng(1)
    truth, measured = walks(rng, 240)
    ids = {"train": np.arange(200), "val": np.arange(200, 220), "test": np.arange(220, 240)}
    model_cfg = Seq2SeqConfig(cell="lstm", hidden_size=16, head_hidden=32, obs_len=10,
                              horizon=10, epochs=4, batch_size=128, ensemble=2, neighbours=0,
                              lr=0.01)
    model, reports, pre = train_direct(measured, truth, ids,
                                       DirectConfig(model_cfg, stride=2, jobs=1))
    assert model.name == NAME and len(reports) == 2 and pre == []
    t = ids["test"]
    scores = direct_scores({NAME: model, "constant_velocity": ConstantVelocity(k=5)},
                           measured[t], truth[t], 10, (5, 10), stride=5)
    assert scores[NAME]["ade_10"] < 0.7 * scores["constant_velocity"]["ade_10"], scores
    assert scores[NAME]["n_pairs"] == scores["constant_velocity"]["n_pairs"] > 0


def test_settings_are_checked():
    model_cfg = Seq2SeqConfig(neighbours=0)
    with pytest.raises(ConfigError, match="model.neighbours"):
        DirectConfig(replace(model_cfg, neighbours=2), stride=2, jobs=1)
    with pytest.raises(ConfigError, match="stride"):
        DirectConfig(model_cfg, stride=0, jobs=1)
    d = DirectConfig(replace(model_cfg, obs_len=20, horizon=40), stride=2, jobs=1)
    check_fits(d, window=50, horizon_frames=40)
    with pytest.raises(ConfigError, match="direct.model.obs_len.*dataset.window = 10"):
        check_fits(d, window=10, horizon_frames=40)
    with pytest.raises(ConfigError, match="direct.model.horizon.*horizon_frames = 60"):
        check_fits(d, window=50, horizon_frames=60)
    rng = np.random.default_rng(2)
    truth, measured = walks(rng, 4, T=12)
    ids = {"train": np.arange(2), "val": np.arange(2, 4)}
    with pytest.raises(CalibrationError, match="must fit in paths"):
        train_direct(measured, truth, ids, DirectConfig(model_cfg, stride=1, jobs=1))
    truth, measured = walks(rng, 4, T=40, miss=0.0)
    measured[2:, 0] = np.nan                  # the val paths: their one window starts on a miss
    short = replace(model_cfg, obs_len=10, horizon=10)
    with pytest.raises(ValueError, match="val paths yield no"):
        train_direct(measured, truth, ids, DirectConfig(short, stride=40, jobs=1))


def test_pretraining_on_many_walks_helps_when_radar_paths_are_few():
    """Six noisy training paths are too few for the network (from scratch it does worse than
    constant velocity); pre-trained on 3000 clean walks of the same kind (their histories given
    the paths' own point errors), then fine-tuned on the six, it must beat both on held-out
    paths."""
    rng = np.random.default_rng(5)
    truth, measured = walks(rng, 66)
    ids = {"train": np.arange(6), "val": np.arange(6, 26), "test": np.arange(26, 66)}
    clean, _ = walks(rng, 3000, T=20, noise_m=0.0, miss=0.0)
    errors = (measured - truth)[np.isfinite(measured).all(-1)]
    pre_walks = clean + np.concatenate(
        [errors[rng.integers(0, len(errors), (3000, 10))], np.zeros((3000, 10, 2))], axis=1)
    model_cfg = Seq2SeqConfig(cell="lstm", hidden_size=16, head_hidden=32, obs_len=10,
                              horizon=10, epochs=4, batch_size=64, ensemble=2, neighbours=0,
                              lr=0.01)
    cfg = DirectConfig(model_cfg, stride=2, jobs=1, pretrain_epochs=3)
    tuned, reports, pre = train_direct(measured, truth, ids, cfg, pretrain=pre_walks)
    scratch, _, none = train_direct(measured, truth, ids, replace(cfg, pretrain_epochs=0),
                                    pretrain=pre_walks)
    assert len(pre) == 2 and none == [] and all(r.init_val_ade is not None for r in reports)
    t = ids["test"]
    s = direct_scores({"tuned": tuned, "scratch": scratch, "cv": ConstantVelocity(k=5)},
                      measured[t], truth[t], 10, (10,), 5)
    assert s["tuned"]["ade_10"] < 0.6 * min(s["scratch"]["ade_10"], s["cv"]["ade_10"]), s
    # direct.finetune false: the pre-trained members themselves, their reports the pre-training's
    kept, kept_reports, kept_pre = train_direct(measured, truth, ids, replace(cfg, finetune=False),
                                                pretrain=pre_walks)
    assert kept_reports is kept_pre and [r.best_epoch for r in kept_pre] == [r.best_epoch
                                                                             for r in pre]
    h = measured[t][:, :10]
    h = np.where(np.isfinite(h), h, truth[t][:, :10])
    tuned_pred, kept_pred = tuned.predict(h, 10), kept.predict(h, 10)
    moved = [r.best_epoch > 0 for r in reports]               # members whose fine-tuning won
    assert np.allclose(tuned_pred, kept_pred) == (not any(moved))
    again, _, _ = train_direct(measured, truth, ids, replace(cfg, finetune=False, model=replace(
        model_cfg, epochs=1)), pretrain=pre_walks)             # radar epochs are not read
    np.testing.assert_array_equal(again.predict(h, 10), kept_pred)
    with pytest.raises(ConfigError, match="finetune"):
        replace(cfg, pretrain_epochs=0, finetune=False)
    with pytest.raises(ValueError, match="no pre-training walks"):
        train_direct(measured, truth, ids, replace(cfg, finetune=False))


def test_pretraining_walks_are_seeded_subsets_with_radar_errors_on_their_histories(tmp_path):
    """A folder of one straight ETH/UCY walker: the walks' futures are the resampled walk
    itself, each history point is moved by one of the given paths' error vectors, at most
    pretrain_walks of them, the same for the same seed."""
    F, v = 40, np.array([1.0, 0.5])
    ped = np.column_stack([10.0 * np.arange(F), np.ones(F), v[0] * 0.4 * np.arange(F),
                           v[1] * 0.4 * np.arange(F)])
    for fold in ("eth", "hotel", "univ", "zara1", "zara2"):    # every fold is read
        (tmp_path / fold / "test").mkdir(parents=True)
        np.savetxt(tmp_path / fold / "test" / "walk.txt", ped, delimiter="\t")
    truth = np.zeros((2, 5, 2))
    measured = truth.copy()
    measured[0, :, 0] = 0.3                    # every radar point 0.3 m off in x, or missed
    measured[1] = np.nan
    model_cfg = Seq2SeqConfig(obs_len=6, horizon=4, neighbours=0, seed=3)
    cfg = DirectConfig(model_cfg, stride=1, jobs=1, pretrain_epochs=1, pretrain_walks=5)
    a = pretraining_walks(tmp_path, measured, truth, cfg, 0.1)
    b = pretraining_walks(tmp_path, measured, truth, cfg, 0.1)
    np.testing.assert_array_equal(a, b)
    assert a.shape == (5, 10, 2)
    steps = np.diff(a[:, 6:], axis=1)          # futures: the walk at v * 0.1 s per point
    np.testing.assert_allclose(np.linalg.norm(steps, axis=-1), np.linalg.norm(v) * 0.1,
                               atol=1e-9)
    # histories: the same straight walk shifted by exactly (0.3, 0) at every point
    err = a[:, :6] - (a[:, 6:7] - np.arange(6, 0, -1)[None, :, None] * steps[:, :1])
    np.testing.assert_allclose(err, np.broadcast_to([0.3, 0.0], err.shape), atol=1e-9)
    with pytest.raises(ValueError, match="no radar point"):
        pretraining_walks(tmp_path, measured[1:], truth[1:], cfg, 0.1)
