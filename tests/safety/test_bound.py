"""Perception-limited bounds (blindspot.safety.bound): the M-of-N confirmation frame against a
frame-by-frame reference, the observed-frame table, and, through the scenario group's own
Euro NCAP crossings and the outcome model, a request at a true TTC above the closed-form last
point to brake avoids the child and one below it does not."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from omegaconf import OmegaConf

from blindspot.radar.driving import load_scenarios, scene_truth
from blindspot.safety.assess import perception_bounds
from blindspot.safety.bound import (BOUNDS, BoundError, bound_results, bound_summary,
                                    first_confirmed, first_frame, lead_observed, logged_bounds)
from blindspot.safety.braking import BrakingModel
from blindspot.safety.config import WarningConfig
from blindspot.safety.risk import EgoShape

ROOT = Path(__file__).resolve().parents[2]


def _confirmed_reference(row: np.ndarray, m: int, n: int) -> int:
    for k in range(len(row)):
        if row[max(0, k - n + 1):k + 1].sum() >= m:
            return k
    return len(row)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 6).flatmap(lambda n: st.tuples(st.integers(1, n), st.just(n))),
       st.lists(st.lists(st.booleans(), min_size=12, max_size=12), min_size=1, max_size=5))
def test_first_confirmed_is_the_first_frame_with_m_of_the_last_n(mn, rows):
    m, n = mn
    obs = np.array(rows, bool)
    want = [_confirmed_reference(r, m, n) for r in obs]
    assert first_confirmed(obs, m, n).tolist() == want
    assert first_confirmed(obs, 1, n).tolist() == first_frame(obs).tolist()


def test_bad_confirmation_and_points_are_named():
    with pytest.raises(BoundError, match="confirm_m <= confirm_n"):
        first_confirmed(np.zeros((1, 5), bool), 4, 3)
    with pytest.raises(BoundError,
                       match="data/driving/points.parquet: missing columns \\['source'\\]"):
        lead_observed(pd.DataFrame({"scene": ["a"], "frame": [0]}), np.array(["a"]),
                      np.arange(3), where="data/driving/points.parquet")


def test_lead_observed_marks_only_the_lead_in_known_scenes_and_frames():
    pts = pd.DataFrame({"scene": ["a", "a", "b", "c", "a"], "frame": [1, 2, 0, 1, 9],
                        "source": ["p0", "static", "p0", "p0", "p0"]})
    seen = lead_observed(pts, np.array(["a", "b"]), np.arange(4))
    assert seen.tolist() == [[False, True, False, False], [True, False, False, False]]


@pytest.fixture(scope="module")
def crossings():
    group, named = load_scenarios(OmegaConf.load(ROOT / "conf" / "scenario" / "euro_ncap.yaml"))
    scenes = [replace(named["cpnco"], speed_kmh=v, name=f"cpnco_{v:g}") for v in (20.0, 40.0, 60.0)]
    scenes.append(replace(named["stop_at_kerb"], speed_kmh=40.0, name="kerb_40"))
    truth = pd.concat([scene_truth(s, group, 0.1) for s in scenes], ignore_index=True)
    truth["set"] = "test"
    meta = {s.name: {"pedestrians": [{"name": "p0", "impact_pct": 50.0}]} for s in scenes}
    bodies = {b.name: (b.length_m, b.width_m, b.ref_from_front_m) for b in group.bodies}
    w = WarningConfig.from_mapping(OmegaConf.to_container(
        OmegaConf.load(ROOT / "conf" / "warning" / "default.yaml")))
    return truth, meta, bodies, EgoShape(group.ego.width_m, group.ego.length_m), w


def _points_from(truth, first_ttc_s):
    """The lead pedestrian seen on every frame from the first whose true TTC is at most
    ``first_ttc_s`` (scene -> s; the kerb scene from the same frame as the 40 km/h crossing)."""
    rows = []
    for scene, g in truth[truth.pedestrian == "p0"].groupby("scene"):
        ttc = first_ttc_s.get(scene, first_ttc_s["cpnco_40"])
        ref = (truth[(truth.scene == "cpnco_40") & (truth.pedestrian == "p0")]
               if scene == "kerb_40" else g)
        k0 = int(ref.frame[ref.ttc_s <= ttc + 1e-9].min())
        rows += [(scene, f, "p0") for f in range(k0, int(g.frame.max()) + 1)]
    return pd.DataFrame(rows, columns=["scene", "frame", "source"])


def test_a_request_above_the_last_point_to_brake_avoids_and_one_below_does_not(crossings):
    """Radar points from the first frame whose request (a decision delay later) comes 0.05-0.15 s
    (one frame) above the closed-form last point to brake avoid the crossing child at every
    speed; 0.05-0.15 s below it, no speed is avoided. The M-of-N bound of points on every frame
    requests M - 1 frames later; the kerb scene (no intrusion) never requests."""
    truth, meta, bodies, shape, w = crossings
    b = BrakingModel.from_config(w.aeb)
    speeds = {"cpnco_20": 20 / 3.6, "cpnco_40": 40 / 3.6, "cpnco_60": 60 / 3.6}
    early = {k: float(b.stop_ttc(v)) + w.decision_delay_s + 0.15 for k, v in speeds.items()}
    late = {k: float(b.stop_ttc(v)) + w.decision_delay_s - 0.05 for k, v in speeds.items()}
    for first, avoided in ((early, True), (late, False)):
        out = perception_bounds(truth, meta, _points_from(truth, first), w, bodies=bodies,
                                shape=shape, confirm=(1, 1), evaluated_set="test")
        by = out["radar_point"]["by_speed_kmh"]
        assert [by[s]["avoided_rate"] for s in ("20", "40", "60")] == [float(avoided)] * 3
        assert out["radar_point"]["false_activation_rate"] == 0.0
        assert out["radar_point"]["n_intruding"] == 3 and out["radar_point"]["n_non_intruding"] == 1
    m = 3
    out = perception_bounds(truth, meta, _points_from(truth, early), w, bodies=bodies,
                            shape=shape, confirm=(m, 5), evaluated_set="test")
    lead = {k: out[k]["by_speed_kmh"]["40"]["lead_time_s_median"] for k in BOUNDS}
    assert lead["radar_point"] - lead["confirmed_track"] == pytest.approx(0.1 * (m - 1))
    assert lead["line_of_sight"] >= lead["radar_point"] - 1e-9
    # line of sight: the request leaves decision_delay_s after the first non-occluded frame
    p0 = truth[(truth.pedestrian == "p0") & truth.scene.str.startswith("cpnco")]
    first_seen = p0[~p0.occluded.astype(bool)].groupby("scene").time_s.min()
    want = p0.groupby("scene").collision_time_s.first() - first_seen - w.decision_delay_s
    got = {s: out["line_of_sight"]["by_speed_kmh"][s.split("_")[1]]["lead_time_s_median"]
           for s in want.index}
    assert got == pytest.approx(want.to_dict(), abs=1e-9)
    assert out["settings"]["confirm_m"] == m
    # a perfect decider responds to the lead pedestrian: never before it was seen
    assert all(out[k]["aeb_before_visible_rate"] == 0.0 for k in BOUNDS)


def test_bound_results_checks_its_shapes(crossings):
    from blindspot.safety.evaluation import SceneInfo

    info = SceneInfo(np.array(["a"]), np.array([40.0]), np.array([True]), np.array([50.0]),
                     np.array([2.0]), np.array([1.0]))
    with pytest.raises(BoundError, match="outcome table"):
        bound_results(info, np.zeros((1, 3)), np.arange(3) * 0.1, np.array([1]), 0.1)
    res = bound_results(info, np.array([[np.nan, 20.0, 30.0, 40.0]]), np.arange(3) * 0.1,
                        np.array([1]), 0.1)
    assert res.aeb_frame.tolist() == [1] and res.impact_speed_kmh.tolist() == [20.0]


def test_best_request_frame_prefers_the_first_avoiding_frame_from_the_first_on():
    """From the first frame of information on: the first avoiding request (NaN), else the
    lowest impact speed; never before the first frame; F where there is no information. Two
    frames after the first avoid here, as when an early stop leaves the car in a later
    crosser's path (a 0 km/h contact)."""
    from blindspot.safety.bound import best_request_frame

    nan = np.nan
    impact = np.array([[nan, 0.0, nan, 5.0, 30.0],     # first 1: frame 2 avoids
                       [nan, 20.0, 10.0, 15.0, 30.0],  # first 1: lowest impact at 2
                       [nan, nan, nan, nan, 30.0],     # no information: never (F = 4)
                       [5.0, 3.0, 3.0, 9.0, 30.0]])    # a tie: the earlier frame
    first = np.array([1, 1, 4, 0])
    assert best_request_frame(impact, first).tolist() == [2, 2, 4, 1]
    with pytest.raises(BoundError, match="outcome table"):
        best_request_frame(impact, first[:2])


