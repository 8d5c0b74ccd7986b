"""The direct multi-step predictor: constant velocity before training, exact symmetries
(rotation, translation, mirror), learning a turn constant velocity cannot follow, ensemble
moments, bit-identical retraining, and the errors it names."""

from dataclasses import replace

import numpy as np
import pytest
import torch

from blindspot.traj.baselines import ConstantVelocity
from blindspot.traj.config import Seq2SeqConfig
from blindspot.traj.predictor import HistoryError
from blindspot.traj.seq2seq import (
    Seq2SeqEnsemble,
    Seq2SeqModel,
    Seq2SeqNet,
    _framed_inputs,
    base_deviations,
    train_seq2seq,
)

CFG = Seq2SeqConfig(cell="mlp", hidden_size=16, head_hidden=32, epochs=3, batch_size=128,
                    ensemble=1, threads=1)


def turning_tracks(rng, n, T=20, dt=0.4):
    """Constant-speed, constant-turn-rate walks (a circle arc): speed 0.8-1.6 m/s, turn rate
    +-0.3 rad/s, random start and heading."""
    speed = rng.uniform(0.8, 1.6, n)[:, None]
    omega = rng.uniform(-0.3, 0.3, n)[:, None]
    h0 = rng.uniform(0, 2 * np.pi, n)[:, None]
    heading = h0 + omega * dt * np.arange(T)[None, :]
    steps = speed[..., None] * dt * np.stack([np.cos(heading), np.sin(heading)], axis=-1)
    return rng.uniform(-10, 10, (n, 1, 2)) + np.cumsum(steps, axis=1)


def _rot(a):
    return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])


def test_untrained_residual_head_is_constant_velocity():
    rng = np.random.default_rng(0)
    xy = turning_tracks(rng, 50)
    for cell in ("mlp", "gru", "lstm", "transformer"):
        cfg = replace(CFG, cell=cell)
        model = Seq2SeqModel(Seq2SeqNet(cfg), cfg)
        np.testing.assert_allclose(model.predict(xy[:, :8], 12),
                                   ConstantVelocity().predict(xy[:, :8], 12), atol=1e-5)


@pytest.mark.parametrize("cell, basis_rank", [("mlp", 0), ("transformer", 0), ("mlp", 3)])
def test_predictions_rotate_translate_and_mirror_with_the_track(cell, basis_rank):
    rng = np.random.default_rng(1)
    xy = turning_tracks(rng, 400)
    model, _ = train_seq2seq(xy[:300], xy[300:], replace(CFG, cell=cell, basis_rank=basis_rank))
    obs = xy[300:, :8]
    pred = model.predict(obs, 12)
    R, t = _rot(0.7), np.array([3.0, -2.0])
    moved = model.predict(obs @ R.T + t, 12)
    np.testing.assert_allclose(moved, pred @ R.T + t, atol=1e-4)
    mirrored = model.predict(obs * [1.0, -1.0], 12)
    np.testing.assert_allclose(mirrored, pred * [1.0, -1.0], atol=1e-4)
    fc = model.predict_distribution(obs, 12)
    fc_moved = model.predict_distribution(obs @ R.T + t, 12)
    np.testing.assert_allclose(fc_moved.cov, R @ fc.cov @ R.T, atol=1e-6)


def test_learns_a_turn_that_constant_velocity_cannot_follow():
    """Walks on circle arcs: CV's error grows with the turn; the trained model must be well
    below it after three epochs on 3000 windows."""
    rng = np.random.default_rng(2)
    train, val, test = turning_tracks(rng, 3000), turning_tracks(rng, 500), turning_tracks(rng, 500)
    model, report = train_seq2seq(train, val, CFG)
    err = np.linalg.norm(model.predict(test[:, :8], 12) - test[:, 8:], axis=-1).mean()
    cv = np.linalg.norm(ConstantVelocity().predict(test[:, :8], 12) - test[:, 8:], axis=-1).mean()
    assert err < 0.5 * cv, (err, cv)
    assert report.val_ade[report.best_epoch - 1] == min(report.val_ade)
    assert report.best_val_ade == min(report.val_ade) and report.init_val_ade is None


def test_retraining_with_the_same_seed_gives_the_same_weights():
    rng = np.random.default_rng(3)
    xy = turning_tracks(rng, 300)
    a, _ = train_seq2seq(xy[:200], xy[200:], replace(CFG, epochs=1))
    b, _ = train_seq2seq(xy[:200], xy[200:], replace(CFG, epochs=1))
    c, _ = train_seq2seq(xy[:200], xy[200:], replace(CFG, epochs=1), seed=5)
    for (k, va), vb in zip(a.net.state_dict().items(), b.net.state_dict().values()):
        assert np.array_equal(va.numpy(), vb.numpy()), k
    assert not np.array_equal(a.predict(xy[:5, :8], 12), c.predict(xy[:5, :8], 12))


