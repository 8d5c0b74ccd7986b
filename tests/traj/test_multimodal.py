"""The multi-modal predictor the safety chain can use (blindspot.traj.multimodal)."""

from dataclasses import replace

import numpy as np
import pytest

from blindspot.traj.config import Seq2SeqConfig
from blindspot.traj.multimodal import MultiModalPredictor
from blindspot.traj.predictor import HistoryError
from blindspot.traj.seq2seq import Seq2SeqEnsemble, Seq2SeqModel, Seq2SeqNet

CFG = Seq2SeqConfig(cell="mlp", hidden_size=8, head_hidden=16, ensemble=1, threads=1,
                    neighbours=0, modes=3)


def _member(seed: int) -> Seq2SeqModel:
    import torch

    torch.manual_seed(seed)
    net = Seq2SeqNet(CFG)
    with torch.no_grad():             # a head that is not all zeros: hypotheses that differ
        for p in net.head.parameters():
            p.normal_(0.0, 0.3)
    return Seq2SeqModel(net, replace(CFG, seed=seed), "mix")


def _tracks(n=4):
    rng = np.random.default_rng(0)
    return np.cumsum(rng.normal(0.4, 0.1, (n, 8, 2)), axis=1)


def test_members_are_pooled_with_equal_shares_and_the_gaussian_is_the_second_moment():
    a, b = _member(0), _member(1)
    pred = MultiModalPredictor(Seq2SeqEnsemble([a, b], name="mix"))
    obs = _tracks()
    mix = pred.predict_mixture(obs, 12)
    ma, mb = a.predict_mixture(obs, 12), b.predict_mixture(obs, 12)
    assert mix.modes == 6 and np.allclose(mix.weights.sum(1), 1.0)
    assert np.allclose(mix.weights[:, :3], ma.weights / 2)
    assert np.allclose(mix.means[:, 3:], mb.means)
    assert np.allclose(mix.mean(), (ma.mean() + mb.mean()) / 2)     # mean of the members' means
    fc = pred.predict_distribution(obs, 12)
    assert np.allclose(fc.mean, mix.mean()) and np.allclose(fc.cov, mix.moment_cov())
    mode = MultiModalPredictor(Seq2SeqEnsemble([a, b]), point="mode",
                               step_scale=np.full(12, 4.0))
    assert np.allclose(mode.predict(obs, 12), mix.most_likely())
    fc4 = mode.predict_distribution(obs, 5)
    assert np.allclose(fc4.cov, 4.0 * mix.truncated(5).second_moment(mix.most_likely()[:, :5]))


def test_bad_arguments_are_named():
    single = Seq2SeqModel(Seq2SeqNet(replace(CFG, modes=1)), replace(CFG, modes=1))
    with pytest.raises(HistoryError, match="modes"):
        MultiModalPredictor(Seq2SeqEnsemble([single]))
    ens = Seq2SeqEnsemble([_member(0)])
    with pytest.raises(HistoryError, match="point"):
        MultiModalPredictor(ens, point="median")
    with pytest.raises(HistoryError, match="step_scale"):
        MultiModalPredictor(ens, step_scale=np.array([1.0, -1.0]))
    with pytest.raises(HistoryError, match="step_scale holds 2 steps"):
        MultiModalPredictor(ens, step_scale=np.ones(2)).predict_distribution(_tracks(), 3)
