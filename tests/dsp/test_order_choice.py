"""The Doppler ambiguity order choice of the driving chain (blindspot.dsp.driving): skipping the
scans of orders that cannot win gives the choice of scanning every order, and the Bartlett
scan's chunking does not change its angles."""

from __future__ import annotations

import numpy as np
import pytest

from blindspot.config import compose
from blindspot.dsp import driving
from blindspot.dsp.chain import DetectionChain
from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig
from blindspot.dsp.doa import steering_matrix
from blindspot.radar.array import array_for
from blindspot.radar.config import RadarConfig


@pytest.fixture(scope="module")
def chain():
    cfg = compose([])
    radar = RadarConfig.from_cfg(cfg, "driving_radar")
    return DetectionChain.from_config(radar, array_for(radar),
                                      CfarConfig.from_cfg(cfg, "driving_cfar"),
                                      DoaConfig.from_cfg(cfg), DetectConfig.from_cfg(cfg))


def _snapshots(chain, rng, n: int) -> np.ndarray:
    """(n, E, 9) snapshots: one source at a random angle, random phases over the cells, noise."""
    theta = rng.uniform(-75, 75, n)
    a = steering_matrix(chain.ula_pos, theta).T                                # (n, E)
    s = np.exp(2j * np.pi * rng.random((n, 1, 9)))
    noise = rng.normal(size=(n, a.shape[1], 9, 2)).view(complex)[..., 0]
    return a[:, :, None] * s * rng.uniform(0.5, 5.0, (n, 1, 1)) + noise


@pytest.mark.parametrize("seed", range(4))
def test_skipping_orders_that_cannot_win_keeps_every_choice(chain, seed):
    rng = np.random.default_rng(seed)
    n = 300
    v_max = chain.radar.max_velocity_mps
    ula = _snapshots(chain, rng, n)
    v_w = rng.uniform(-v_max, v_max, n)
    odo = rng.uniform(0.0, 17.0, n)                     # the ego speeds of the draws, m/s
    scan = lambda comp: driving._bartlett_angles(comp, chain)   # noqa: E731
    got = driving._choose_order(ula, v_w, odo, chain, v_max, scan, driving.ORDER_GRID_DEG)
    want = driving._choose_order(ula, v_w, odo, chain, v_max, scan)
    assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
    assert len(set(want[0])) > 1                        # the draw needs more than one order


def test_the_bartlett_scan_in_chunks_equals_one_product(chain, monkeypatch):
    rng = np.random.default_rng(5)
    comp = _snapshots(chain, rng, 700)
    chunked = driving._bartlett_angles(comp, chain)
    monkeypatch.setattr(driving, "BARTLETT_CHUNK", 10 ** 9)
    assert np.array_equal(chunked, driving._bartlett_angles(comp, chain))
