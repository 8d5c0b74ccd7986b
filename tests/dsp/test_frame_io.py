"""blindspot.dsp.frame_io: one frame's maps written and read back."""

import numpy as np
import pandas as pd
import pytest

from blindspot.dsp.chain import FrameResult
from blindspot.dsp.frame_io import FRAME_KEYS, read_frame_result, write_frame_result


def _result(spectrum: bool) -> FrameResult:
    rng = np.random.default_rng(0)
    power = rng.random((8, 4))
    return FrameResult(
        frame=7, time_s=0.7, detections=pd.DataFrame(), point=pd.DataFrame(), power=power,
        threshold=power * 2, mask=power > 0.5, noise=power / 2,
        spectrum=rng.random(181) if spectrum else None, spectrum_detection=3 if spectrum else None,
        angles_deg=np.linspace(-90, 90, 181), range_axis_m=np.arange(8) * 0.5,
        velocity_axis_mps=np.linspace(-2, 2, 4))


@pytest.mark.parametrize("spectrum", [True, False])
def test_round_trip(tmp_path, spectrum):
    r = _result(spectrum)
    path = write_frame_result(tmp_path / "d" / "frame.npz", r, scene="approach_car")
    got = read_frame_result(path)
    assert set(got) == set(FRAME_KEYS)
    for key in ("power", "threshold", "mask", "range_axis_m", "velocity_axis_mps", "angles_deg"):
        np.testing.assert_array_equal(got[key], getattr(r, key))
    assert got["mask"].dtype == bool
    assert str(got["scene"]) == "approach_car" and int(got["frame"]) == 7
    assert float(got["time_s"]) == 0.7
    if spectrum:
        np.testing.assert_array_equal(got["spectrum"], r.spectrum)
        assert int(got["spectrum_detection"]) == 3
    else:
        assert got["spectrum"].shape == (0,) and int(got["spectrum_detection"]) == -1
    assert [p.name for p in path.parent.iterdir()] == ["frame.npz"]  # no temporary left


def test_reader_rejects_foreign_npz(tmp_path):
    np.savez(tmp_path / "x.npz", power=np.zeros((2, 2)))
    with pytest.raises(ValueError, match=r"x.npz.*missing keys"):
        read_frame_result(tmp_path / "x.npz")
