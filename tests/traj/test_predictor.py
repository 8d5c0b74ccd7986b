"""Heading-frame rollout: geometry of the frame, invariances, and exact CVM limits."""

import numpy as np
import pytest

from blindspot.traj.baselines import ConstantVelocity
from blindspot.traj.predictor import (
    HeadingFrameRollout,
    HistoryError,
    PathPredictor,
    from_frame,
    heading_frame,
    heading_frame_pairs,
    to_frame,
)


class ConstantVelocityStep:
    """Next point = last point + last step (a NextPointModel)."""

    window = 8

    def predict_next(self, w):
        return 2 * w[:, -1] - w[:, -2]


class Zero:
    window = 8

    def predict_next(self, w):
        return np.zeros((w.shape[0], 2))


class TurnLeft:
    """In its own frame: keep the speed, turn left by 0.1 m per step (an asymmetric model)."""

    window = 8

    def predict_next(self, w):
        step = w[:, -1] - w[:, -2]
        return w[:, -1] + step + np.array([0.0, 0.1])


def walks(seed, B=16, T=8):
    return np.cumsum(np.random.default_rng(seed).normal(size=(B, T, 2)), axis=1)


def rotate(p, theta):
    c, s = np.cos(theta), np.sin(theta)
    return p @ np.array([[c, s], [-s, c]])


def test_frame_puts_last_point_at_origin_and_last_step_on_plus_x():
    w = walks(0)
    origin, rot = heading_frame(w)
    q = to_frame(w, origin, rot)
    np.testing.assert_allclose(q[:, -1], 0.0, atol=1e-12)
    assert np.all(q[:, -2, 0] < 0) and np.allclose(q[:, -2, 1], 0.0, atol=1e-12)
    np.testing.assert_allclose(-q[:, -2, 0], np.linalg.norm(w[:, -1] - w[:, -2], axis=-1))
    np.testing.assert_allclose(from_frame(q, origin, rot), w, atol=1e-12)
    # distances are preserved (a rigid motion)
    np.testing.assert_allclose(np.linalg.norm(np.diff(q, axis=1), axis=-1),
                               np.linalg.norm(np.diff(w, axis=1), axis=-1))


def test_pairs_residual_and_mirror():
    seq = walks(1, T=9)
    x, y = heading_frame_pairs(seq, residual=False, mirror=False)
    x_r, y_r = heading_frame_pairs(seq, residual=True, mirror=True)
    assert x_r.shape == (32, 8, 2) and y_r.shape == (32, 2)
    np.testing.assert_allclose(x_r[:16], x)
    np.testing.assert_allclose(x_r[16:], x * [1, -1])
    # residual = next point minus the constant-velocity guess (last point + last step)
    np.testing.assert_allclose(y_r[:16], y - (x[:, -1] - x[:, -2]))
    with pytest.raises(HistoryError, match="W \\+ 1"):
        heading_frame_pairs(np.zeros((4, 2, 2)))


@pytest.mark.parametrize("model,residual", [(ConstantVelocityStep(), False), (Zero(), True)])
def test_cvm_limits_are_exact(model, residual):
    h = walks(2)
    roll = HeadingFrameRollout(model, residual=residual)
    assert isinstance(roll, PathPredictor)
    np.testing.assert_allclose(roll.predict(h, 12), ConstantVelocity().predict(h, 12), atol=1e-9)


def test_rollout_is_rotation_and_translation_equivariant():
    h = walks(3)
    roll = HeadingFrameRollout(TurnLeft(), residual=False, symmetric=False)
    moved = rotate(h, 0.7) + [5.0, -3.0]
    np.testing.assert_allclose(roll.predict(moved, 6), rotate(roll.predict(h, 6), 0.7) + [5.0, -3.0],
                               atol=1e-9)


def test_symmetric_rollout_cancels_a_one_sided_bias():
    h = np.stack([np.arange(8.0), np.zeros(8)], axis=-1)[None]       # straight along +x
    biased = HeadingFrameRollout(TurnLeft(), residual=False, symmetric=False).predict(h, 3)
    assert np.all(biased[0, :, 1] > 0)                                # drifts left
    sym = HeadingFrameRollout(TurnLeft(), residual=False, symmetric=True).predict(h, 3)
    np.testing.assert_allclose(sym[0], [[8, 0], [9, 0], [10, 0]], atol=1e-12)


def test_rollout_refuses_short_or_gappy_histories():
    roll = HeadingFrameRollout(Zero())
    with pytest.raises(HistoryError, match="window=8"):
        roll.predict(walks(4, T=5), 3)
    h = walks(4)
    h[0, -1] = np.nan
    with pytest.raises(HistoryError, match="NaN"):
        roll.predict(h, 3)


def test_speed_scaled_frame_has_a_unit_last_step_and_round_trips():
    w = walks(5) * 0.3
    step = np.linalg.norm(w[:, -1] - w[:, -2], axis=-1)
    origin, rot = heading_frame(w, speed_floor=0.05)
    q = to_frame(w, origin, rot)
    fast = step > 0.05
    np.testing.assert_allclose(q[fast, -2], np.tile([-1.0, 0.0], (fast.sum(), 1)), atol=1e-12)
    np.testing.assert_allclose(q[~fast, -2, 0], -step[~fast] / 0.05)
    np.testing.assert_allclose(from_frame(q, origin, rot), w, atol=1e-12)
    # CVM stays exact, and a frame-defined model scales with the walk (above the floor)
    roll = HeadingFrameRollout(Zero(), residual=True, speed_floor=0.05)
    np.testing.assert_allclose(roll.predict(w, 5), ConstantVelocity().predict(w, 5), atol=1e-9)
    fast_walk = np.stack([np.arange(8.0), np.zeros(8)], axis=-1)[None]
    turn = HeadingFrameRollout(TurnLeft(), residual=False, symmetric=False, speed_floor=0.05)
    np.testing.assert_allclose(turn.predict(2 * fast_walk, 4), 2 * turn.predict(fast_walk, 4),
                               atol=1e-9)
    with pytest.raises(ValueError, match="speed_floor"):
        heading_frame(w, speed_floor=0.0)