def test_ensemble_covariance_is_the_mixture_moment():
    rng = np.random.default_rng(4)
    xy = turning_tracks(rng, 300)
    members = [train_seq2seq(xy[:200], xy[200:], replace(CFG, epochs=1), seed=s)[0]
               for s in range(3)]
    ens = Seq2SeqEnsemble(members)
    obs = xy[200:, :8]
    fc = ens.predict_distribution(obs, 12)
    fcs = [m.predict_distribution(obs, 12) for m in members]
    means = np.stack([f.mean for f in fcs])
    mu = means.mean(0)
    second = np.mean([f.cov + np.einsum("bhi,bhj->bhij", f.mean, f.mean) for f in fcs], axis=0)
    np.testing.assert_allclose(fc.mean, mu)
    np.testing.assert_allclose(fc.cov, second - np.einsum("bhi,bhj->bhij", mu, mu), atol=1e-9)
    scaled = Seq2SeqEnsemble(members, step_scale=np.full(12, 2.0)).predict_distribution(obs, 12)
    np.testing.assert_allclose(scaled.cov, 2.0 * fc.cov)


def test_bad_histories_are_named():
    model = Seq2SeqModel(Seq2SeqNet(CFG), CFG)
    xy = turning_tracks(np.random.default_rng(5), 4)
    with pytest.raises(HistoryError, match="obs_len=8"):
        model.predict(xy[:, :5], 12)
    gap = xy[:, :8].copy()
    gap[1, 3] = np.nan
    with pytest.raises(HistoryError, match="NaN"):
        model.predict(gap, 12)
    with pytest.raises(HistoryError, match="emits 12 steps"):
        model.predict(xy[:, :8], 13)
    with pytest.raises(HistoryError, match="train_xy"):
        train_seq2seq(xy[:, :10], xy, CFG)


def side_step_scenes(rng, n, T=20, dt=0.4):
    """A walker along a straight line (1.0-1.4 m/s, any heading) and one neighbour 1-2 m to its
    left or right at the last observed frame, walking alongside; over the future the walker
    steps 0.8 m away from the neighbour's side (linearly). Without the neighbour the side is
    a coin flip: the best a lone-walker model can do is go straight."""
    speed = rng.uniform(1.0, 1.4, n)
    h = rng.uniform(0, 2 * np.pi, n)
    fwd = np.stack([np.cos(h), np.sin(h)], -1)
    left = np.stack([-np.sin(h), np.cos(h)], -1)
    t = np.arange(T)
    side = rng.choice([-1.0, 1.0], n)
    gap = rng.uniform(1.0, 2.0, n)
    away = -side[:, None] * 0.8 * np.clip((t - 7) / 12, 0, 1)[None]          # (n, T)
    walker = (speed[:, None, None] * dt * t[None, :, None] * fwd[:, None]
              + away[..., None] * left[:, None])
    nb = (walker[:, :8] - away[:, :8, None] * left[:, None]
          + (side * gap)[:, None, None] * left[:, None])
    origin = rng.uniform(-10, 10, (n, 1, 2))
    return walker + origin, (nb + origin)[:, None]                          # (n, T, 2), (n, 1, 8, 2)


def test_neighbours_as_context_predict_what_the_walker_alone_cannot():
    rng = np.random.default_rng(6)
    (tr, tr_nb), (va, va_nb), (te, te_nb) = (side_step_scenes(rng, m) for m in (2000, 300, 300))
    alone = replace(CFG, neighbours=0)
    social = replace(CFG, neighbours=2)
    m0, _ = train_seq2seq(tr, va, alone)
    m1, _ = train_seq2seq(tr, va, social, train_nb=tr_nb, val_nb=va_nb)
    e0 = np.linalg.norm(m0.predict(te[:, :8], 12) - te[:, 8:], axis=-1).mean()
    e1 = np.linalg.norm(m1.predict(te[:, :8], 12, neighbours=te_nb) - te[:, 8:], axis=-1).mean()
    assert e1 < 0.5 * e0, (e1, e0)
    # the neighbours move with the scene: rotation, translation and mirror
    R, t = _rot(-1.1), np.array([1.0, 4.0])
    obs, nb = te[:50, :8], te_nb[:50]
    pred = m1.predict(obs, 12, neighbours=nb)
    np.testing.assert_allclose(m1.predict(obs @ R.T + t, 12, neighbours=nb @ R.T + t),
                               pred @ R.T + t, atol=1e-4)
    np.testing.assert_allclose(m1.predict(obs * [1.0, -1.0], 12, neighbours=nb * [1.0, -1.0]),
                               pred * [1.0, -1.0], atol=1e-4)
    # nobody near: no neighbours given, or only absent ones, is the same input
    np.testing.assert_allclose(m1.predict(obs, 12),
                               m1.predict(obs, 12, neighbours=np.full_like(nb, np.nan)))
    with pytest.raises(HistoryError, match="neighbours"):
        m1.predict(obs, 12, neighbours=nb[:, :, :5])


