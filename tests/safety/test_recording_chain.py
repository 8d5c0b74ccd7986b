"""A recording from its capture to a decision (issue 44): the one command on a capture made by
the simulator and on a cut of TI's people log, the chain's decisions from a car, and bad input
named in its message with nothing half-written."""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from blindspot import config
from blindspot.safety.config import WarningConfig
from blindspot.safety.recording import RecordingEntry, RecordingError, run_recording
from blindspot.track.config import TrackerConfig
from blindspot.traj.baselines import kalman_baseline
from blindspot.traj.config import EvalConfig

REPO = Path(__file__).resolve().parents[2]
TI_LOG = "data/radar/ti-gtrack-people/fHistScene4_2d_0001.bin"


def ti_cut(src: Path, dst: Path, n_frames: int) -> Path:
    """The first ``n_frames`` frames of a TI people-counting TLV log (frame header u32 number,
    u32 n_tlv; each TLV u32 type, u32 length, payload)."""
    data, off = src.read_bytes(), 0
    for _ in range(n_frames):
        _, n_tlv = struct.unpack_from("<II", data, off)
        off += 8
        for _ in range(n_tlv):
            off += 8 + struct.unpack_from("<II", data, off)[1]
    dst.write_bytes(data[:off])
    return dst


def simulated_capture(path: Path, n_frames: int = 10) -> Path:
    """A DCA1000 capture of the dca1000_awr1843 profile made by the simulator: a person (three
    scatterers) walking across at 1.3 m/s 4 m in front of a still radar from 2.5 m to its
    left, beside a static pole."""
    from blindspot.radar.array import array_for
    from blindspot.radar.capture import write_dca1000
    from blindspot.radar.config import RadarConfig
    from blindspot.radar.simulator import FmcwSimulator, frame_bit_generator

    radar = RadarConfig.from_mapping(config.compose([], config_dir=REPO / "conf")
                                     .recordings.dca1000_awr1843.radar)
    sim = FmcwSimulator(radar, array_for(radar), noise=True)
    frames = []
    for f in range(n_frames):
        x = -2.5 + 1.3 * f * radar.frame_period_s       # radial speed 0.5-0.7 m/s, past the
        # static cut (0.3 m/s): nearer the boresight the walker sits in the Doppler notch
        pos = np.array([[x, 4.0, 1.0], [x + 0.1, 4.0, 0.5], [x - 0.1, 4.05, 1.3], [2.0, 6.0, 1.0]])
        vel = np.array([[1.3, 0, 0], [1.6, 0, 0], [1.1, 0, 0], [0, 0, 0]], float)
        frames.append(sim.frame(pos, vel, np.array([0.5, 0.3, 0.3, 3.0]),
                                bit_generator=frame_bit_generator(7, f)))
    return write_dca1000(path, np.stack(frames))


def _run_recordings(tmp_path, shared_dir, run_dir):
    """`python -m blindspot recordings recordings=mine` with tmp_path/conf on Hydra's search path
    and the run's outputs in ``run_dir``: the completed process."""
    env = {**os.environ, "PYTHONPATH": str(REPO / "src"), "BLINDSPOT_SHARED": str(shared_dir)}
    return subprocess.run(
        [sys.executable, "-m", "blindspot", "recordings", "recordings=mine", "runs.enabled=false",
         "progress=false", f"hydra.searchpath=[file://{tmp_path / 'conf'}]",
         f"hydra.run.dir={run_dir}"], cwd=REPO, env=env, capture_output=True, text=True,
        timeout=300)