def test_mean_next_point_averages_models_and_checks_windows():
    from blindspot.traj.predictor import MeanNextPoint

    w = walks(6)
    mean = MeanNextPoint([ConstantVelocityStep(), Zero()])
    np.testing.assert_allclose(mean.predict_next(w), 0.5 * (2 * w[:, -1] - w[:, -2]))
    assert mean.window == 8

    class Short(Zero):
        window = 5

    with pytest.raises(ValueError, match="window"):
        MeanNextPoint([Zero(), Short()])
    with pytest.raises(ValueError, match="at least one"):
        MeanNextPoint([])


def test_world_rollout_appends_and_slides():
    from blindspot.traj.predictor import NextPointRollout

    h = walks(7)
    np.testing.assert_allclose(NextPointRollout(ConstantVelocityStep()).predict(h, 6),
                               ConstantVelocity().predict(h, 6), atol=1e-9)


class _FixedHorizon:
    """A direct model that emits at most 4 steps: a curve (quadratic in the step)."""

    name = "fixed"
    window = 3

    def predict(self, history, horizon):
        if horizon > 4:
            raise HistoryError(f"emits 4 steps, asked for {horizon}")
        k = np.arange(1, horizon + 1, dtype=float)
        last = history[:, -1]
        return last[:, None, :] + np.stack([k, 0.1 * k ** 2], axis=-1)[None]

    def predict_distribution(self, history, horizon, **options):
        return ("dist", horizon, options)


def test_constant_velocity_tail_keeps_the_model_and_continues_its_last_step():
    from blindspot.traj.predictor import ConstantVelocityTail

    base = _FixedHorizon()
    tail = ConstantVelocityTail(base, 4)
    hist = np.random.default_rng(0).normal(size=(3, 5, 2))
    np.testing.assert_array_equal(tail.predict(hist, 3), base.predict(hist, 3))
    long = tail.predict(hist, 9)
    assert long.shape == (3, 9, 2)
    np.testing.assert_array_equal(long[:, :4], base.predict(hist, 4))
    # steps 5..9: the 4th point plus k times the 4th step (1, 0.7): a straight line at that speed
    last = base.predict(hist, 4)
    step = last[:, 3] - last[:, 2]
    np.testing.assert_allclose(step, np.tile([1.0, 0.7], (3, 1)))
    np.testing.assert_allclose(np.diff(long[:, 3:], axis=1),
                               np.broadcast_to(step[:, None], (3, 5, 2)))
    assert tail.window == 3 and tail.name == "fixed"
    assert tail.predict_distribution(hist, 2, measured=False) == ("dist", 2, {"measured": False})


def test_constant_velocity_tail_needs_a_last_step():
    from blindspot.traj.predictor import ConstantVelocityTail

    with pytest.raises(ValueError, match="max_horizon: expected an integer >= 2"):
        ConstantVelocityTail(_FixedHorizon(), 1)


def test_constant_velocity_tail_serves_a_direct_model_through_forecast_tracks():
    """A real (untrained) direct model of 6 steps, forecast through ``forecast_tracks`` for
    tracks last seen 0, 3 and 9 frames before the start: the steps the model emits are its own
    (the same as asking it directly), the rest a straight line at its last step's velocity."""
    import torch

    from blindspot.traj.config import Seq2SeqConfig
    from blindspot.traj.forecast import forecast_tracks
    from blindspot.traj.predictor import ConstantVelocityTail
    from blindspot.traj.seq2seq import Seq2SeqEnsemble, Seq2SeqModel, Seq2SeqNet

    torch.manual_seed(0)
    cfg = Seq2SeqConfig(cell="lstm", hidden_size=8, head_hidden=16, obs_len=5, horizon=6,
                        neighbours=0)
    model = Seq2SeqEnsemble([Seq2SeqModel(Seq2SeqNet(cfg), cfg)], name="lstm_direct")
    t = np.arange(40) * 0.1
    track = np.stack([1.2 * t, 5 + 0.3 * t + 0.2 * np.sin(t)], axis=-1)
    tracks = np.repeat(track[None], 3, axis=0)
    start = np.array([20, 20, 20])
    for b, lead in enumerate((0, 3, 9)):
        tracks[b, 20 - lead:20] = np.nan                       # last seen lead frames before
    tail = ConstantVelocityTail(model, cfg.horizon)
    with pytest.raises(HistoryError, match="emits 6 steps"):
        forecast_tracks(tracks, start, model, end=start + 4)   # lead 9 + 4 steps > 6
    pred = forecast_tracks(tracks, start, tail, end=start + 4)
    assert pred.shape == (3, 4, 2) and np.isfinite(pred).all()
    for b, lead in enumerate((0, 3, 9)):
        own = model.predict(tracks[b:b + 1, 20 - lead - cfg.obs_len:20 - lead], cfg.horizon)[0]
        steps = lead + np.arange(4)                            # steps from the last point seen
        want = np.where((steps < cfg.horizon)[:, None], own[np.minimum(steps, cfg.horizon - 1)],
                        own[-1] + (steps - cfg.horizon + 1)[:, None] * (own[-1] - own[-2]))
        np.testing.assert_allclose(pred[b], want, atol=1e-9)