@pytest.mark.parametrize("neighbours", [0, 3])
def test_validation_mean_of_tracks_framed_once_is_predict_to_the_bit(neighbours):
    """The per-epoch validation frames the val tracks once (``_framed_inputs``) and computes the
    mean only: the same numbers as ``predict``, which frames them and computes the covariance
    on every call, so the epoch kept (and the ETH/UCY outputs) cannot move. A network with
    random weights (the head's last layer is zero at initialisation), the mirror on."""
    import torch

    from blindspot.traj.seq2seq import _framed_inputs

    rng = np.random.default_rng(3)
    cfg = replace(CFG, cell="lstm", neighbours=neighbours, mirror=True)
    torch.manual_seed(0)
    net = Seq2SeqNet(cfg)
    with torch.no_grad():
        for p in net.parameters():
            p.normal_(0.0, 0.3)
    model = Seq2SeqModel(net, cfg)
    obs = turning_tracks(rng, 300)[:, :cfg.obs_len]
    nb = None
    if neighbours:
        nb = obs[:, None] + rng.normal(0.0, 2.0, (300, neighbours, 1, 2))
        nb[rng.random((300, neighbours)) < 0.4] = np.nan
    once = model._mean_of_framed(_framed_inputs(obs, nb, cfg), cfg.horizon)
    assert np.array_equal(once, model.predict(obs, cfg.horizon, neighbours=nb))


def test_ensemble_saves_and_loads_to_the_bit_and_names_a_foreign_file(tmp_path):
    import torch

    rng = np.random.default_rng(7)
    xy = turning_tracks(rng, 300)
    cfg = replace(CFG, cell="lstm", epochs=1)
    ens = Seq2SeqEnsemble([train_seq2seq(xy[:200], xy[200:], cfg, seed=s)[0] for s in (0, 1)],
                          name="lstm_direct")
    back = Seq2SeqEnsemble.load(ens.save(tmp_path / "m.pt"))
    obs = xy[200:, :8]
    a, b = ens.predict_distribution(obs, 12), back.predict_distribution(obs, 12)
    assert np.array_equal(a.mean, b.mean) and np.array_equal(a.cov, b.cov)
    assert back.name == "lstm_direct" and back.window == back.obs_len == cfg.obs_len
    np.testing.assert_allclose(ens.predict(obs, 12), a.mean, atol=1e-12)
    torch.save({"format": "something else"}, tmp_path / "other.pt")
    with pytest.raises(ValueError, match="other.pt.*Seq2SeqEnsemble"):
        Seq2SeqEnsemble.load(tmp_path / "other.pt")
    with pytest.raises(ValueError, match="share one config"):
        Seq2SeqEnsemble([ens.members[0], Seq2SeqModel(Seq2SeqNet(CFG), CFG)])


@pytest.mark.parametrize("neighbours", [0, 2])
def test_rotation_augmentation_rotates_the_walker_and_its_neighbours(neighbours):
    """With ``rotation_deg`` the training copies are rotated; the rotation's sine once shadowed
    the social features (training crashed without neighbours and fed the sine as features with
    them). A world-frame model trained with full rotation must come out (nearly) rotation
    invariant, neighbours included."""
    rng = np.random.default_rng(8)
    (tr, tr_nb), (va, va_nb), (te, te_nb) = (side_step_scenes(rng, m) for m in (1500, 200, 100))
    cfg = replace(CFG, frame="world", rotation_deg=180.0, neighbours=neighbours, epochs=2)
    kw = dict(train_nb=tr_nb, val_nb=va_nb) if neighbours else {}
    model, report = train_seq2seq(tr, va, cfg, **kw)
    assert np.isfinite(report.val_ade).all()
    obs, nb = te[:, :8], (te_nb if neighbours else None)
    R = _rot(2.0)
    turned = model.predict(obs @ R.T, 12, neighbours=None if nb is None else nb @ R.T)
    pred = model.predict(obs, 12, neighbours=nb)
    spread = np.linalg.norm(pred - obs[:, -1:], axis=-1).mean()
    assert np.linalg.norm(turned - pred @ R.T, axis=-1).mean() < 0.1 * spread


def test_members_trained_in_worker_processes_have_the_same_weights():
    from blindspot.traj.seq2seq import train_ensemble

    rng = np.random.default_rng(9)
    xy = turning_tracks(rng, 200)
    cfg = replace(CFG, epochs=1, ensemble=2)
    here, _ = train_ensemble(xy[:150], xy[150:], cfg)
    there, _ = train_ensemble(xy[:150], xy[150:], cfg, jobs=2)
    for a, b in zip(here.members, there.members):
        for (k, va), vb in zip(a.net.state_dict().items(), b.net.state_dict().values()):
            assert np.array_equal(va.numpy(), vb.numpy()), k


