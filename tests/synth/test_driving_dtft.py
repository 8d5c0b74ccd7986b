"""The fast driving measurement's interpolated windowed DTFT
(blindspot.synth.driving_measurement._tone_dft_interpolated), which the range-Doppler-angle
rule's snapshots of every CFAR cell use instead of the exact sum.

Truth used: blindspot.radar.rd_patch.tone_dft, the exact windowed DFT of a unit tone (itself
tested equal to numpy's FFT of the windowed tone)."""

from __future__ import annotations

import numpy as np
import pytest

from blindspot.dsp.range_doppler import window
from blindspot.radar.rd_patch import tone_dft
from blindspot.synth.driving_measurement import _dtft_table, _tone_dft_interpolated


@pytest.mark.parametrize("name,n", [("hann", 256), ("hann", 64), ("rect", 64),
                                    ("blackmanharris", 256), ("hamming", 128)])
def test_interpolated_dtft_equals_the_exact_sum_to_1e_4_of_the_peak(name, n):
    w = window(name, n)
    rng = np.random.default_rng(7)
    nu = rng.uniform(-2.0, 2.0, 2000)                        # aliases wrap
    first = np.floor(nu * n).astype(np.int64) + rng.integers(-4, 3, nu.size)
    exact = tone_dft(nu, first, 3, w)                        # (T, 3), main lobe and flanks
    fast = _tone_dft_interpolated(_dtft_table(w), n, nu[:, None], first[:, None] + np.arange(3))
    assert np.abs(fast - exact).max() < 1e-4 * w.sum()
    # a table lookup without the linear phase taken out would be off by a whole radian
    assert np.abs(np.angle(fast[np.abs(exact) > 0.1 * w.sum()]
                           / exact[np.abs(exact) > 0.1 * w.sum()])).max() < 1e-3
