"""The AEB gate by the time the brakes need (warning.aeb_gate): the last point to brake against
the braking model's own simulated stop, rows above the gate never request, the gate off
reproduces the ungated decisions, and the held-out split."""

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings, strategies as st

from blindspot.safety.assess import frame_risks
from blindspot.safety.braking import BrakingModel
from blindspot.safety.config import WarningConfig
from blindspot.safety.evaluation import (SceneInfo, aeb_gate_s, replicate_half,
                                         scene_frame_risk, scene_results)
from blindspot.typed_config import ConfigError

KMH = 3.6


def _simulated_stop_distance(v0, T, j, a, dt=1e-5):
    """Distance to standstill by integrating the jerk-limited deceleration profile (latency T,
    ramp at jerk j to a, held) numerically, independent of the closed forms."""
    t = np.arange(0.0, T + a / j + v0 / a + 1.0, dt)
    decel = np.clip(j * (t - T), 0.0, a)
    v = v0 - np.concatenate([[0.0], np.cumsum((decel[1:] + decel[:-1]) / 2 * dt)])
    v = np.maximum(v, 0.0)
    return float(np.sum((v[1:] + v[:-1]) / 2 * dt))


@pytest.mark.parametrize("speed_kmh", [10.0, 20.0, 30.0, 40.0, 50.0, 60.0])
def test_last_point_to_brake_is_the_simulated_stop_at_a_stationary_obstacle(speed_kmh):
    b = BrakingModel(0.2, 30.0, 9.8)                     # conf/warning/default.yaml's aeb
    v0 = speed_kmh / KMH
    d = _simulated_stop_distance(v0, 0.2, 30.0, 9.8)
    # an obstacle at d is reached at constant speed after d / v0: the TTC of the last request
    # that still stops the car at it
    assert b.stop_ttc(v0) == pytest.approx(d / v0, rel=1e-4)
    # requested at a TTC 1 % above it the braked car stops short, 1 % below it does not
    for factor, stops in ((1.01, True), (0.99, False)):
        gap = v0 * b.stop_ttc(v0) * factor
        s, _ = b.motion(v0, b.stop_time(v0))
        assert bool(s < gap) is stops
    # the gate adds the decision delay and the margin
    g = aeb_gate_s(np.array([v0]), b, gate="stopping_time", margin_s=0.3, decision_delay_s=0.1)
    assert g[0] == pytest.approx(d / v0 + 0.4, rel=1e-4)


def test_last_point_to_brake_inside_the_ramp():
    b = BrakingModel(0.1, 10.0, 9.8)                     # ramp 0.98 s: 1 m/s stops within it
    d = _simulated_stop_distance(1.0, 0.1, 10.0, 9.8)
    assert b.stop_ttc(1.0) == pytest.approx(d / 1.0, rel=1e-4)
    with pytest.raises(ValueError, match="speeds must be > 0"):
        b.stop_ttc(0.0)


def test_a_standing_ego_takes_the_limit_of_the_gate():
    """v -> 0: the last point to brake tends to the braking latency (nothing to stop); a
    standing ego's gate is that limit plus delay and margin, continuous with a creeping ego's,
    so a row far from contact cannot request AEB for a standing car."""
    b = BrakingModel(0.2, 30.0, 9.8)
    g = aeb_gate_s(np.array([0.0, -1.0, 1e-6, 10.0]), b, gate="stopping_time", margin_s=0.2,
                   decision_delay_s=0.1)
    assert g[0] == g[1] == pytest.approx(0.2 + 0.1 + 0.2)
    assert g[2] == pytest.approx(g[0], abs=1e-3) and g[3] > g[0]
    rows = _rows("a", np.arange(3), 0.9, [3.0, 0.6, 0.4])
    _, p_aeb = frame_risks(rows, np.array(["a"]), np.zeros(1), 3, b, gate="stopping_time",
                           margin_s=0.2, decision_delay_s=0.1)
    assert p_aeb.tolist() == [[0.0, 0.0, 0.9]]


def _rows(scene, frame, p, ttc):
    return pd.DataFrame({"group": scene, "frame": frame, "p_collision": p, "ttc_s": ttc})


@settings(max_examples=40, deadline=None)
@given(speed_kmh=st.floats(5.0, 80.0), margin=st.floats(0.0, 2.0), p=st.floats(0.01, 1.0),
       over=st.floats(1e-3, 3.0))
