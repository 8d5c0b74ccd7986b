"""FMCW simulator physics, checked with plain numpy FFTs against FMCW theory and the radar
equation (expected values are computed here from the profile's inputs and physical constants,
not from the simulator's helpers)."""

import dataclasses
import hashlib

import numpy as np
import pytest
from omegaconf import OmegaConf

from blindspot.radar.array import array_for
from blindspot.radar.config import RadarConfig
from blindspot.radar.scene import load_scenes
from blindspot.radar.simulator import (
    FmcwSimulator, SimulatedSource, frame_bit_generator, from_int16_iq, quantise, to_int16_iq,
)
from blindspot.radar.source import FrameSource
from tests.conftest import REPO_ROOT

C = 299_792_458.0
K_B = 1.380649e-23
# Physics tests run on the float cube (sqrt(W)); the ADC-code variant is tested on its own.
MMWCAS = {**OmegaConf.to_container(OmegaConf.load(REPO_ROOT / "conf/radar/mmwcas.yaml")), "adc_bits": None}
RADAR = RadarConfig.from_mapping(MMWCAS)
SCENES = load_scenes(OmegaConf.load(REPO_ROOT / "conf/scene/paper.yaml"))

# Independent of blindspot: the paper's numbers and the profile's raw inputs.
LAM = C / (MMWCAS["start_freq_hz"] + MMWCAS["bandwidth_hz"] / 2)       # 77 GHz centre
RANGE_RES = C / (2 * MMWCAS["bandwidth_hz"])                            # 0.5 m
T_CHIRP = MMWCAS["ramp_time_s"] + MMWCAS["idle_time_s"]
T_LOOP = MMWCAS["n_tx"] * T_CHIRP
V_RES = LAM / (2 * MMWCAS["n_chirps"] * T_LOOP)


def target(r_m, v_mps, theta_deg):
    """One scatterer at range r, radial velocity v, azimuth theta (z = 0)."""
    u = np.array([np.sin(np.radians(theta_deg)), np.cos(np.radians(theta_deg)), 0.0])
    return (r_m * u)[None], (v_mps * u)[None]


def range_doppler(cube, hann=False):
    """(chirps, tx, rx, samples) -> (doppler (fftshift), tx, rx, range) 2-D FFT, unwindowed
    unless ``hann`` (Hann windows on both axes, for scenes with strong extended targets)."""
    if hann:
        cube = cube * np.hanning(cube.shape[-1]) * np.hanning(cube.shape[0])[:, None, None, None]
    x = np.fft.fft(cube, axis=-1)
    return np.fft.fftshift(np.fft.fft(x, axis=0), axes=0)


@pytest.mark.parametrize("r_m,v_mps,theta_deg", [(7.3, 1.1, 12.0), (18.2, -2.3, -35.0),
                                                 (4.0, 0.4, 50.0)])