def test_rotation_augmentation_turns_track_future_and_neighbour_vectors_alike():
    """``_rotate_batch``: each scene's points and its neighbours' relative positions and steps
    turn by the scene's own angle; the presence flag does not move."""
    import torch

    from blindspot.traj.seq2seq import _rotate_batch

    rng = np.random.default_rng(10)
    x, y = torch.tensor(rng.normal(size=(3, 8, 2))), torch.tensor(rng.normal(size=(3, 12, 2)))
    s = torch.tensor(rng.normal(size=(3, 2, 8, 5)))
    th = torch.tensor([0.3, -2.0, np.pi], dtype=torch.float64)
    xr, yr, sr = _rotate_batch(x, y, s, th)
    for b in range(3):
        R = _rot(float(th[b]))
        np.testing.assert_allclose(xr[b].numpy(), x[b].numpy() @ R.T, atol=1e-12)
        np.testing.assert_allclose(yr[b].numpy(), y[b].numpy() @ R.T, atol=1e-12)
        for cols in (slice(0, 2), slice(2, 4)):
            np.testing.assert_allclose(sr[b][..., cols].numpy(), s[b][..., cols].numpy() @ R.T,
                                       atol=1e-12)
        np.testing.assert_array_equal(sr[b][..., 4].numpy(), s[b][..., 4].numpy())
    assert _rotate_batch(x, y, None, th)[2] is None


def test_scale_augmentation_scales_track_future_and_neighbour_vectors_alike():
    """``_scale_batch``: each scene's points and its neighbours' relative positions and steps
    are multiplied by the scene's own factor (a walker of another speed on a path of the same
    shape); the presence flag is not; a config with ``scale_aug`` trains bit for bit the same
    twice and differs from one without."""
    import torch

    from blindspot.traj.seq2seq import _scale_batch

    rng = np.random.default_rng(11)
    x, y = torch.tensor(rng.normal(size=(3, 8, 2))), torch.tensor(rng.normal(size=(3, 12, 2)))
    s = torch.tensor(rng.normal(size=(3, 2, 8, 5)))
    k = torch.tensor([0.8, 1.0, 1.3], dtype=torch.float64)
    xs, ys, ss = _scale_batch(x, y, s, k)
    for b in range(3):
        np.testing.assert_allclose(xs[b].numpy(), x[b].numpy() * float(k[b]), atol=1e-12)
        np.testing.assert_allclose(ys[b].numpy(), y[b].numpy() * float(k[b]), atol=1e-12)
        np.testing.assert_allclose(ss[b][..., :4].numpy(), s[b][..., :4].numpy() * float(k[b]),
                                   atol=1e-12)
        np.testing.assert_array_equal(ss[b][..., 4].numpy(), s[b][..., 4].numpy())
    assert _scale_batch(x, y, None, k)[2] is None
    xy = turning_tracks(np.random.default_rng(12), 200)
    cfg = replace(CFG, scale_aug=0.2, epochs=1)
    one, two = (train_seq2seq(xy[:150], xy[150:], cfg)[0] for _ in range(2))
    plain = train_seq2seq(xy[:150], xy[150:], replace(cfg, scale_aug=0.0))[0]
    obs = xy[150:, :8]
    np.testing.assert_array_equal(one.predict(obs, 12), two.predict(obs, 12))
    assert not np.array_equal(one.predict(obs, 12), plain.predict(obs, 12))


def test_a_damaged_ensemble_file_is_named(tmp_path):
    import torch

    cfg = replace(CFG, cell="lstm")
    Seq2SeqEnsemble([Seq2SeqModel(Seq2SeqNet(cfg), cfg) for _ in range(2)]).save(tmp_path / "e.pt")
    blob = torch.load(tmp_path / "e.pt", weights_only=True)
    blob["state_dicts"] = blob["state_dicts"][:1]              # a member's weights lost
    torch.save(blob, tmp_path / "cut.pt")
    with pytest.raises(ValueError, match="cut.pt: a damaged Seq2SeqEnsemble file.*2 configs"):
        Seq2SeqEnsemble.load(tmp_path / "cut.pt")


@pytest.mark.parametrize("frame, speed_floor", [("heading", 0.0), ("heading", 0.3),
                                                ("world", 0.3)])