def test_the_command_on_a_simulated_capture_and_a_cut_of_tis_people_log(tmp_path, shared_dir):
    """`python -m blindspot recordings recordings=<mine>` on the user's own conf file: points,
    tracks, predicted paths per recording, the summary with n_tracks, TI's tracks kept."""
    conf = tmp_path / "conf" / "recordings"
    conf.mkdir(parents=True)
    # 20 frames (0.67 s at 30 frames/s): the tracker's 0.5 s confirmation window fits
    capture = simulated_capture(tmp_path / "adc_data.bin", n_frames=20)
    cut = ti_cut(shared_dir / TI_LOG, tmp_path / "ti_cut.bin", 120)
    (conf / "mine.yaml").write_text(f"""
defaults:
  - /radar@sim.radar: dca1000_awr1843
sim:
  kind: dca1000
  path: {capture}
  doa: {{subarray: null}}
  static_speed_mps: 0.3
ti_cut:
  kind: ti_gtrack
  path: {cut}
  frame_period_s: 0.05
  reference_gate_m: 0.5
  min_detectable_speed_mps: 0.04
  boundary_box_m: [-2.0, 10.0, 0.0, 10.0]
""")
    run_dir = tmp_path / "run"
    proc = _run_recordings(tmp_path, shared_dir, run_dir)
    assert proc.returncode == 0, proc.stderr[-3000:]
    summary = json.loads((run_dir / "reports/metrics/recordings.json").read_text())
    assert set(summary) == {"sim", "ti_cut"}
    for name in summary:
        for key in ("points", "tracks", "predictions"):
            assert (run_dir / "data/recordings" / name / f"{key}.parquet").is_file(), (name, key)
    assert str(tmp_path) not in json.dumps(summary)      # no absolute path in an output
    # the walker: moving points, one confirmed track near it, its predicted path going +x
    pts = pd.read_parquet(run_dir / "data/recordings/sim/points.parquet")
    walker = pts[~pts.static & pts.x_m.notna()]
    assert len(walker) and np.allclose(walker.y_m.median(), 4.0, atol=0.5), walker
    assert summary["sim"]["n_tracks"] >= 1, summary["sim"]
    pred = pd.read_parquet(run_dir / "data/recordings/sim/predictions.parquet")
    assert len(pred) and {"step", "cov_xx", "cov_xy", "cov_yy"} <= set(pred.columns)
    assert (run_dir / "data/recordings/sim/range_doppler.png").is_file()
    # TI's cut: three people have appeared by frame 120 (TI's tracks 0-2 start at 21, 57, 87)
    ti = summary["ti_cut"]
    assert ti["n_frames"] == 120 and ti["n_tracks"] == 3 and ti["n_reference"] == 3, ti
    assert ti["id_switches"] == 0 and ti["frames_without_points"] > 0, ti
    assert (run_dir / "data/recordings/ti_cut/reference.parquet").is_file()


@pytest.fixture(scope="module")
def groups():
    cfg = config.compose(["profile=tiny"], config_dir=REPO / "conf")
    return cfg, TrackerConfig.from_cfg(cfg), WarningConfig.from_cfg(cfg), EvalConfig.from_cfg(cfg)


def _run(groups, path: Path, **entry):
    cfg, tracker, warning, ev = groups
    mapping = {"name": "mine", "kind": "points_table", "path": str(path), **entry}
    rec = RecordingEntry.from_mapping(mapping, where="recordings.mine")
    return run_recording(rec, mapping, path, cfg, tracker, lambda dt: kalman_baseline(ev, dt),
                         warning)


def crossing_from_a_car(n_frames: int = 25, dt: float = 0.1, v: float = 8.33) -> pd.DataFrame:
    """A point table from a car at v m/s: kerb posts at x = +-4 m every 3 m (static, on the
    ego-motion curve) and a child crossing from x = 2 m at 1.4 m/s, 12 m ahead of the start."""
    rows = []
    for f in range(n_frames):
        ego_y = v * f * dt
        posts = [(s * 4.0, y - ego_y) for s in (-1, 1) for y in np.arange(3.0, 40.0, 3.0)
                 if y - ego_y > 1.0]
        for x, y in posts:
            rows.append((f, x, y, -v * y / np.hypot(x, y)))
        cx, cy = 2.0 - 1.4 * f * dt, 12.0 - ego_y
        if cy > 0.5:
            for dx in (-0.1, 0.0, 0.1):
                x = cx + dx
                rows.append((f, x, cy, (x * -1.4 + cy * -v) / np.hypot(x, cy)))
    t = pd.DataFrame(rows, columns=["frame", "x_m", "y_m", "velocity_mps"])
    return t.assign(time_s=t.frame * dt, ego_speed_mps=v)


