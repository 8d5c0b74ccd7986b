"""The range-Doppler-angle peak rule (blindspot.dsp.detections.angle_peaks) and the moving-car
chain's ``ego_motion.peak_search`` (blindspot.dsp.driving.DrivingChain).

Truth used: the FMCW tone model of tests/dsp/_synth.py (written apart from the chain): a point
target's return leaks into the neighbouring range bin at the range window's response (-6 dB
for Hann at one bin), so a weak target one bin from a strong one at the same Doppler is not a
local maximum of the range-Doppler map; at its own angle, the strong target's beam is far down
its sidelobes, so it is one in range, Doppler and angle together.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig, EgoMotionConfig
from blindspot.radar.config import RadarConfig
from blindspot.config import compose
from blindspot.dsp.detections import DetectionError, angle_peaks
from blindspot.dsp.driving import DrivingChain
from blindspot.radar.array import array_for

from ._synth import tone_cube

N_EL = 86                      # the MMWCAS cascade's azimuth ULA


def _beam_snapshots(cells: list[list[tuple[float, float]]]) -> np.ndarray:
    """(1, N_EL, L) noiseless snapshots: cell l holds plane waves (angle deg, amplitude) on a
    half-wavelength ULA."""
    pos = np.arange(N_EL) * 0.5
    x = np.zeros((1, N_EL, len(cells)), np.complex128)
    for l, waves in enumerate(cells):  # noqa: E741
        for ang, amp in waves:
            x[0, :, l] += amp * np.exp(2j * np.pi * pos * np.sin(np.radians(ang)))
    return x


def test_a_weak_target_on_the_flank_of_a_strong_one_at_another_angle_is_a_peak():
    strong, weak = (20.0, 30.0), (-10.0, 1.0)
    # cell 1 is the strong target's own cell, cell 0 its flank (-6 dB) holding the weak target
    flank = [(20.0, 15.0), weak]
    x = _beam_snapshots([flank, [strong], [(20.0, 15.0)]])
    keep, angle = angle_peaks(x, centre=0, spacing_wl=0.5)
    assert keep[0] and angle[0] == pytest.approx(-10.0, abs=0.1)   # the weak one's own angle
    keep, angle = angle_peaks(x, centre=1, spacing_wl=0.5)         # the strong one's own cell
    assert keep[0] and angle[0] == pytest.approx(20.0, abs=0.1)
    keep, angle = angle_peaks(x, centre=2, spacing_wl=0.5)         # a pure flank cell
    assert not keep[0] and np.isnan(angle[0])
    # the total power (the 2-D rule's measure) ranks the flank cell below the strong cell
    power = (np.abs(x[0]) ** 2).sum(0)
    assert power[0] < power[1]


def test_the_weak_target_is_lost_when_it_shares_the_strong_ones_angle():
    x = _beam_snapshots([[(20.0, 15.0), (20.5, 1.0)], [(20.0, 30.0)]])
    assert not angle_peaks(x, centre=0, spacing_wl=0.5)[0][0]


def test_noise_alone_does_not_make_a_flank_cell_a_peak():
    # flank cells of one strong target plus noise 40 dB below it: the noise finds angles where
    # the flank cell beats its neighbours, the margin over the beam's median refuses almost all
    # (what passes sits by the nulls of the target's sidelobe pattern, where all three cells
    # hold noise and the flank's own sidelobe residual)
    rng = np.random.default_rng(0)
    x = np.repeat(_beam_snapshots([[(20.0, 15.0)], [(20.0, 30.0)], [(20.0, 15.0)]]), 2000, 0)
    x += 0.3 * (rng.standard_normal(x.shape) + 1j * rng.standard_normal(x.shape))
    keep, _ = angle_peaks(x, centre=0, spacing_wl=0.5)
    assert keep.mean() < 0.01
    assert angle_peaks(x, centre=0, spacing_wl=0.5, margin_db=0.0)[0].mean() > 0.5


def test_bad_input_names_what_was_expected():
    x = _beam_snapshots([[(0.0, 1.0)], [(0.0, 1.0)]])
    with pytest.raises(DetectionError, match="centre must be an integer index of the 2"):
        angle_peaks(x, centre=2, spacing_wl=0.5)
    with pytest.raises(DetectionError, match="centre must be an integer index"):
        angle_peaks(x, centre=0.5, spacing_wl=0.5)
    with pytest.raises(DetectionError, match="must be complex"):
        angle_peaks(x.real, centre=0, spacing_wl=0.5)
    with pytest.raises(DetectionError, match="n_fft must be >= the 86 elements"):
        angle_peaks(x, centre=0, spacing_wl=0.5, n_fft=64)
    with pytest.raises(DetectionError, match="spacing_wl must be a positive"):
        angle_peaks(x, centre=0, spacing_wl=0.0)
    with pytest.raises(DetectionError, match="snapshots"):
        angle_peaks(np.ones((3, 4)), centre=0, spacing_wl=0.5)
    keep, angle = angle_peaks(np.zeros((0, N_EL, 9), np.complex64), centre=0, spacing_wl=0.5)
    assert keep.shape == angle.shape == (0,)


@pytest.fixture(scope="module")
def chains():
    cfg = compose([])
    radar = RadarConfig.from_cfg(cfg, "driving_radar")
    array = array_for(radar)
    ego = EgoMotionConfig.from_cfg(cfg)

    def chain(rule: str) -> DrivingChain:
        return DrivingChain(radar, array, CfarConfig.from_cfg(cfg, "driving_cfar"), DoaConfig.from_cfg(cfg),
                            DetectConfig.from_cfg(cfg), replace(ego, peak_search=rule))
    return radar, array, chain("range_doppler"), chain("range_doppler_angle")


@pytest.mark.parametrize("order", [0, -1, -2])
def test_driving_chain_keeps_a_child_beside_a_parked_car_only_with_the_angle_rule(chains, order):
    """At 10 km/h and above the static world's Doppler wraps (v_max 5.4 m/s): ``order`` is the
    ambiguity order of the car and the child, the ego's odometry the speed at which the car is
    static; the TX slots must be compensated with the unwrapped velocity, or the car's beam
    splits into lobes that mask the child."""
    radar, array, rd_chain, rda_chain = chains
    axis_r, axis_v = rd_chain.base.range_axis_m, rd_chain.base.velocity_axis_mps
    k0 = int(np.searchsorted(axis_r, 12.0))
    d0 = int(np.searchsorted(axis_v, 1.0))
    v = axis_v[d0] + 2 * radar.max_velocity_mps * order
    odo = 0.0 if order == 0 else -v / np.cos(np.radians(20.0))
    car = (axis_r[k0], v, 20.0, 30.0)
    child = (axis_r[k0 + 1], v, -10.0, 1.0)                    # one range bin further, 30 dB down
    cube = tone_cube(radar, array, [car, child], noise_power=1e-4,
                     rng=np.random.default_rng(3))[None]
    found = {}
    for name, ch in (("rd", rd_chain), ("rda", rda_chain)):
        det = ch.process_batch(cube, np.full(1, odo), np.zeros(1, np.int64)).detections
        near = lambda ang: det[(np.abs(det.angle_deg - ang) < 1.0)  # noqa: E731
                               & (np.abs(det.range_m - axis_r[k0]) < 1.5)]
        found[name] = (len(near(car[2])), len(near(child[2])))
    assert found["rd"] == (1, 0)           # the 3 x 3 rule drops the child's cell
    assert found["rda"] == (1, 1)          # one detection each, the car's flank cells dropped
