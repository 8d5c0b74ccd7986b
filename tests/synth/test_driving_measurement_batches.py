"""The fast driving measurement's batching (blindspot.synth.driving_measurement.measure_driving):
its result does not depend on how the work is spread, only on what is measured.

Truth used: the measurement of a scene alone. The scatterer table of several scenes is padded to
the widest (three pedestrians' body parts, the most cluttered street); padding slots carry
1e-30 m^2 at -400 dB, so a batch of one scene must give that scene's own points to float64
rounding whichever scenes share the table, and the batches (each with its own noise stream)
must give the same points in one process or in worker processes."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig, EgoMotionConfig
from blindspot.radar.config import RadarConfig, SimConfig
from blindspot.radar.scenario import load_scenarios
from blindspot.config import compose
from blindspot.synth.driving_measurement import measure_driving

REPO = Path(__file__).resolve().parents[2]
FRAMES = np.arange(22, 28)  # six frames of each scene, one batch each (the child off-curve in 27)


@pytest.fixture(scope="module", params=["range_doppler", "range_doppler_angle"])
def setup(request):
    """The configured chain under each peak rule (``ego_motion.peak_search``)."""
    cfg = compose(config_dir=REPO / "conf")
    group, named = load_scenarios(cfg.scenario)
    args = (group, RadarConfig.from_cfg(cfg, "driving_radar"), CfarConfig.from_cfg(cfg, "driving_cfar"), DoaConfig.from_cfg(cfg), DetectConfig.from_cfg(cfg),
            replace(EgoMotionConfig.from_cfg(cfg), peak_search=request.param))
    return named, args, SimConfig.from_cfg(cfg).adc_headroom_db


def _run(scenes, setup, jobs=1):
    _, args, headroom = setup
    return measure_driving(scenes, *args, adc_headroom_db=headroom,
                           frames={s.name: FRAMES for s in scenes},
                           frames_per_batch=FRAMES.size, jobs=jobs)


def _assert_same(a: pd.DataFrame, b: pd.DataFrame) -> None:
    assert len(a) > 0
    pd.testing.assert_frame_equal(a.reset_index(drop=True), b.reset_index(drop=True),
                                  check_exact=False, rtol=1e-9, atol=1e-9)


def test_padding_to_a_wider_scene_and_worker_processes_change_nothing(setup):
    named = setup[0]
    narrow, wide = named["cpnco"], named["cpnco_bystanders"]   # 1 and 3 pedestrians
    assert len(wide.pedestrians) > len(narrow.pedestrians)
    alone = _run([narrow], setup)
    both = _run([narrow, wide], setup, jobs=2)   # batch 0: the narrow scene, padded to the wide
    _assert_same(alone.points, both.points[both.points.scene == narrow.name])
    _assert_same(alone.measured, both.measured[both.measured.scene == narrow.name])
    both_1 = _run([narrow, wide], setup, jobs=1)
    _assert_same(both.points, both_1.points)
    _assert_same(both.measured, both_1.measured)
