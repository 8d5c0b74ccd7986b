"""The capture readers on real recordings nobody here made (../shared/data/radar).

A correct reading of real FMCW data shows the scene's strong returns as sharp range peaks in the
same bins in every chirp and every frame, static returns phase-coherent from loop to loop, and
received power falling with range. The measures below are computed here with plain numpy (DC
removed, Hann window, range FFT per chirp, the bins within ``GUARD`` of DC ignored because TX->RX
leakage and DC offset live there), not with the project's DSP code.

For the DCA1000 file the same bytes are also read in the other plausible ways (I/Q pairs, I and
Q swapped, TI's four-lane order, TX slot slowest): each fails at least one measure by a wide
margin, which is what fixes the layout documented in :mod:`blindspot.radar.capture.dca1000`.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from omegaconf import OmegaConf

from blindspot.radar.capture import (
    CaptureError,
    DCA1000Capture,
    DCA1000Recording,
    read_dca1000,
    read_openradar_npy,
)
from blindspot.radar.config import RadarConfig
from blindspot.radar.source import FrameSource
from tests.conftest import REPO_ROOT

pytestmark = pytest.mark.real_data

GUARD = 4  # bins on each side of DC left out of every measure


def profile(name: str) -> RadarConfig:
    return RadarConfig.from_mapping(OmegaConf.load(REPO_ROOT / "conf" / "radar" / f"{name}.yaml"))


# ---------------------------------------------------------------------------------- measures
def range_spectrum(cube: np.ndarray) -> np.ndarray:
    """complex (..., samples) range FFT of each chirp, DC removed, Hann window."""
    x = cube - cube.mean(-1, keepdims=True)
    return np.fft.fft(x * np.hanning(x.shape[-1]), axis=-1)


def range_power(cube: np.ndarray) -> np.ndarray:
    """|range FFT|^2 (frames, loops, tx, rx, samples) with the DC guard bins zeroed."""
    p = np.abs(range_spectrum(cube)) ** 2
    p[..., : GUARD + 1] = 0
    p[..., p.shape[-1] - GUARD:] = 0
    return p


def strongest_peaks(prof: np.ndarray, k: int = 3) -> np.ndarray:
    """(..., k) bins of the k strongest local maxima of each profile along the last axis."""
    is_max = (prof >= np.roll(prof, 1, -1)) & (prof >= np.roll(prof, -1, -1))
    return np.argsort(np.where(is_max, prof, 0), -1)[..., -k:]


def measures(cube: np.ndarray) -> dict[str, float]:
    """Consistency measures of a (frames, loops, tx, rx, samples) reading."""
    n = cube.shape[-1]
    p = range_power(cube)
    inner = slice(GUARD + 1, n - GUARD)
    mean_profile = p.mean((0, 1, 2, 3))[inner]
    channel_profile = p.mean((0, 1))                       # (tx, rx, samples)
    peaks = strongest_peaks(channel_profile)               # (tx, rx, 3)
    argmax = p.argmax(-1)                                  # (frames, loops, tx, rx)
    at_peak = (np.abs(argmax[..., None] - peaks) <= 1).any(-1)
    # phase coherence of each channel's strongest bin over the loops of a frame
    k = channel_profile.argmax(-1)
    x = np.take_along_axis(range_spectrum(cube), k[None, None, :, :, None], -1)[..., 0]
    coherence = np.abs(x.mean(1)) / np.abs(x).mean(1)       # (frames, tx, rx)
    frame_db = 10 * np.log10(p.mean((1, 2, 3))[:, inner])  # (frames, bins)
    return {
        "peak_to_median_db": float(10 * np.log10(mean_profile.max() / np.median(mean_profile))),
        "at_peak_worst_channel": float(at_peak.mean((0, 1)).min()),
        "coherence_min": float(coherence.min()),
        "near_far_db": float(10 * np.log10(p[..., GUARD + 1: n // 2].sum()
                                           / p[..., n // 2: n - GUARD].sum())),
        "frame_corr_min": float(np.corrcoef(frame_db).min()) if len(frame_db) > 1 else 1.0,
        "frame_top_bins_agree": float(np.all(frame_db.argmax(-1) == frame_db.argmax(-1)[0])),
    }


# ---------------------------------------------------------------------------------- DCA1000
DCA_SIZE, DCA_FRAME = 4_190_862, 128 * 255 * 2 * 4 * 4


@pytest.fixture(scope="module")
def dca_path(shared_dir):
    path = shared_dir / "data" / "radar" / "dca1000-awr1843" / "adc_data.bin"
    if not path.is_file():
        pytest.skip(f"real DCA1000 recording not found at {path}")
    return path


@pytest.fixture(scope="module")
def dca_cube(dca_path):
    r = profile("dca1000_awr1843")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return read_dca1000(dca_path, r.n_samples, r.n_chirps, r.n_tx, r.n_rx)


def test_dca1000_whole_frames_and_the_cut_one(dca_path):
    r = profile("dca1000_awr1843")
    assert dca_path.stat().st_size == DCA_SIZE
    with pytest.warns(UserWarning, match=rf"adc_data.bin: size is not a whole number of frames"
                      rf".*{DCA_SIZE} bytes = 4 frames of {DCA_FRAME} bytes \+ "
                      rf"{DCA_SIZE - 4 * DCA_FRAME} bytes.*a cut capture.*lost packets: "
                      rf"{5 * DCA_FRAME - DCA_SIZE} bytes missing to 5 whole frames, not a whole "
                      r"number of 1456-byte.*ends inside a sample"):
        cube = read_dca1000(dca_path, r.n_samples, r.n_chirps, r.n_tx, r.n_rx)
    assert cube.shape == (4, 255, 2, 4, 128) and cube.dtype == np.complex64
    # two's-complement ADC codes of a few thousand at most, not offset-binary (~32768)
    assert 500 < np.abs(cube.real).max() < 8192 and 500 < np.abs(cube.imag).max() < 8192


def test_dca1000_wrong_loop_count_is_reported_with_its_causes(dca_path):
    """256 loops instead of 255: the file is then 3 frames + 1,045,134 bytes (99.7 % of a
    frame); no cut end is claimed, the numbers of each possible cause are given."""
    r = profile("dca1000_awr1843")
    frame = 128 * 256 * 2 * 4 * 4
    with pytest.warns(UserWarning, match=rf"{DCA_SIZE} bytes = 3 frames of {frame} bytes \+ "
                      rf"{DCA_SIZE - 3 * frame} bytes.*a cut capture.*lost packets: "
                      rf"{4 * frame - DCA_SIZE} bytes missing to 4 whole frames.*a wrong profile"
                      ) as w:
        cube = read_dca1000(dca_path, r.n_samples, 256, r.n_tx, r.n_rx)
    assert cube.shape[0] == 3 and "dropped" not in str(w[0].message)
    with pytest.raises(CaptureError, match="not a whole number of frames"):
        read_dca1000(dca_path, r.n_samples, 256, r.n_tx, r.n_rx, strict=True)


def test_dca1000_real_frames_hold_no_zero_runs(dca_path):
    with pytest.warns(UserWarning, match="not a whole number"):
        cap = DCA1000Capture(dca_path, 128, 255, 2, 4)
    report = cap.diagnose()
    assert report.frames.longest_zero_run.max() <= 2  # a real ADC: no long runs of exact zeros
    assert report.skip_bytes == 0 and report.leading_zero_bytes < 8


def test_dca1000_strong_returns_consistent_across_chirps_and_frames(dca_cube):
    m = measures(dca_cube)
    assert m["at_peak_worst_channel"] > 0.95   # every chirp shows the same strong returns
    assert m["peak_to_median_db"] > 20          # sharp peaks, far above the noise floor
    assert m["coherence_min"] > 0.99            # static returns coherent from loop to loop
    assert m["near_far_db"] > 10                # power falls with range (R^-4, IF low-pass)
    assert m["frame_corr_min"] > 0.99 and m["frame_top_bins_agree"] == 1.0


def test_dca1000_other_interleavings_are_clearly_worse(dca_path, dca_cube):
    r = profile("dca1000_awr1843")
    s, l, t, x = r.n_samples, r.n_chirps, r.n_tx, r.n_rx
    raw = np.fromfile(dca_path, "<i2", count=4 * DCA_FRAME // 2).astype(np.float32)
    g = raw.reshape(4, -1, 4)
    iq_pairs = (g[..., [0, 2]] + 1j * g[..., [1, 3]]).reshape(4, l, t, x, s)
    swapped = dca_cube.imag + 1j * dca_cube.real
    tx_slowest = dca_cube.reshape(4, l * t, x, s).reshape(4, t, l, x, s).transpose(0, 2, 1, 3, 4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        four_lane = read_dca1000(dca_path, s, l, t, x, layout="xwr14xx")
    good = measures(dca_cube)
    for other in (iq_pairs, four_lane):   # lanes mixed up: the returns smear over the spectrum
        assert measures(other)["peak_to_median_db"] < good["peak_to_median_db"] - 8
    # I and Q swapped: the mirror image, strong returns at far range and near range empty
    assert measures(swapped)["near_far_db"] < -10
    # TX slot taken as slowest: chirps of two TX mixed within a "channel"
    bad = measures(tx_slowest)
    assert bad["coherence_min"] < 0.9 and bad["at_peak_worst_channel"] < 0.8


def test_dca1000_recording_source(dca_path, dca_cube):
    r = profile("dca1000_awr1843")
    with pytest.warns(UserWarning, match="not a whole number of frames"):
        src = DCA1000Recording(dca_path, r)
    assert isinstance(src, FrameSource) and src.n_frames == 4 and src.array.n_ula == 8
    assert np.array_equal(src.frame(2), dca_cube[2])
    np.testing.assert_allclose(np.diff(src.times_s), r.frame_period_s)


# ---------------------------------------------------------------------------------- OpenRadar
@pytest.fixture(scope="module")
def openradar_dir(shared_dir):
    path = shared_dir / "data" / "radar" / "openradar-presense"
    if not (path / "doppler_example_1.npy").is_file():
        pytest.skip(f"OpenRadar examples not found in {path}")
    return path


def test_openradar_doppler_example_consistent(openradar_dir):
    r = profile("openradar_presense")
    cube = read_openradar_npy(openradar_dir / "doppler_example_1.npy", n_tx=r.n_tx)
    assert cube.shape == (1, r.n_chirps, r.n_tx, r.n_rx, r.n_samples)
    m = measures(cube)
    assert m["at_peak_worst_channel"] > 0.9 and m["peak_to_median_db"] > 20
    assert m["coherence_min"] > 0.99
    # the file's unsigned codes taken at face value (not reinterpreted as int16) smear the peaks
    stored = np.load(openradar_dir / "doppler_example_1.npy").reshape(cube.shape)
    assert measures(stored)["peak_to_median_db"] < m["peak_to_median_db"] - 5


def test_openradar_two_recordings_agree(openradar_dir):
    single = read_openradar_npy(openradar_dir / "simple_frame_1.npy")       # (chirps, samples)
    assert single.shape == (128, 128)
    m = measures(single[None, :, None, None, :])
    assert m["at_peak_worst_channel"] > 0.9 and m["peak_to_median_db"] > 20
    multi = read_openradar_npy(openradar_dir / "doppler_example_1.npy", n_tx=2)
    # the two captures of the same room share their strongest return (within one bin)
    top_single = range_power(single[None, :, None, None, :]).mean((0, 1, 2, 3)).argmax()
    top_multi = range_power(multi).mean((0, 1, 2, 3)).argmax()
    assert abs(int(top_single) - int(top_multi)) <= 1
