"""The chirp profiles of the two real recordings (conf/radar) against their published numbers."""

import pytest
from omegaconf import OmegaConf

from blindspot.radar.config import SPEED_OF_LIGHT, RadarConfig
from tests.conftest import REPO_ROOT

RADAR = REPO_ROOT / "conf" / "radar"


def load(name: str) -> dict:
    return OmegaConf.to_container(OmegaConf.load(RADAR / f"{name}.yaml"))


@pytest.mark.parametrize("name", ["dca1000_awr1843", "openradar_presense"])
def test_profiles_use_the_key_set_of_the_paper_profile(name):
    assert sorted(load(name)) == sorted(load("mmwcas"))
    assert RadarConfig.from_mapping(load(name)).name == name


@pytest.mark.parametrize(
    "name,slope_mhz_per_us,fs,n,loops,chirp_period_us",
    [
        # README / Radar_data_Processing.m: 21.002 MHz/us, 4 Msps, 128 samples, 255 loops, 60 us
        ("dca1000_awr1843", 21.002, 4e6, 128, 255, 60.0),
        # OpenRadar notebook: 60 MHz/us, 2500 ksps, 128 samples, idle 30 us + ramp end 62 us
        ("openradar_presense", 60.0, 2.5e6, 128, 128, 92.0),
    ],
)
def test_profiles_reproduce_the_recorded_chirp(name, slope_mhz_per_us, fs, n, loops,
                                               chirp_period_us):
    r = RadarConfig.from_mapping(load(name))
    assert r.slope_hz_per_s == pytest.approx(slope_mhz_per_us * 1e12)
    assert (r.adc_rate_hz, r.n_samples, r.n_chirps, r.n_tx, r.n_rx) == (fs, n, loops, 2, 4)
    assert r.chirp_period_s == pytest.approx(chirp_period_us * 1e-6)
    # complex sampling: range bin c * fs / (2 * slope * N)
    assert r.range_bin_m == pytest.approx(SPEED_OF_LIGHT * fs / (2 * slope_mhz_per_us * 1e12 * n))
    assert r.frame_period_s >= r.frame_active_time_s