def test_line_of_sight_onset_is_the_emergence_that_leads_to_the_crossing():
    """Issue 40: a child glimpsed standing ahead, hidden again, then stepping out is seen from
    the last emergence before the collision, not from the glimpse."""
    from blindspot.safety.evaluation import line_of_sight_onset

    t = np.arange(10) * 0.1
    occ = [True, False, False, True, True, True, False, False, False, False]   # glimpse at 0.1
    p0 = pd.DataFrame({"scene": "a", "time_s": t, "occluded": occ, "collision_time_s": 0.9})
    never_hidden = pd.DataFrame({"scene": "b", "time_s": t, "occluded": False,
                                 "collision_time_s": np.nan})
    onset = line_of_sight_onset(pd.concat([p0, never_hidden]))
    assert onset["a"] == pytest.approx(0.6)
    assert onset["b"] == pytest.approx(0.0)


def _summary(avoided, by_speed):
    return {"avoided_rate": avoided, "avoided_after_visible_rate": avoided, "goals": {},
            "by_speed_kmh": by_speed}


def test_logged_bounds_keep_the_rates_and_drop_what_is_missing():
    bounds = {"radar_point": _summary(0.7, {"10": {"avoided_rate": 1.0,
                                                   "impact_speed_kmh_mean": 0.0,
                                                   "lead_time_s_median": None},
                                            "60": {"avoided_rate": 0.3,
                                                   "impact_speed_kmh_mean": None,
                                                   "lead_time_s_median": 1.1}}),
              "settings": {"seed": 3}}
    assert logged_bounds(bounds) == {"radar_point": {"avoided_rate": 0.7, "by_speed_kmh": {
        "10": {"avoided_rate": 1.0, "impact_speed_kmh_mean": 0.0},
        "60": {"avoided_rate": 0.3, "lead_time_s_median": 1.1}}}}
    assert bound_summary("held", bounds) == [
        "held radar_point: avoided 0.700; by speed 10: 1.00 avoided, 0.0 km/h, "
        "60: 0.30 avoided, - km/h"]
    with pytest.raises(BoundError, match="bound 'radar_point'"):
        logged_bounds({"radar_point": {"avoided_rate": 0.7}})
    with pytest.raises(BoundError, match="bound 'radar_point'"):
        logged_bounds({"radar_point": {"avoided_rate": 0.7, "by_speed_kmh": None}})
    with pytest.raises(BoundError, match="bounds: expected"):
        bound_summary("held", None)
    with pytest.raises(BoundError, match="stage"):
        bound_summary("", bounds)