def test_ensemble_moments_taken_in_the_frame_equal_the_members_world_moments(frame, speed_floor):
    """The ensemble frames each track once and takes the mixture's moments in that frame (the
    map to the world is affine, speed scaling included); the members' world-frame forecasts
    mixed directly give the same numbers."""
    import torch

    rng = np.random.default_rng(11)
    cfg = replace(CFG, cell="lstm", frame=frame, speed_floor=speed_floor)
    torch.manual_seed(1)
    members = []
    for _ in range(3):
        net = Seq2SeqNet(cfg)
        with torch.no_grad():
            for p in net.parameters():
                p.normal_(0.0, 0.2)
        members.append(Seq2SeqModel(net, cfg))
    obs = turning_tracks(rng, 40)[:, :cfg.obs_len]
    fc = Seq2SeqEnsemble(members).predict_distribution(obs, 12)
    fcs = [m.predict_distribution(obs, 12) for m in members]
    means = np.stack([f.mean for f in fcs])
    mu = means.mean(0)
    d = means - mu
    cov = np.mean([f.cov for f in fcs], axis=0) + np.einsum("kbhi,kbhj->bhij", d, d) / 3
    np.testing.assert_allclose(fc.mean, mu, atol=1e-12)
    np.testing.assert_allclose(fc.cov, cov, rtol=1e-9, atol=1e-15)


def test_fine_tuning_starts_from_the_pretrained_weights_and_keeps_what_they_learned():
    """A network pre-trained on 3000 arcs, then trained on 40: with a vanishing learning rate it
    still predicts what the pre-trained one does (the weights were loaded, not drawn); with the
    usual one it beats the same 40 arcs trained from scratch on held-out arcs."""
    from blindspot.traj.seq2seq import train_ensemble

    rng = np.random.default_rng(11)
    pre_xy, small, val, test = (turning_tracks(rng, n) for n in (3000, 40, 200, 300))
    pre, _ = train_seq2seq(pre_xy, val, CFG)
    frozen, _ = train_seq2seq(small, val, replace(CFG, epochs=1, lr=1e-12), init=pre)
    np.testing.assert_allclose(frozen.predict(test[:, :8], 12), pre.predict(test[:, :8], 12),
                               atol=1e-5)
    tuned, _ = train_seq2seq(small, val, CFG, init=pre)
    scratch, _ = train_seq2seq(small, val, CFG)
    # a fine-tuning that only wrecks the weights keeps the pre-trained ones (epoch 0)
    wrecked, rep = train_seq2seq(small, val, replace(CFG, epochs=2, lr=50.0), init=pre)
    assert rep.best_epoch == 0 and rep.init_val_ade < min(rep.val_ade)
    assert rep.best_val_ade == rep.init_val_ade            # the weights kept are the init's
    np.testing.assert_array_equal(wrecked.predict(test[:, :8], 12), pre.predict(test[:, :8], 12))

    def ade(m):
        return np.linalg.norm(m.predict(test[:, :8], 12) - test[:, 8:], axis=-1).mean()

    assert ade(tuned) < 0.7 * ade(scratch), (ade(tuned), ade(scratch))
    with pytest.raises(ValueError, match=r"hidden_size \(16, expected 8\)"):
        train_seq2seq(small, val, replace(CFG, hidden_size=8), init=pre)
    # an ensemble fine-tunes member by member, in worker processes to the same bits
    cfg2 = replace(CFG, epochs=1, ensemble=2)
    pre2, _ = train_ensemble(pre_xy[:300], val, cfg2)
    here, _ = train_ensemble(small, val, cfg2, init=pre2)
    there, _ = train_ensemble(small, val, cfg2, init=pre2, jobs=2)
    for a, b in zip(here.members, there.members):
        for (k, va), vb in zip(a.net.state_dict().items(), b.net.state_dict().values()):
            assert np.array_equal(va.numpy(), vb.numpy()), k
    with pytest.raises(ValueError, match="init holds 1 members"):
        train_ensemble(small, val, cfg2, init=Seq2SeqEnsemble([pre]))


def forking_tracks(rng, n, T=20, dt=0.4, fork=8):
    """Straight walks (1.2 m/s, random heading) that after ``fork`` frames turn 90 degrees left
    or right at random (each half the time): a future with two modes."""
    h0 = rng.uniform(0, 2 * np.pi, n)[:, None]
    side = rng.choice([-1.0, 1.0], n)[:, None]
    heading = h0 + np.where(np.arange(T)[None, :] >= fork, side * np.pi / 2, 0.0)
    steps = 1.2 * dt * np.stack([np.cos(heading), np.sin(heading)], axis=-1)
    return rng.uniform(-10, 10, (n, 1, 2)) + np.cumsum(steps, axis=1)