def test_from_a_car_the_child_gets_a_warning_then_the_aeb_request(groups, tmp_path):
    path = tmp_path / "drive.parquet"
    crossing_from_a_car().to_parquet(path)
    res = _run(groups, path, moving=True, speed_column="ego_speed_mps", static_speed_mps=0.1)
    assert res.points.static.sum() > 0 and (~res.points.static & res.points.x_m.notna()).any()
    dec = res.decisions
    assert {"frame", "p_collision", "warning", "aeb"} <= set(dec.columns)
    assert dec.aeb.any(), dec
    assert dec.frame[dec.warning].min() <= dec.frame[dec.aeb].min()
    assert res.summary["first_aeb_s"] is not None and res.summary["n_tracks"] >= 1


def test_timestamps_going_backwards_are_named(groups, tmp_path):
    t = crossing_from_a_car()
    t.loc[t.frame == 7, "time_s"] = 0.3
    t.to_parquet(path := tmp_path / "back.parquet")
    with pytest.raises(RecordingError, match=r"back\.parquet.*time stamps go backwards: frame 7"):
        _run(groups, path)


def test_a_recording_shorter_than_the_history_is_named(groups, tmp_path):
    crossing_from_a_car(n_frames=2).to_parquet(path := tmp_path / "short.parquet")
    with pytest.raises(RecordingError, match=r"short\.parquet.*2 frames, fewer than the 3 "
                                             r"frames the tracker needs to confirm a track"):
        _run(groups, path)
    assert _run(groups, path, stop_at="points").tracks is None      # points only: accepted


def test_a_point_log_with_empty_frames_is_tracked_through_them(groups, tmp_path):
    t = crossing_from_a_car()
    t = t[~t.frame.isin([4, 5])]
    empty = pd.DataFrame({"frame": [4, 5], "time_s": [0.4, 0.5]})
    pd.concat([t, empty]).to_parquet(path := tmp_path / "gaps.parquet")
    with pytest.warns(UserWarning, match=r"gaps\.parquet.*2 of 25 frames hold no point"):
        res = _run(groups, path)
    assert res.summary["frames_without_points"] == 2 and res.summary["n_frames"] == 25
    with pytest.raises(RecordingError, match="no point in any of its 2 frames"):
        empty.assign(x_m=np.nan, y_m=np.nan, velocity_mps=np.nan).to_parquet(path)
        _run(groups, path)


def test_a_profile_that_does_not_fit_the_capture_is_named(groups, tmp_path):
    cfg = groups[0]
    capture = simulated_capture(tmp_path / "adc_data.bin", n_frames=2)
    radar = {**cfg.recordings.dca1000_awr1843.radar, "n_samples": 256}
    cfg_, tracker, warning, ev = groups
    mapping = {"name": "mine", "kind": "dca1000", "path": str(capture), "radar": radar,
               "options": {"strict": True}, "doa": {"subarray": None}}
    from omegaconf import OmegaConf

    rec = RecordingEntry.from_mapping(mapping, where="recordings.mine")
    with pytest.raises(RecordingError, match=r"recording 'mine' \(adc_data\.bin\).*expected"):
        run_recording(rec, OmegaConf.create(mapping), capture, cfg_, tracker,
                      lambda dt: kalman_baseline(ev, dt), warning)


def test_a_reader_error_names_the_file_and_leaves_no_half_written_folder(tmp_path, shared_dir):
    """The first recording is fine, the second's file is cut inside a frame: the command fails
    naming that file with what was expected and found, and writes no data/recordings at all."""
    conf = tmp_path / "conf" / "recordings"
    conf.mkdir(parents=True)
    good = ti_cut(shared_dir / TI_LOG, tmp_path / "good.bin", 60)
    bad = tmp_path / "bad.bin"
    bad.write_bytes(good.read_bytes()[:-7])
    entry = ("  kind: ti_gtrack\n  path: {}\n  frame_period_s: 0.05\n"
             "  tracker: {{cluster_min_samples: 2, confirm_m: 6, confirm_n: 8}}\n")
    (conf / "mine.yaml").write_text("good:\n" + entry.format(good) + "bad:\n" + entry.format(bad))
    run_dir = tmp_path / "run"
    proc = _run_recordings(tmp_path, shared_dir, run_dir)
    assert proc.returncode != 0
    assert "bad.bin" in proc.stderr and "expected" in proc.stderr, proc.stderr[-2000:]
    assert not (run_dir / "data/recordings").exists()
    assert not (run_dir / "reports/metrics/recordings.json").exists()