def test_a_row_above_the_gate_never_requests(speed_kmh, margin, p, over):
    b = BrakingModel(0.2, 30.0, 9.8)
    v = speed_kmh / KMH
    gate = b.stop_ttc(v) + 0.1 + margin
    scenes = np.array(["a", "b", "c"])
    # scene a: TTC just above the gate every frame; b: no predicted TTC (NaN); c: at the gate
    rows = pd.concat([_rows("a", np.arange(5), p, gate + over),
                      _rows("b", np.arange(5), p, np.nan),
                      _rows("c", [3], p, gate)], ignore_index=True)
    p_warn, p_aeb = frame_risks(rows, scenes, np.full(3, v), 5, b, gate="stopping_time",
                                margin_s=margin, decision_delay_s=0.1)
    assert np.all(p_aeb[:2] == 0.0)                      # never requests
    assert p_aeb[2, 3] == p and p_aeb[2].sum() == p      # at the gate: counts
    assert np.all(p_warn[:2] == p)                       # the warning is not gated
    with pytest.raises(ValueError, match="warning.aeb_gate"):
        aeb_gate_s(np.array([v]), b, gate="ttc", margin_s=0.0, decision_delay_s=0.1)


def test_gate_off_reproduces_the_ungated_decisions():
    # the case of test_evaluation.test_operating_curve_ends_and_scene_results, as risk rows
    # (several tracks per frame: the scene-frame risk is their maximum)
    p = np.array([[0, 0.9, 0.9], [0, 0, 0.4], [0.2, 0.2, 0.2], [0, 0, 0]], float)
    scenes = np.array(["s0", "s1", "s2", "s3"])
    s, f = np.nonzero(p)
    rows = pd.concat([_rows(scenes[s], f, p[s, f], 0.5), _rows(scenes[s], f, p[s, f] / 2, 2.9)],
                     ignore_index=True)
    info = SceneInfo(scenes, np.full(4, 30.0), np.array([True, True, False, False]),
                     np.full(4, 50.0), np.array([2.0, 2.0, np.nan, np.nan]), np.zeros(4))
    impact = np.array([[np.nan, np.nan, 20.0, 30.0]] * 4)
    b = BrakingModel(0.2, 30.0, 9.8)
    p_warn, p_aeb = frame_risks(rows, scenes, np.full(4, 30 / KMH), 3, b, gate="none",
                                margin_s=0.7, decision_delay_s=0.1)
    assert np.array_equal(p_warn, p) and np.array_equal(p_aeb, p)
    kw = dict(warning_threshold=0.3, aeb_threshold=0.5, decision_delay_s=0.1)
    res = scene_results(p_warn, info, impact, np.array([0.0, 0.1, 0.2]), p_aeb=p_aeb, **kw)
    assert res.avoided.tolist() == [True, False, False, False]
    assert res.impact_speed_kmh.tolist()[:2] == [0.0, 30.0]
    assert res.warn_frame.tolist() == [1, 2, -1, -1]
    pd.testing.assert_frame_equal(res, scene_results(p, info, impact, np.array([0.0, 0.1, 0.2]),
                                                     **kw))
    # gated at 30 km/h (gate 0.78 s + 0.1 s): the TTC-0.5 s rows count, the 2.9 s ones not;
    # the far rows carry the larger risk here, so a frame's maximum cannot hide them
    far = pd.concat([_rows(scenes[s], f, p[s, f], 2.9), _rows(scenes[s], f, p[s, f] / 2, 0.5)],
                    ignore_index=True)
    p_w, p_g = frame_risks(far, scenes, np.full(4, 30 / KMH), 3, b, gate="stopping_time",
                           margin_s=0.0, decision_delay_s=0.1)
    assert np.array_equal(p_w, p)                        # the warning sees every row
    assert np.array_equal(p_g, p / 2)                    # the AEB only the near ones
    assert np.array_equal(scene_frame_risk(far, scenes, 3, gate_s=np.full(len(far), 1.0)),
                          p / 2)


def test_replicate_half_splits_every_cell_and_names_a_bad_scene():
    names = np.array([f"mc_{v}kmh_{p}pct_{k}_{i}" for v in (10, 60) for p in (25, 75)
                      for k in ("int", "non") for i in range(6)])
    tune = replicate_half(names)
    assert tune.sum() == len(names) / 2
    cells = pd.Series(tune).groupby(pd.Series(names).str.rsplit("_", n=1).str[0]).sum()
    assert (cells == 3).all()
    with pytest.raises(ValueError, match="'cpnco'"):
        replicate_half(np.array(["mc_10kmh_25pct_int_0", "cpnco"]))


def test_gate_config_is_typed():
    from pathlib import Path

    from omegaconf import OmegaConf

    base = OmegaConf.to_container(OmegaConf.load(
        Path(__file__).resolve().parents[2] / "conf" / "warning" / "default.yaml"))
    w = WarningConfig.from_mapping(base)
    # the README's default: the gate on, at the margin tuned on the even replicates
    assert (w.aeb_gate, w.aeb_gate_margin_s) == ("stopping_time", pytest.approx(0.2))
    with pytest.raises(ConfigError, match="warning.aeb_gate"):
        WarningConfig.from_mapping({**base, "aeb_gate": "ttc"})
    with pytest.raises(ConfigError, match="warning.aeb_gate_margin_s"):
        WarningConfig.from_mapping({**base, "aeb_gate_margin_s": -0.1})


