"""RadarConfig validation and derived quantities; the MMWCAS virtual array."""

import math

import numpy as np
import pytest
from omegaconf import OmegaConf

from blindspot.radar.array import mmwcas_array, ula_array, array_for
from blindspot.radar.config import SPEED_OF_LIGHT, RadarConfig
from blindspot.typed_config import ConfigError
from tests.conftest import REPO_ROOT

MMWCAS = OmegaConf.to_container(OmegaConf.load(REPO_ROOT / "conf/radar/mmwcas.yaml"))


def make(**over):
    return RadarConfig.from_mapping({**MMWCAS, **over})


def test_paper_profile_derived_quantities():
    r = make()
    assert r.center_freq_hz == pytest.approx(77e9)
    assert r.slope_hz_per_s == pytest.approx(10e12)  # 10 MHz/us
    assert r.range_resolution_m == pytest.approx(SPEED_OF_LIGHT / 600e6)
    assert r.range_resolution_m == pytest.approx(0.5, abs=1e-3)
    assert r.range_bin_m == pytest.approx(r.range_resolution_m)
    # TDM over 12 TX: loop period 12 * 35 us; v_max = lambda / (4 T_loop)
    lam = SPEED_OF_LIGHT / 77e9
    assert r.max_velocity_mps == pytest.approx(lam / (4 * 12 * 35e-6))
    assert r.velocity_resolution_mps == pytest.approx(lam / (2 * 64 * 12 * 35e-6))
    # a walking pedestrian (<= 2 m/s) is unambiguous
    assert r.max_velocity_mps > 2.0
    v = r.velocity_axis_mps()
    assert v[r.n_chirps // 2] == 0 and len(v) == 64


@pytest.mark.parametrize(
    "key,value,fragment",
    [
        ("bandwidth_hz", -300e6, "radar.bandwidth_hz"),
        ("ramp_time_s", float("nan"), "radar.ramp_time_s"),
        ("n_tx", 13, "at most 12 TX"),
        ("adc_rate_hz", 5e6, "samples fit in the 30 us ramp"),
        ("n_samples", 0, "radar.n_samples"),
        ("tx_order", [0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10], "radar.tx_order"),
        ("frame_period_s", 0.001, "active chirp time"),
        ("adc_bits", 1, "radar.adc_bits"),
    ],
)
def test_invalid_values_name_the_key(key, value, fragment):
    with pytest.raises(ConfigError) as err:
        make(**{key: value})
    assert fragment in str(err.value)
    assert key in str(err.value)


def test_missing_required_key():
    m = dict(MMWCAS)
    del m["n_chirps"]
    with pytest.raises(ConfigError, match="radar.n_chirps"):
        RadarConfig.from_mapping(m)


def test_mmwcas_virtual_array_86_contiguous():
    arr = mmwcas_array()
    assert arr.virtual_pos.shape == (12, 16, 2)
    assert arr.n_ula == 86
    assert arr.ula_is_contiguous
    np.testing.assert_array_equal(arr.ula_positions_units, np.arange(86))
    t, r = arr.ula_index
    assert np.all(arr.virtual_pos[t, r, 1] == 0)  # elevation-0 TX only


def test_firing_order_permutes_tx_axis_only():
    fired = mmwcas_array(tuple(range(11, -1, -1)))
    phys = mmwcas_array()
    np.testing.assert_array_equal(fired.tx_pos, phys.tx_pos[::-1])
    assert fired.n_ula == 86
    np.testing.assert_array_equal(fired.ula_positions_units, phys.ula_positions_units)


def test_spacing_in_wavelengths_follows_frequency():
    arr = array_for(make())
    assert arr.spacing_wl == pytest.approx(0.5 * 77e9 / 76.8e9)


def test_generic_ula_is_filled():
    arr = ula_array(2, 4)
    assert arr.n_ula == 8 and arr.ula_is_contiguous
    assert math.isclose(arr.ula_positions_wl[1] - arr.ula_positions_wl[0], 0.5)
