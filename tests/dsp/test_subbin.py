"""Sub-bin range against theory: Grandke's closed form for Hann, exact recovery of a noise-free
off-grid tone for every window, the Cramer-Rao bound of a tone in noise (Rife & Boorstyn 1974),
and a simulated point target through the whole chain (range-Doppler coupling included)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from omegaconf import OmegaConf

from blindspot.dsp.config import WINDOW_NAMES
from blindspot.dsp.range_doppler import window
from blindspot.dsp.subbin import IpdftTable, SubbinError, ipdft_table, peak_offset
from tests.dsp._synth import mmwcas

N = 256


def tone_spectrum(name: str, f_bins: float, n: int = N, amp: complex = 1.0, noise=None):
    """Windowed DFT of amp exp(j 2 pi f n / N) (+ complex noise samples)."""
    s = amp * np.exp(2j * np.pi * f_bins * np.arange(n) / n)
    if noise is not None:
        s = s + noise
    return np.fft.fft(window(name, n) * s, axis=-1)


def three(x: np.ndarray, k: int):
    a = np.abs(x)
    return a[..., k - 1], a[..., k], a[..., k + 1]


def test_hann_table_is_grandkes_closed_form():
    """Hann: delta = 2 (|X+| - |X-|) / (|X-| + 2 |X0| + |X+|) (Grandke 1983), the table agrees
    to 1e-6 bin and the closed form itself recovers off-grid tones to 1e-4 bin at N = 256."""
    t = ipdft_table("hann", N)
    np.testing.assert_allclose(t.ratio, t.delta / 2, atol=1e-6)
    for f in (40.0, 40.13, 40.37, 40.5, 39.71):
        lo, mid, hi = three(tone_spectrum("hann", f), int(round(f)) if f != 40.5 else 40)
        closed = 2 * (hi - lo) / (lo + 2 * mid + hi)
        assert closed == pytest.approx(f - (int(round(f)) if f != 40.5 else 40), abs=1e-4)


@settings(max_examples=25, deadline=None)
@given(delta=st.floats(-0.5, 0.5), k=st.integers(3, N - 4), name=st.sampled_from(WINDOW_NAMES),
       phase=st.floats(0, 2 * np.pi))
def test_noise_free_off_grid_tone_is_recovered_for_every_window(delta, k, name, phase):
    x = tone_spectrum(name, k + delta, amp=np.exp(1j * phase))
    est = peak_offset(*three(x, k), name, N)
    assert est == pytest.approx(delta, abs=2e-3)


def test_variance_against_the_cramer_rao_bound():
    """2000 noisy tones (post-FFT SNR 30 dB for a rectangular window), off-grid offsets: the
    estimate is unbiased and its variance lies between the CRB (Rife & Boorstyn 1974:
    var(f) >= 6 / ((2 pi)^2 SNR N (N^2 - 1)) cycles/sample, times N^2 in bins) and 5 times it
    (measured 4.0x: Hann's 1.76 dB processing loss and the three-bin estimator's own loss; an
    estimate below the bound would be a bug). In metres on the MMWCAS profile at this SNR:
    0.012 m RMS, against 0.144 m RMS for the bin alone."""
    rng = np.random.default_rng(1)
    trials, snr = 2000, 1000.0 / N                       # per-sample SNR
    delta = rng.uniform(-0.4, 0.4, trials)
    k = 60
    noise = np.sqrt(1 / (2 * snr)) * (rng.standard_normal((trials, N))
                                      + 1j * rng.standard_normal((trials, N)))
    s = np.exp(2j * np.pi * (k + delta)[:, None] * np.arange(N) / N) + noise
    x = np.fft.fft(window("hann", N) * s, axis=-1)
    est = peak_offset(*three(x, k), "hann", N)
    err = est - delta
    crb = 6 * N ** 2 / ((2 * np.pi) ** 2 * snr * N * (N ** 2 - 1))
    assert abs(err.mean()) < 4 * np.sqrt(crb / trials) + 1e-3
    assert crb < err.var() < 5 * crb, (err.var() / crb)


def test_offsets_clip_and_bad_input():
    t = ipdft_table("hann", N)
    assert t.offset(np.array([0.0]), np.array([0.0]), np.array([0.0]))[0] == 0.0
    assert t.offset(np.array([0.0]), np.array([1.0]), np.array([5.0]))[0] == 0.5  # not a peak
    with pytest.raises(SubbinError, match="magnitudes"):
        t.offset(np.array([1.0, 2.0]), np.array([1.0]), np.array([1.0]))
    with pytest.raises(SubbinError, match="left"):
        t.offset(np.array([-1.0]), np.array([1.0]), np.array([1.0]))
    with pytest.raises(SubbinError, match="window"):
        IpdftTable(np.ones(2))


@pytest.fixture(scope="module")
def chain():
    from blindspot.dsp.chain import DetectionChain
    from tests.conftest import REPO_ROOT

    radar, arr = mmwcas()
    load = lambda g, n: OmegaConf.load(REPO_ROOT / "conf" / g / f"{n}.yaml")  # noqa: E731
    return DetectionChain.from_config(radar, arr, load("cfar", "paper"), load("doa", "music"),
                                      load("detect", "paper"))


@pytest.mark.parametrize(("range_m", "v_mps"), [(7.13, 1.2), (7.13, -1.2), (10.37, 0.5)])
def test_simulated_point_target_off_grid_range(chain, range_m, v_mps):
    """The project's FMCW simulator (beat frequency 2 S R / c + 2 v / lambda), one point target
    between range bins: the chain's range is within 1 cm (0.02 bin) of the truth, where the
    bin alone is up to 25 cm off and the beat frequency without the coupling term 9 mm."""
    from blindspot.radar.simulator import FmcwSimulator, frame_bit_generator

    sim = FmcwSimulator(chain.radar, chain.array, noise=True, adc_headroom_db=60.0)
    th = np.radians(10.0)
    pos = np.array([[range_m * np.sin(th), range_m * np.cos(th), 0.0]])
    vel = np.array([[v_mps * np.sin(th), v_mps * np.cos(th), 0.0]])
    cube = np.empty(sim.shape, dtype=np.complex64)
    sim.frame(pos, vel, np.array([1.0]), out=cube, bit_generator=frame_bit_generator(3, 0))
    det = chain.process(cube, keep_spectrum=False).detections.iloc[0]
    assert det.range_m == pytest.approx(range_m, abs=0.01)
    assert abs(det.range_bin * chain.radar.range_bin_m - range_m) > 0.05  # truly off the grid