def test_a_request_at_the_gate_stops_the_outcome_model_short_of_a_standing_pedestrian():
    """Through the outcome model (boxes, contact, braked ego): a pedestrian standing in the
    path 5 s ahead; requested at a TTC (to first contact) 2 % above TTC_stop the car stops
    short; 2 % below it, it hits with what is left of the stop, v = sqrt(2 a dd) (dd = 2 % of
    v TTC_stop, the last metres under full deceleration), at each Euro NCAP ego speed."""
    from blindspot.safety.outcome import SceneArrays, braked_impacts, pedestrian_boxes
    from blindspot.safety.risk import EgoShape

    b = BrakingModel(0.2, 30.0, 9.8)
    v = np.array([10.0, 20.0, 30.0, 40.0, 50.0, 60.0]) / KMH
    S, F = len(v), 81
    t = np.arange(F) * 0.1
    ped_y = 5.0 * v + 0.5                                  # reference point; box behind it
    pos = np.zeros((S, 1, F, 2))
    pos[..., 1] = ped_y[:, None, None]
    sa = SceneArrays(np.array([f"s{i}" for i in range(S)]), t, np.zeros(S), np.zeros(S), v, pos,
                     np.zeros((S, 1, F, 2)), np.ones((S, 1), bool), np.full((S, 1), 0.6),
                     np.full((S, 1), 0.5), np.full((S, 1), 0.36))
    tg, lo, hi = pedestrian_boxes(sa, 0.001, 0.0)
    contact_ttc = lo[:, 0, 0, 1] / v                       # TTC to first contact at t = 0
    ttc_stop = b.stop_ttc(v)
    trig = np.stack([contact_ttc - 1.02 * ttc_stop, contact_ttc - 0.98 * ttc_stop], axis=1)
    _, speed = braked_impacts(sa, tg, lo, hi, trig, b, EgoShape(1.8, 4.5))
    assert np.all(np.isnan(speed[:, 0]))                   # stopped short: avoided
    dd = 0.02 * v * ttc_stop
    assert speed[:, 1] == pytest.approx(np.sqrt(2 * 9.8 * dd), rel=0.02)


def test_last_point_to_brake_is_where_the_euro_ncap_crossings_stop_being_avoidable():
    """On the scenario group's own crossing scenes (CPNCO, CPNA 25 / 75 %; the child walks
    across the path, it does not stand in it), the latest request that still avoids the
    collision comes at a true TTC of TTC_stop (to the 0.01 s step of the sweep; the far-side
    CPNA-75 child may clear the path a little earlier at high speed)."""
    from dataclasses import replace
    from pathlib import Path

    from omegaconf import OmegaConf

    from blindspot.radar.driving import load_scenarios, scene_truth
    from blindspot.safety.outcome import braked_impacts, pedestrian_boxes, scene_arrays
    from blindspot.safety.risk import EgoShape

    conf = Path(__file__).resolve().parents[2] / "conf" / "scenario" / "euro_ncap.yaml"
    group, named = load_scenarios(OmegaConf.load(conf))
    bodies = {b.name: (b.length_m, b.width_m, b.ref_from_front_m) for b in group.bodies}
    ego = EgoShape(group.ego.width_m, group.ego.length_m)
    b = BrakingModel(0.2, 30.0, 9.8)
    scenes = [replace(named[n], speed_kmh=v, name=f"{n}_{v:g}")
              for n in ("cpnco", "cpna25", "cpna75") for v in (20.0, 40.0, 60.0)]
    truth = pd.concat([scene_truth(s, group, 0.1) for s in scenes], ignore_index=True)
    sa = scene_arrays(truth, bodies)
    t, lo, hi = pedestrian_boxes(sa, 0.002, 3.0)
    t_col = truth.groupby("scene").collision_time_s.min().reindex(sa.scenes).to_numpy()
    ttc = np.arange(0.2, 1.6, 0.01)
    _, v = braked_impacts(sa, t, lo, hi, t_col[:, None] - ttc[None, :], b, ego)
    critical = np.where(np.isnan(v), ttc, np.inf).min(axis=1)      # latest avoiding request
    excess = critical - b.stop_ttc(sa.speed_mps)
    near = ~np.char.startswith(sa.scenes.astype(str), "cpna75")
    assert np.all(np.abs(excess[near]) <= 0.015)
    assert np.all(excess <= 0.015)                        # never later than the gate says