def test_multi_modal_head_finds_both_turns_a_single_path_averages():
    """Left or right at random: one path can only go between them (ADE of the average); the
    mixture's best hypothesis follows the true turn, its weights split about evenly and the
    moment covariance holds the spread between the turns."""
    rng = np.random.default_rng(3)
    train, val, test = forking_tracks(rng, 1500), forking_tracks(rng, 200), forking_tracks(rng, 200)
    cfg = replace(CFG, epochs=6, nll_weight=0.1)
    single, _ = train_seq2seq(train, val, cfg)
    multi, _ = train_seq2seq(train, val, replace(cfg, modes=4))
    obs, fut = test[:, :8], test[:, 8:]
    one = np.linalg.norm(single.predict(obs, 12) - fut, axis=-1).mean()
    mix = multi.predict_mixture(obs, 12)
    from blindspot.traj.mixture import best_of
    best = best_of(mix.means, fut)[0]
    assert best < 0.3 * one, (best, one)        # the left/right average misses by metres
    # the two most probable hypotheses take most of the mass, about half each
    top2 = np.sort(mix.weights, axis=1)[:, -2:]
    assert np.median(top2.sum(1)) > 0.8 and 0.25 < np.median(top2[:, 0]) <= 0.5
    # predict / predict_distribution give the mixture's moments (the point: its mean)
    fc = multi.predict_distribution(obs, 12)
    assert np.allclose(fc.mean, mix.mean()) and np.allclose(fc.cov, mix.moment_cov())
    multi.point = "mode"
    assert np.allclose(multi.predict(obs, 12), mix.most_likely())


def test_multi_modal_model_saves_and_loads_and_a_single_path_has_no_mixture(tmp_path):
    rng = np.random.default_rng(4)
    tracks = forking_tracks(rng, 200)
    multi, _ = train_seq2seq(tracks[:150], tracks[150:], replace(CFG, epochs=1, modes=3))
    path = Seq2SeqEnsemble([multi], name="mix").save(tmp_path / "mix.pt")
    back = Seq2SeqEnsemble.load(path).members[0]
    a, b = multi.predict_mixture(tracks[:5, :8], 12), back.predict_mixture(tracks[:5, :8], 12)
    assert np.array_equal(a.means, b.means) and np.array_equal(a.weights, b.weights)
    single, _ = train_seq2seq(tracks[:150], tracks[150:], replace(CFG, epochs=1))
    with pytest.raises(HistoryError, match="modes"):
        single.predict_mixture(tracks[:5, :8], 12)
    with pytest.raises(ValueError, match="point"):
        Seq2SeqModel(single.net, single.cfg, point="median")


def test_keep_by_best_of_keeps_the_epoch_of_the_best_hypotheses_and_wta_score_counts_the_end():
    """keep_by="best_of": the val ADE recorded per epoch (and the epoch kept) is that of each
    window's best hypothesis, recomputed here from the kept model; keep_by="mean" records the
    mixture mean's. wta_score="ade_fde" picks the winner by ADE + FDE."""
    rng = np.random.default_rng(5)
    tracks = forking_tracks(rng, 300)
    train, val = tracks[:240], tracks[240:]
    cfg = replace(CFG, epochs=3, modes=3)
    best, fit_b = train_seq2seq(train, val, replace(cfg, keep_by="best_of"))
    mean, fit_m = train_seq2seq(train, val, cfg)
    from blindspot.traj.mixture import best_of
    hyp = best.predict_mixture(val[:, :8], 12).means
    assert fit_b.val_ade[fit_b.best_epoch - 1] == pytest.approx(best_of(hyp, val[:, 8:])[0])
    assert min(fit_b.val_ade) == fit_b.val_ade[fit_b.best_epoch - 1]
    one = np.linalg.norm(mean.predict(val[:, :8], 12) - val[:, 8:], axis=-1).mean()
    assert fit_m.val_ade[fit_m.best_epoch - 1] == pytest.approx(one)
    # the same seed and data: the recorded curves differ only by what is measured
    assert all(b < m for b, m in zip(fit_b.val_ade, fit_m.val_ade))
    # two hypotheses of a 2-step window: A nearer on average (ADE 0.5, FDE 1.0), B nearer
    # at the end (ADE 0.55, FDE 0.4); the loss reports its winner's ADE
    import torch
    from blindspot.traj.seq2seq import _loss
    out = torch.zeros(1, 2, 2, 5)
    out[0, 0, :, 0] = torch.tensor([0.0, 1.0])
    out[0, 1, :, 0] = torch.tensor([0.7, 0.4])
    two = replace(cfg, horizon=2, modes=2, nll_weight=0.0, outputs="position", loss="ade")
    zero = torch.zeros(1, 2, 2)
    for score, ade_won in (("ade", 0.5), ("ade_fde", 0.55)):
        _, won = _loss((out, torch.zeros(1, 2)), zero, zero, replace(two, wta_score=score))
        assert float(won) == pytest.approx(ade_won)
    # one hypothesis: its best is its mean (the same model and record as keep_by="mean")
    one_b, fit_1b = train_seq2seq(train, val, replace(CFG, epochs=2, keep_by="best_of"))
    one_m, fit_1m = train_seq2seq(train, val, replace(CFG, epochs=2))
    assert fit_1b.val_ade == fit_1m.val_ade
    with pytest.raises(ValueError, match="keep_by"):
        replace(cfg, keep_by="last")
    with pytest.raises(ValueError, match="wta_score"):
        replace(cfg, wta_score="fde")


