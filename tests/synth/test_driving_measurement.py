"""The fast driving measurement against the full FMCW chain (slow: a few minutes), and the
full chain's ego speed on simulated frames.

Truth used: the full simulation (FmcwSimulator cubes of the whole scene: parked cars, roadside,
the walking child, thermal noise, int16 ADC) through DrivingChain, and the scene's truth."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from omegaconf import OmegaConf

from blindspot import experiment as ex
from blindspot.config import compose
from blindspot.radar.driving import scene_truth
from blindspot.synth.driving_detection import (
    detect_driving_scene, point_error_statistics, points_from_detections,
)
from blindspot.synth.driving_measurement import measure_driving_scenes

REPO = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def both():
    cfg = compose(config_dir=REPO / "conf")
    group, named = ex.scenarios(cfg)
    radar, ego = ex.driving_radar(cfg), ex.ego_motion(cfg)
    chain = (ex.cfar(cfg), ex.doa(cfg), ex.detect(cfg))
    full, fast, truth, egos = [], [], [], []
    for kmh in (20.0, 60.0):
        sc = replace(named[group.figure_scene], speed_kmh=kmh, name=f"cpnco_{kmh:g}")
        tr = scene_truth(sc, group, radar.frame_period_s)
        tr = tr[(tr.range_m < ego.max_range_m - 2) & (tr.y_vehicle_m > 0.2)
                & (tr.angle_deg.abs() < 75) & ~tr.occluded]
        res = detect_driving_scene(sc, group, radar, *chain, ego, ex.sim(cfg), frames=tr.frame.to_numpy())
        full.append(points_from_detections(res.detections, res.ego, scene=sc.name,
                                           cluster_gap_m=ex.detect(cfg).cluster_gap_m,
                                           static_tolerance_mps=ego.static_tolerance_mps))
        fast.append(measure_driving_scenes([sc], group, radar, *chain, ego,
                                           frames={sc.name: tr.frame.to_numpy()}))
        truth.append(tr)
        egos.append(res.ego)
    import pandas as pd

    t = pd.concat(truth)
    return (point_error_statistics(pd.concat(full), t),
            point_error_statistics(pd.concat(fast).drop(columns=["pedestrian", "x_m", "y_m"]), t),
            pd.concat(egos))


@pytest.mark.xfail(reason="not validated yet: on the CPNCO frames at 20/40/60 km/h only 5 of 43 "
                   "visible frames give a point in either chain (the crossing child sits on the "
                   "static Doppler curve); detection rate equal, median error 0.23 vs 0.14 m on "
                   "those 5; on CPFA (117 frames) detection rate 0.44 fast vs 0.29 full, median "
                   "error +13 %, p90 -4 % (benchmarks/bench_driving.py --scene cpfa): the patch "
                   "lacks the static world's returns in the CFAR training cells",
                   strict=False)
def test_fast_measurement_within_10_percent_of_the_full_chain(both):
    full, fast, _ = both
    assert full["n_frames"] >= 20
    for key in ("detection_rate", "median_error_m", "p90_error_m"):
        assert fast[key] == pytest.approx(full[key], rel=0.10), (key, full, fast)


def test_full_chain_ego_speed_within_0p1_mps(both):
    _, _, ego = both
    err = (ego.ego_speed_mps - ego.true_speed_mps).to_numpy()
    assert np.isfinite(err).mean() > 0.9
    assert np.sqrt(np.nanmean(err**2)) < 0.1
