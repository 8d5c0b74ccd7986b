"""The detection chain end to end: synthetic tones with known positions, the simulator's paper
scene (someone else's physics), every config variant, the benchmark command."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from omegaconf import OmegaConf

from blindspot.dsp.chain import DetectionChain
from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig
from blindspot.radar.config import RadarConfig
from blindspot.typed_config import ConfigError
from tests.conftest import REPO_ROOT
from tests.dsp._synth import mmwcas, tone_cube

CONF = REPO_ROOT / "conf"


def group(name: str, variant: str) -> dict:
    return OmegaConf.to_container(OmegaConf.load(CONF / name / f"{variant}.yaml"))


@pytest.fixture(scope="module")
def paper():
    radar, array = mmwcas()
    chain = DetectionChain.from_config(radar, array, group("cfar", "paper"), group("doa", "music"),
                                       group("detect", "paper"))
    return radar, array, chain


CAR = [(5.0, 0.0, 17.0, 3e4), (8.5, 0.0, 10.0, 1e4)]
NOISE = 2 * 30.0 ** 2  # ADC-code units: noise floor of the map ~90 dB like a 16-bit capture


def test_pedestrian_point_on_a_synthetic_frame(paper):
    radar, array, chain = paper
    ped = (12.5, -0.7, 36.0, 300.0)
    cube = tone_cube(radar, array, CAR + [ped], noise_power=NOISE, rng=np.random.default_rng(2))
    res = chain.process(cube, frame=7, time_s=0.7)
    det = res.detections
    assert det["moving"].sum() >= 1
    # the car's two points are detected and marked static
    static = det[~det["moving"]]
    for r_m, _, ang, _ in CAR:
        near = static[np.abs(static["range_m"] - r_m) < radar.range_bin_m]
        assert len(near) >= 1 and np.nanmin(np.abs(near["angle_deg"] - ang)) < 0.1
    assert len(res.point) == 1
    pt = res.point.iloc[0]
    x, y = ped[0] * np.sin(np.radians(ped[2])), ped[0] * np.cos(np.radians(ped[2]))
    assert np.hypot(pt.x_m - x, pt.y_m - y) < radar.range_bin_m
    assert pt.angle_deg == pytest.approx(36.0, abs=0.1)
    assert pt.velocity_mps == pytest.approx(-0.7, abs=radar.velocity_resolution_mps)
    assert pt.frame == 7 and pt.time_s == 0.7
    # maps and the spectrum for the figures
    assert res.power.shape == res.threshold.shape == res.mask.shape == (res.range_axis_m.size, 64)
    assert res.spectrum is not None and res.spectrum.shape == res.angles_deg.shape
    assert res.angles_deg[np.argmax(res.spectrum)] == pytest.approx(36.0, abs=0.5)
    # no noise-only detections: the paper threshold is ~16 dB above this noise floor
    assert len(det) <= 6


def test_static_scene_gives_no_point(paper):
    radar, array, chain = paper
    cube = tone_cube(radar, array, CAR, noise_power=NOISE, rng=np.random.default_rng(3))
    res = chain.process(cube)
    assert len(res.detections) >= 2 and not res.detections["moving"].any()
    assert res.point.empty


def test_process_frames_points_only_where_seen(paper):
    radar, array, chain = paper
    rng = np.random.default_rng(4)
    frames = [tone_cube(radar, array, CAR + ([(11.0, 0.6, -20.0, 300.0)] if i != 1 else []),
                        noise_power=NOISE, rng=rng) for i in range(3)]
    det, pts = chain.process_frames(frames, np.array([0.0, 0.1, 0.2]), progress=False)
    assert set(det["frame"]) == {0, 1, 2}
    assert pts["frame"].tolist() == [0, 2]
    np.testing.assert_allclose(pts["angle_deg"], -20.0, atol=0.1)


def test_db_domain_refuses_a_map_in_watts(paper):
    radar, array, chain = paper
    cube = tone_cube(radar, array, [(5.0, 0.0, 0.0, 1e-4)], noise_power=1e-12,
                     rng=np.random.default_rng(5))
    with pytest.raises(ConfigError, match="cfar.domain"):
        chain.process(cube)


@pytest.mark.parametrize("cfar", ["paper", "ca_pfa", "go", "so", "os"])
@pytest.mark.parametrize("doa", ["music", "bartlett", "capon"])
def test_every_config_variant_finds_the_pedestrian(paper, cfar, doa):
    radar, array, _ = paper
    chain = DetectionChain.from_config(radar, array, group("cfar", cfar), group("doa", doa),
                                       group("detect", "paper"))
    ped = (12.5, -0.7, 36.0, 300.0)
    cube = tone_cube(radar, array, CAR + [ped], noise_power=NOISE, rng=np.random.default_rng(6))
    res = chain.process(cube)
    assert len(res.point) == 1
    assert res.point.iloc[0].angle_deg == pytest.approx(36.0, abs=0.2)


def test_config_errors_name_the_key():
    ca_pfa, music, detect = group("cfar", "ca_pfa"), group("doa", "music"), group("detect", "paper")
    with pytest.raises(ConfigError, match="cfar.pfa"):
        CfarConfig.from_mapping({**ca_pfa, "scale": 1.18, "pfa": 1e-3})
    with pytest.raises(ConfigError, match="cfar.domain"):
        CfarConfig.from_mapping({**ca_pfa, "pfa": 1e-3, "domain": "db"})
    with pytest.raises(ConfigError, match="cfar.guard"):
        CfarConfig.from_mapping({**ca_pfa, "guard": [1, -2]})
    with pytest.raises(ConfigError, match="cfar.rank"):
        CfarConfig.from_mapping({k: v for k, v in ca_pfa.items() if k != "rank"})
    with pytest.raises(ConfigError, match="doa.methd"):
        DoaConfig.from_mapping({**music, "methd": "music"})
    with pytest.raises(ConfigError, match="doa.grid_deg"):
        DoaConfig.from_mapping({**music, "grid_deg": [90, -90, 1]})
    with pytest.raises(ConfigError, match="detect.snapshots"):
        DetectConfig.from_mapping({**detect, "snapshots": "frames"})
    radar, array = mmwcas()
    with pytest.raises(ConfigError, match="doa.subarray"):
        DetectionChain.from_config(radar, array, CfarConfig.from_mapping(ca_pfa),
                                   DoaConfig.from_mapping({**music, "subarray": 100}),
                                   DetectConfig.from_mapping(detect))


def test_chirp_snapshot_mode(paper):
    radar, array, _ = paper
    chain = DetectionChain.from_config(radar, array, group("cfar", "paper"),
                                       {**group("doa", "music"), "subarray": 43},
                                       {**group("detect", "paper"), "snapshots": "chirps"})
    ped = (12.5, -0.7, 36.0, 300.0)  # alone at its range, so the chirp snapshots see only it
    cube = tone_cube(radar, array, CAR + [ped], noise_power=NOISE, rng=np.random.default_rng(7))
    res = chain.process(cube)
    assert res.point.iloc[0].angle_deg == pytest.approx(36.0, abs=0.1)


def test_simulated_paper_scene_visible_and_hidden():
    """The simulator's straight_car scene in 16-bit ADC codes: frame 3 (pedestrian in view at
    ~12.7 m) gives a point near the torso truth, frame 20 (hidden behind the car) gives none."""
    sim = pytest.importorskip("blindspot.radar.simulator")
    from blindspot.radar.array import array_for
    from blindspot.radar.scene import load_scenes

    radar = RadarConfig.from_mapping({**group("radar", "mmwcas"), "adc_bits": 16})
    scenes = load_scenes(group("scene", "paper"))
    src = sim.SimulatedSource(scenes["straight_car"], radar)
    chain = DetectionChain.from_config(radar, array_for(radar), group("cfar", "paper"),
                                       group("doa", "music"), group("detect", "paper"))
    truth = src.truth()
    det, pts = chain.process_many(src, frames=[3, 20], progress=False)
    assert not truth.loc[3, "occluded"] and truth.loc[20, "occluded"]
    assert pts["frame"].tolist() == [3]
    p, t = pts.iloc[0], truth.loc[3]
    assert np.hypot(p.x_m - t.x_m, p.y_m - t.y_m) < 0.6
    assert p.time_s == pytest.approx(t.time_s)
    # the car's strongest returns (near bumper corner ~5 m) are detected as static
    static = det[(det["frame"] == 3) & ~det["moving"]]
    assert (np.abs(static["range_m"] - 5.0) < 0.6).any()


def test_benchmark_command_prints_json(capsys):
    from blindspot.bench.dsp import main

    assert main(["--repeats", "2", "--warmup", "1", "--threads", "1", "--json"]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    summary = json.loads(last)
    assert set(summary) >= {"fps", "ms_per_frame", "steps", "n_detections"}
    assert summary["fps"] > 0 and summary["n_detections"] >= 1
    assert {"range_doppler", "cfar", "doa", "points"} <= set(summary["steps"])


def test_a_batch_gives_what_each_frame_gives(paper):
    """process_batch on three frames at once equals process on each frame: detections, angles,
    points, maps (the batch axis changes nothing but speed)."""
    radar, array, chain = paper
    rng = np.random.default_rng(4)
    cubes = np.stack([tone_cube(radar, array, CAR + [(12.5 - 0.3 * i, -0.7, 30.0 + 3 * i, 300.0)],
                                noise_power=NOISE, rng=rng) for i in range(3)])
    batch = chain.process_batch(cubes, np.array([10, 11, 12]), np.array([1.0, 1.1, 1.2]),
                                keep_maps=True, keep_spectra=True)
    for i in range(3):
        one = chain.process(cubes[i], frame=10 + i, time_s=1.0 + 0.1 * i)
        got = batch.detections[batch.detections.frame == 10 + i].reset_index(drop=True)
        pd.testing.assert_frame_equal(got, one.detections)
        pd.testing.assert_frame_equal(batch.points[batch.points.frame == 10 + i]
                                      .reset_index(drop=True), one.point)
        np.testing.assert_array_equal(batch.power[i], one.power)
        np.testing.assert_array_equal(batch.mask[i], one.mask)
        row, spec = batch.spectra[i]
        np.testing.assert_array_equal(spec, one.spectrum)
        assert batch.detections.iloc[row].frame == 10 + i
    assert len(batch.points) == 3
    with pytest.raises(ValueError, match="frames, chirps, tx, rx, samples"):
        chain.range_doppler(cubes[0])