def test_point_target_lands_in_its_range_and_doppler_bins(r_m, v_mps, theta_deg):
    sim = FmcwSimulator(RADAR, noise=False)
    pos, vel = target(r_m, v_mps, theta_deg)
    rd = range_doppler(sim.frame(pos, vel, np.array([1.0])))
    power = (np.abs(rd) ** 2).sum(axis=(1, 2))               # (doppler, range)
    kd, kr = np.unravel_index(np.argmax(power), power.shape)
    assert abs(kr - r_m / RANGE_RES) <= 0.5
    assert abs((kd - RADAR.n_chirps // 2) - v_mps / V_RES) <= 0.5


@pytest.mark.parametrize("theta_deg", [-40.0, -7.5, 0.0, 12.0, 33.0])
def test_phase_across_86_virtual_positions_gives_theta(theta_deg):
    """At the target's range-Doppler cell, remove the TX-slot Doppler phase; the remaining
    phase across the 86-element ULA is 2 pi p sin(theta) (p in wavelengths)."""
    r_m, v_mps = 10.0, 1.2
    sim = FmcwSimulator(RADAR, noise=True)
    pos, vel = target(r_m, v_mps, theta_deg)
    cube = sim.frame(pos, vel, np.array([10.0]), bit_generator=frame_bit_generator(3, 0))
    rd = range_doppler(cube)
    power = (np.abs(rd) ** 2).sum(axis=(1, 2))
    kd, kr = np.unravel_index(np.argmax(power), power.shape)
    arr = array_for(RADAR)
    t_idx, r_idx = arr.ula_index
    snap = rd[kd, t_idx, r_idx, kr]                           # (86,)
    assert snap.shape == (86,)
    slot_phase = 4 * np.pi * v_mps * t_idx * T_CHIRP / LAM    # TX slot = position in firing order
    p = arr.ula_positions_wl

    def fit(x):
        phase = np.unwrap(np.angle(x))
        coef = np.polyfit(p, phase, 1)
        residual = phase - np.polyval(coef, p)
        return np.degrees(np.arcsin(coef[0] / (2 * np.pi))), np.sqrt(np.mean(residual**2))

    theta, rms = fit(snap * np.exp(-1j * slot_phase))
    assert theta == pytest.approx(theta_deg, abs=0.2) and rms < 0.01
    # without the compensation the phase is not linear in position: the TDM phase is there
    assert fit(snap)[1] > 0.1


def test_tx_slot_and_loop_doppler_phase():
    """Between consecutive TX slots of one loop the phase advances by 4 pi v T_chirp / lambda,
    between loops by 4 pi v T_loop / lambda (target on boresight, so no spatial phase)."""
    v = 1.3
    sim = FmcwSimulator(RADAR, noise=False)
    pos, vel = target(9.0, v, 0.0)
    cube = sim.frame(pos, vel, np.array([1.0])).astype(np.complex128)
    step_slot = cube[:, 1:] * np.conj(cube[:, :-1])
    step_loop = cube[1:] * np.conj(cube[:-1])
    err_slot = np.angle(step_slot * np.exp(-1j * 4 * np.pi * v * T_CHIRP / LAM))
    err_loop = np.angle(step_loop * np.exp(-1j * 4 * np.pi * v * T_LOOP / LAM))
    assert np.abs(err_slot).max() < 1e-4 and np.abs(err_loop).max() < 1e-4
    # and the beat tone: phase advance per sample = 2 pi (2 S R / c + 2 v / lambda) / fs
    slope = MMWCAS["bandwidth_hz"] / (MMWCAS["n_samples"] / MMWCAS["adc_rate_hz"])
    f_b = 2 * slope * 9.0 / C + 2 * v / LAM
    step_n = cube[..., 1:] * np.conj(cube[..., :-1])
    assert np.abs(np.angle(step_n * np.exp(-2j * np.pi * f_b / MMWCAS["adc_rate_hz"]))).max() < 1e-4


def expected_snr_db(rcs_m2, r_m):
    """Radar equation + k T0 F f_s + coherent gain of the 2-D FFT, from first principles."""
    p_t = 10 ** (MMWCAS["tx_power_dbm"] / 10) / 1000
    g = 10 ** ((MMWCAS["tx_gain_dbi"] + MMWCAS["rx_gain_dbi"]) / 10)
    p_r = p_t * g * LAM**2 * rcs_m2 / ((4 * np.pi) ** 3 * r_m**4)
    noise = K_B * 290.0 * 10 ** (MMWCAS["noise_figure_db"] / 10) * MMWCAS["adc_rate_hz"]
    return 10 * np.log10(p_r / noise * MMWCAS["n_samples"] * MMWCAS["n_chirps"])


@pytest.mark.parametrize("rcs_m2,bin_r,bin_v", [(1.0, 24, 6), (0.3, 40, -9)])
def test_snr_after_2d_fft_matches_radar_equation(rcs_m2, bin_r, bin_v):
    r_m, v_mps = bin_r * RANGE_RES, bin_v * V_RES           # centred in their bins
    sim = FmcwSimulator(RADAR, noise=True)
    pos, vel = target(r_m, v_mps, 20.0)
    cube = sim.frame(pos, vel, np.array([rcs_m2]), bit_generator=frame_bit_generator(11, bin_r))
    p = np.abs(range_doppler(cube)) ** 2                     # (doppler, tx, rx, range)
    noise = p[..., 100:250].mean()                           # far from the target
    peak = p[RADAR.n_chirps // 2 + bin_v, :, :, bin_r].mean()  # averaged over 192 channels
    measured = 10 * np.log10((peak - noise) / noise)
    assert measured == pytest.approx(expected_snr_db(rcs_m2, r_m), abs=0.2)


def test_noise_is_circular_gaussian_of_power_kt0fb():
    sim = FmcwSimulator(RADAR, noise=True)
    far = np.array([[0.0, 1e4, 0.0]])                         # a negligible scatterer
    z = sim.frame(far, np.zeros((1, 3)), np.array([1e-12]),
                  bit_generator=frame_bit_generator(5, 0)).astype(np.complex128).ravel()
    n0 = K_B * 290.0 * 10 ** (MMWCAS["noise_figure_db"] / 10) * MMWCAS["adc_rate_hz"]
    assert np.mean(np.abs(z) ** 2) / n0 == pytest.approx(1.0, abs=0.005)
    assert np.mean(z.real**2) / (n0 / 2) == pytest.approx(1.0, abs=0.005)
    assert abs(np.mean(z.real * z.imag)) / (n0 / 2) < 0.005         # I and Q uncorrelated
    assert abs(np.mean(z)) / np.sqrt(n0) < 0.005
    kurt = np.mean(z.real**4) / np.mean(z.real**2) ** 2
    assert kurt == pytest.approx(3.0, abs=0.02)                     # Gaussian, not uniform
    # white: adjacent samples uncorrelated
    assert abs(np.mean(z[1:] * np.conj(z[:-1]))) / n0 < 0.005


def test_adc_int16_quantisation_round_trip_and_full_scale():
    radar16 = RadarConfig.from_mapping({**MMWCAS, "adc_bits": 16})
    src = SimulatedSource(dataclasses.replace(SCENES["approach_car"], n_frames=2), radar16)
    cube = src.frame(1)
    assert cube.dtype == np.complex64
    iq = to_int16_iq(cube)
    assert iq.dtype == np.int16 and iq.shape == cube.shape + (2,)
    assert np.array_equal(from_int16_iq(iq), cube)                  # bit-exact round trip
    # thermal noise spans full scale / 10^(60/20) = 32.8 LSB RMS per component (headroom 60 dB)
    quiet = FmcwSimulator(radar16, noise=True).frame(
        np.array([[0.0, 1e4, 0.0]]), np.zeros((1, 3)), np.array([1e-12]),
        bit_generator=frame_bit_generator(2, 0))
    assert np.std(quiet.real) == pytest.approx(2**15 / 1000, rel=0.01)
    # the same frame unquantised, in LSB units, differs by at most half an LSB
    lsb = src.simulator.adc_lsb
    raw = SimulatedSource(dataclasses.replace(SCENES["approach_car"], n_frames=2), RADAR).frame(1)
    assert np.abs((raw / lsb).real - cube.real).max() <= 0.5 + 1e-3
    # clipping at full scale
    big = np.array([1e6 - 3.4j, -1e6 + 2.6j, 12.5 + 0.49j], dtype=np.complex64)
    np.testing.assert_array_equal(quantise(big, 16), [32767 - 3j, -32768 + 3j, 12 + 0j])
    with pytest.raises(ValueError, match="int16"):
        to_int16_iq(np.array([0.5 + 0j], dtype=np.complex64))


def test_same_seed_same_bytes_other_seed_other_bytes():
    cfg = dataclasses.replace(SCENES["recede_car"], n_frames=3)

    def digest(c, i):
        return hashlib.sha256(SimulatedSource(c, RADAR).frame(i).tobytes()).hexdigest()

    assert digest(cfg, 2) == digest(cfg, 2)
    assert digest(cfg, 2) != digest(dataclasses.replace(cfg, seed=cfg.seed + 1), 2)
    assert digest(cfg, 1) != digest(cfg, 2)
    src = SimulatedSource(cfg, RADAR)
    frames = list(src)
    assert len(frames) == 3
    assert all(np.array_equal(f, src.frame(i)) for i, f in enumerate(frames))


def test_simulated_source_is_a_frame_source():
    src = SimulatedSource(dataclasses.replace(SCENES["straight_car"], n_frames=4), RADAR)
    assert isinstance(src, FrameSource)
    assert src.n_frames == 4 and len(src) == 4
    np.testing.assert_allclose(src.times_s, np.arange(4) * RADAR.frame_period_s)
    f = src.frame(0)
    assert f.shape == (64, 12, 16, 256) and f.dtype == np.complex64
    assert list(src.truth().frame) == [0, 1, 2, 3]
    with pytest.raises(IndexError, match="straight_car"):
        src.frame(4)
    with pytest.raises(Exception, match="adc_bits"):
        src.write_ti_cascade("/nonexistent")                     # needs int16 codes


def test_car_at_5_to_9_m_zero_doppler_and_hidden_pedestrian_in_the_noise():
    """Frame 30 (t = 3 s, pedestrian behind the car, torso at 11.0 m, -0.47 m/s): the car is the
    strongest return, at zero Doppler and 5-9.5 m; the pedestrian's cells stay at the noise level
    with the car and stand out clearly without it."""
    def detection_map(name):
        src = SimulatedSource(SCENES[name], RADAR)
        p = (np.abs(range_doppler(src.frame(30), hann=True)) ** 2).sum(axis=(1, 2))
        return p, src.truth().iloc[30]

    p_car, tr = detection_map("straight_car")
    noise = np.median(p_car[:, 100:250])
    kd0 = RADAR.n_chirps // 2
    kd, kr = np.unravel_index(np.argmax(p_car), p_car.shape)
    assert kd == kd0 and 4.75 <= kr * RANGE_RES <= 9.5
    strong = np.flatnonzero(10 * np.log10(p_car[kd0] / noise) > 30)   # > 30 dB above noise
    # the car spans 5.0-9.4 m; the Hann main lobe widens that by a bin each side
    assert len(strong) >= 4 and np.all((strong * RANGE_RES >= 4.4) & (strong * RANGE_RES <= 9.6))
    # both ends of the car: returns near 5 m and near 8-9 m
    assert np.any(np.abs(strong * RANGE_RES - 5.0) <= 0.5)
    assert np.any(np.abs(strong * RANGE_RES - 8.5) <= 0.5)
    ped_r = int(round(tr.range_m / RANGE_RES))
    ped_d = kd0 + int(round(tr.radial_velocity_mps / V_RES))
    cells = (slice(ped_d - 2, ped_d + 3), slice(ped_r - 1, ped_r + 2))
    assert 10 * np.log10(p_car[cells].max() / noise) < 1.0
    p_free, _ = detection_map("straight_nocar")
    assert 10 * np.log10(p_free[cells].max() / np.median(p_free[:, 100:250])) > 25.0


def test_bad_inputs_raise_clear_errors():
    sim = FmcwSimulator(RADAR, noise=True)
    pos, vel = target(5.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="bit_generator"):
        sim.frame(pos, vel, np.array([1.0]))
    with pytest.raises(ValueError, match=r"\(K, 2\) or \(K, 3\)"):
        sim.frame(pos[0], vel, np.array([1.0]), bit_generator=frame_bit_generator(0, 0))
    with pytest.raises(ValueError, match="range 0"):
        FmcwSimulator(RADAR, noise=False).frame(np.zeros((1, 3)), vel, np.array([1.0]))
    with pytest.raises(ValueError, match="array has"):
        FmcwSimulator(RADAR, array_for(RadarConfig.from_mapping({**MMWCAS, "n_rx": 8})))


def test_write_ti_cascade_hook_round_trips_through_the_capture_reader(tmp_path):
    """The simulate stage's writer hook: a simulated int16 scene saved in TI cascade format reads
    back bit-exactly (the writer and reader are blindspot.radar.capture's)."""
    from blindspot.radar.capture import read_ti_cascade

    radar16 = RadarConfig.from_mapping({**MMWCAS, "adc_bits": 16})
    src = SimulatedSource(dataclasses.replace(SCENES["approach_car"], n_frames=2), radar16)
    paths = src.write_ti_cascade(tmp_path)
    assert len(paths) == 8 and all(p.exists() for p in paths)
    back = read_ti_cascade(tmp_path, 256, 64, 12, skip_first_frame=False)
    assert back.shape == (2, 64, 12, 16, 256)
    assert np.array_equal(back[0], src.frame(0)) and np.array_equal(back[1], src.frame(1))


def test_from_config_reads_the_sim_group_and_rejects_unknown_keys():
    from blindspot.typed_config import ConfigError

    sim_cfg = OmegaConf.to_container(OmegaConf.load(REPO_ROOT / "conf/sim/default.yaml"))
    cfg = dataclasses.replace(SCENES["straight_nocar"], n_frames=1)
    src = SimulatedSource.from_config(cfg, RADAR, sim_cfg)
    assert src.simulator.noise is True and src.simulator.adc_headroom_db == 60.0
    quiet = SimulatedSource.from_config(cfg, RADAR, {"noise": False})
    # noiseless frames do not depend on the seed; noisy ones do
    other = dataclasses.replace(cfg, seed=cfg.seed + 7)
    assert np.array_equal(quiet.frame(0), SimulatedSource.from_config(other, RADAR, {"noise": False}).frame(0))
    assert not np.array_equal(src.frame(0), SimulatedSource.from_config(other, RADAR, sim_cfg).frame(0))
    with pytest.raises(ConfigError, match="sim.nois"):
        SimulatedSource.from_config(cfg, RADAR, {"nois": True})
    with pytest.raises(ConfigError, match="sim.adc_headroom_db"):
        SimulatedSource.from_config(cfg, RADAR, {"adc_headroom_db": -3})