def test_transformer_encoder_learns_the_turn():
    """Self-attention over the observed steps: well below constant velocity on circle arcs
    after three epochs (its symmetries: test_predictions_rotate_translate_and_mirror...)."""
    rng = np.random.default_rng(20)
    train, val, test = turning_tracks(rng, 3000), turning_tracks(rng, 500), turning_tracks(rng, 300)
    model, _ = train_seq2seq(train, val, replace(CFG, cell="transformer", attention_heads=4))
    obs = test[:, :8]
    err, cv_err = (np.linalg.norm(p - test[:, 8:], axis=-1).mean()
                   for p in (model.predict(obs, 12), ConstantVelocity().predict(obs, 12)))
    assert err < 0.5 * cv_err, (err, cv_err)


def test_transformer_layers_start_from_their_own_draws():
    """torch copies one encoder layer into all of them; each starts from its own weights,
    initialised as a fresh layer is (the attention's output bias zero)."""
    net = Seq2SeqNet(replace(CFG, cell="transformer", num_layers=3))
    layers = list(net.encoder.layers)
    for a, b in zip(layers, layers[1:]):
        assert not torch.equal(a.self_attn.in_proj_weight, b.self_attn.in_proj_weight)
        assert not torch.equal(a.linear1.weight, b.linear1.weight)
    for layer in layers:
        assert not layer.self_attn.out_proj.bias.any()


def _shaped_walks(rng, n, shape):
    """Straight walks whose future leaves constant velocity by ``a x shape`` (heading frame,
    (12, 2)), ``a`` set by the walker's observed speed: the deviations span exactly one
    direction, and the history tells how far along it."""
    speed = rng.uniform(0.8, 1.6, n)
    h = rng.uniform(0, 2 * np.pi, n)
    fwd = np.stack([np.cos(h), np.sin(h)], axis=-1)                    # (n, 2)
    left = np.stack([-np.sin(h), np.cos(h)], axis=-1)
    t = np.arange(20) * 0.4
    xy = (speed[:, None, None] * t[None, :, None]) * fwd[:, None, :]
    a = 3.0 * (speed - 1.2)
    dev = a[:, None, None] * shape[None]                                # (n, 12, 2) framed
    xy[:, 8:] += dev[..., :1] * fwd[:, None, :] + dev[..., 1:] * left[:, None, :]
    return xy + rng.uniform(-10, 10, (n, 1, 2))


def test_motion_basis_spans_the_training_deviations_and_bounds_the_predictions():
    """Walks leave constant velocity along one known shape only: a rank-1 basis set from them
    is that shape (up to sign), a trained rank-1 model's framed offsets have rank 1 and it
    learns the shape, as the unconstrained head does (each within a tenth of constant
    velocity's error)."""
    rng = np.random.default_rng(21)
    k = np.arange(1, 13) / 12
    shape = np.stack([-0.3 * k**2, 0.8 * k**2], axis=-1)              # a slowing left turn
    train, val, test = (_shaped_walks(rng, n, shape) for n in (3000, 500, 300))
    cfg = replace(CFG, basis_rank=1, mirror=False, epochs=10, lr=1e-2)
    model, _ = train_seq2seq(train, val, cfg)
    g = shape.ravel() / np.linalg.norm(shape)
    assert abs(model.net.basis[:, 0].numpy() @ g) > 0.999
    basis = model.net.basis.numpy()
    np.testing.assert_allclose(basis.T @ basis, np.eye(1), atol=1e-6)
    x, soc, _, _ = _framed_inputs(test[:, :8], None, cfg)
    out = model._net_out(x, soc).numpy()                           # framed offsets
    sv = np.linalg.svd(out[..., :2].reshape(300, -1), compute_uv=False)
    assert sv[1] < 1e-5 * sv[0], sv[:3]
    free, _ = train_seq2seq(train, val, replace(cfg, basis_rank=0))
    err = [np.linalg.norm(m.predict(test[:, :8], 12) - test[:, 8:], axis=-1).mean()
           for m in (model, free)]
    cv = np.linalg.norm(ConstantVelocity().predict(test[:, :8], 12) - test[:, 8:],
                        axis=-1).mean()
    assert max(err) < 0.1 * cv, (err, cv)


def test_motion_basis_saves_loads_and_its_bad_settings_are_named(tmp_path):
    from blindspot.typed_config import ConfigError

    rng = np.random.default_rng(22)
    xy = turning_tracks(rng, 300)
    cfg = replace(CFG, cell="transformer", basis_rank=3, epochs=1)
    ens = Seq2SeqEnsemble([train_seq2seq(xy[:200], xy[200:], cfg)[0]])
    back = Seq2SeqEnsemble.load(ens.save(tmp_path / "basis.pt"))
    assert np.array_equal(ens.predict(xy[200:, :8], 12), back.predict(xy[200:, :8], 12))
    assert np.count_nonzero(back.members[0].net.basis.numpy()) > 0
    with pytest.raises(ConfigError, match="basis_rank.*at most 2 x horizon"):
        replace(CFG, basis_rank=25)
    with pytest.raises(ConfigError, match="basis_rank.*outputs is position"):
        replace(CFG, basis_rank=2, outputs="displacement")
    with pytest.raises(ConfigError, match="basis_rank.*rotation_deg > 0"):
        replace(CFG, basis_rank=2, rotation_deg=10.0)
    with pytest.raises(ConfigError, match="attention_heads.*divisor of hidden_size"):
        replace(CFG, cell="transformer", attention_heads=3)
    net = Seq2SeqNet(replace(CFG, basis_rank=2))
    with pytest.raises(ValueError, match="set_basis: deviations: expected at least basis_rank"):
        net.set_basis(np.zeros((1, 12, 2)))
    with pytest.raises(ValueError, match=r"set_basis: deviations: expected shape \(N, 12, 2\)"):
        net.set_basis(np.zeros((3, 11, 2)))
    with pytest.raises(ValueError, match="deviations: expected finite values.*found nan"):
        net.set_basis(np.where(np.arange(120).reshape(5, 12, 2) == 7, np.nan, 0.0))
    with pytest.raises(ValueError, match="set_basis: expected cfg.basis_rank > 0, found 0"):
        Seq2SeqNet(CFG).set_basis(np.zeros((5, 12, 2)))
    x, y = xy[:, :8], xy[:, 8:]
    with pytest.raises(ValueError, match="base_deviations: x"):
        base_deviations(x[:, :7], y, CFG)
    with pytest.raises(ValueError, match="base_deviations: y"):
        base_deviations(x, y[:5], CFG)


def test_motion_basis_of_mirrored_training_is_mirror_symmetric_and_bounds_every_hypothesis():
    """With mirrored copies the basis spans mirrored paths too (M B = B B^T M B), and with M
    hypotheses each one's framed offsets lie in the span (nothing left outside it)."""
    rng = np.random.default_rng(23)
    xy = turning_tracks(rng, 600)
    cfg = replace(CFG, modes=3, basis_rank=4, mirror=True, epochs=2)
    model, _ = train_seq2seq(xy[:500], xy[500:], cfg)
    b = model.net.basis.numpy().astype(float)
    np.testing.assert_allclose(b.T @ b, np.eye(4), atol=1e-5)
    mirror = np.diag(np.tile([1.0, -1.0], 12))
    np.testing.assert_allclose(mirror @ b, b @ b.T @ mirror @ b, atol=1e-5)
    x, soc, _, _ = _framed_inputs(xy[500:, :8], None, cfg)
    hyp = model._net_out(x, soc)[0].numpy()[..., :2].reshape(100, 3, 24)
    assert np.abs(hyp).max() > 1e-3                                  # the head did learn
    np.testing.assert_allclose(hyp - hyp @ b @ b.T, 0.0, atol=1e-5)


def test_fine_tuning_keeps_the_pretrained_basis():
    rng = np.random.default_rng(24)
    a, b = turning_tracks(rng, 300), turning_tracks(rng, 300) * [1.0, 3.0]
    cfg = replace(CFG, basis_rank=2, epochs=1)
    pre, _ = train_seq2seq(a[:200], a[200:], cfg)
    tuned, _ = train_seq2seq(b[:200], b[200:], cfg, init=pre)
    fresh, _ = train_seq2seq(b[:200], b[200:], cfg)
    assert torch.equal(tuned.net.basis, pre.net.basis)
    assert not torch.allclose(fresh.net.basis, pre.net.basis, atol=1e-3)
    with pytest.raises(ValueError, match=r"init: made with another basis_rank \(2, expected 3\)"):
        train_seq2seq(b[:200], b[200:], replace(cfg, basis_rank=3), init=pre)


def test_fine_tuning_a_recurrent_encoder_ignores_the_attention_heads():
    """attention_heads shapes only a transformer: an LSTM made with another value fine-tunes."""
    rng = np.random.default_rng(25)
    xy = turning_tracks(rng, 200)
    cfg = replace(CFG, cell="lstm", epochs=1)
    pre, _ = train_seq2seq(xy[:150], xy[150:], replace(cfg, attention_heads=2))
    tuned, _ = train_seq2seq(xy[:150], xy[150:], cfg, init=pre)
    assert tuned.cfg.attention_heads == 4
    with pytest.raises(ValueError, match="init: made with another attention_heads"):
        train_seq2seq(xy[:150], xy[150:], replace(cfg, cell="transformer"),
                      init=train_seq2seq(xy[:150], xy[150:], replace(
                          cfg, cell="transformer", attention_heads=2))[0])
