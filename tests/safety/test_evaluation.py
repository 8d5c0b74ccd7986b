"""Decisions and metrics: the first frame a threshold is reached (vectorised over thresholds),
the operating characteristic's ends, the oracle tracks' schema and track management, the
warning group's validation naming its keys."""

import numpy as np
import pandas as pd
import pytest

from blindspot.safety.config import OracleConfig, WarningConfig
from blindspot.safety.evaluation import (SceneInfo, aeb_thresholds, avoided_at_false_activation,
                                         operating_curve,
                                         scene_info, scene_results, summarise,
                                         trigger_frames)
from blindspot.safety.oracle import TRACK_COLUMNS, oracle_tracks
from blindspot.safety.predict import BackfilledHistory, track_histories, with_backfill
from blindspot.typed_config import ConfigError


def test_trigger_frames_first_reach_and_never():
    p = np.array([[0.0, 0.3, 0.2, 0.8], [0.1, 0.1, 0.1, 0.1]])
    got = trigger_frames(p, np.array([0.05, 0.25, 0.5, 0.9]))
    assert got.tolist() == [[1, 1, 3, 4], [0, 4, 4, 4]]


def _info(n_int, n_non):
    S = n_int + n_non
    return SceneInfo(np.array([f"s{i}" for i in range(S)]), np.full(S, 30.0),
                     np.r_[np.ones(n_int, bool), np.zeros(n_non, bool)], np.full(S, 50.0),
                     np.r_[np.full(n_int, 2.0), np.full(n_non, np.nan)], np.zeros(S))


def test_operating_curve_ends_and_scene_results():
    info = _info(2, 2)
    p = np.array([[0, 0.9, 0.9], [0, 0, 0.4], [0.2, 0.2, 0.2], [0, 0, 0]], float)
    # outcome table: a request at frame 0 or 1 avoids, at frame 2 or never hits at 20/30 km/h
    impact = np.array([[np.nan, np.nan, 20.0, 30.0]] * 4)
    curve = operating_curve(p, info, impact, np.array([0.1, 0.3, 0.95]), np.array([0.0, 0.1, 0.2]))
    assert curve.avoided_rate.tolist() == [0.5, 0.5, 0.0]
    assert curve.false_activation_rate.tolist() == [0.5, 0.0, 0.0]
    res = scene_results(p, info, impact, np.array([0.0, 0.1, 0.2]), warning_threshold=0.3,
                        aeb_threshold=0.5, decision_delay_s=0.1)
    assert res.avoided.tolist() == [True, False, False, False]
    assert res.impact_speed_kmh.tolist()[:2] == [0.0, 30.0]
    assert res.lead_time_s[0] == pytest.approx(2.0 - 0.2)           # warned at frame 1 + 0.1 s
    assert res.warn_frame.tolist() == [1, 2, -1, -1]


def test_a_request_before_the_lead_pedestrian_is_visible_is_counted_apart():
    """Two intruding scenes, both avoided: in the first the AEB fires from frame 0, while the
    lead pedestrian is still hidden (visible from 0.15 s: frame 2 is the first frame that
    starts after it), so it braked for someone else; in the second from frame 2, after it.
    Only the second counts for the avoided rate after visibility; the warning of the first
    (frame 0) came before visibility too, and visible_to_warning_s is negative there."""
    info = _info(2, 1)
    info = SceneInfo(info.scenes, info.speed_kmh, info.intruding, info.impact_pct,
                     info.collision_s, np.array([0.15, 0.15, 0.0]))
    p = np.array([[0.9, 0.9, 0.9], [0, 0, 0.9], [0, 0, 0]], float)
    impact = np.array([[np.nan, np.nan, np.nan, 30.0]] * 2 + [[np.nan] * 4])   # last: no hit
    res = scene_results(p, info, impact, np.array([0.0, 0.1, 0.2]), warning_threshold=0.3,
                        aeb_threshold=0.5, decision_delay_s=0.1)
    assert res.avoided.tolist() == [True, True, True]
    assert res.aeb_before_visible.tolist() == [True, False, False]
    assert res.warned_before_visible.tolist() == [True, False, False]
    assert res.visible_to_warning_s[0] == pytest.approx(0.1 - 0.15)
    m = summarise(res, n_bootstrap=50, seed=0)
    speed = m["by_speed_kmh"]["30"]
    assert speed["avoided_rate"] == m["avoided_rate"] == 1.0
    assert speed["aeb_before_visible_rate"] == m["aeb_before_visible_rate"] == 0.5
    assert speed["avoided_after_visible_rate"] == m["avoided_after_visible_rate"] == 0.5
    lo, hi = m["avoided_after_visible_rate_ci95"]
    assert lo < 0.5 < hi
    # the decision delay counts: fired from frame 1 (starts 0.1 s, decided at 0.2 s), before
    # the lead was seen at 0.15 s, is early, although its decision comes after 0.15 s
    late = np.array([[0, 0.9, 0.9], [0, 0, 0.9], [0, 0, 0]], float)
    res = scene_results(late, info, impact, np.array([0.0, 0.1, 0.2]), warning_threshold=0.3,
                        aeb_threshold=0.5, decision_delay_s=0.1)
    assert res.aeb_before_visible.tolist() == [True, False, False]
    # a lead pedestrian never visible: any request is before it
    never = SceneInfo(info.scenes, info.speed_kmh, info.intruding, info.impact_pct,
                      info.collision_s, np.array([np.nan, np.nan, 0.0]))
    res = scene_results(p, never, impact, np.array([0.0, 0.1, 0.2]), warning_threshold=0.3,
                        aeb_threshold=0.5, decision_delay_s=0.1)
    assert res.aeb_before_visible.tolist() == [True, True, False]


def test_scene_info_counts_the_lead_pedestrians_first_radar_point_as_seen():
    """The lead's first radar point (0.1 s; which points are the lead's is
    blindspot.safety.bound.lead_observed's, tested there) comes before its line of sight (frame
    2, its centre clearing the car): first_visible_s keeps the line of sight, first_seen_s the
    point; without a point time both are the line of sight; a request from frame 1 is then not
    before the lead was seen; a point time per scene of another shape is refused."""
    frames = np.arange(4)
    rows = [dict(scene="a", frame=f, time_s=0.1 * f, pedestrian=p, occluded=occ,
                 ego_speed_mps=30 / 3.6, behaviour=beh, collision=p == "p0",
                 collision_time_s=2.0 if p == "p0" else np.nan)
            for f in frames
            for p, beh, occ in (("p0", "cross", f < 2), ("p1", "stop_at_kerb", False))]
    truth = pd.DataFrame(rows)
    meta = {"a": {"pedestrians": [{"name": "p0", "impact_pct": 50.0},
                                  {"name": "p1", "impact_pct": 50.0}]}}
    info = scene_info(truth, meta, np.array(["a"]), first_point_s=np.array([0.1]))
    assert info.first_visible_s[0] == pytest.approx(0.2)
    assert info.first_seen_s[0] == pytest.approx(0.1)
    assert scene_info(truth, meta, np.array(["a"])).first_seen_s[0] == pytest.approx(0.2)
    never = scene_info(truth, meta, np.array(["a"]), first_point_s=np.array([np.nan]))
    assert never.first_seen_s[0] == pytest.approx(0.2)           # no point: the line of sight
    p = np.array([[0.0, 0.9, 0.9, 0.9]])
    impact = np.array([[np.nan] * 4 + [30.0]])
    res = scene_results(p, info, impact, 0.1 * frames, warning_threshold=0.3,
                        aeb_threshold=0.5, decision_delay_s=0.1)
    assert not res.aeb_before_visible[0] and res.visible_to_warning_s[0] == pytest.approx(0.0)
    with pytest.raises(ValueError, match="first_point_s"):
        scene_info(truth, meta, np.array(["a"]), first_point_s=np.array([0.1, 0.2]))


def test_the_operating_curve_agrees_with_scene_results_at_every_threshold():
    """Two ways to the same numbers: the vectorised sweep (operating_curve) and the per-scene
    decisions at one threshold (scene_results, summarise), on random risks, outcomes and first
    sightings, including requests before the lead pedestrian was seen."""
    rng = np.random.default_rng(3)
    n_int, n_non, F = 30, 20, 12
    info = _info(n_int, n_non)
    times = 0.1 * np.arange(F)
    # first sightings between frames, on a frame's start (what real data gives: the boundary)
    # and never
    seen = np.where(rng.random(n_int + n_non) < 0.5, rng.uniform(0, 1.2, n_int + n_non),
                    times[rng.integers(0, F, n_int + n_non)])
    seen[rng.random(n_int + n_non) < 0.1] = np.nan
    info = SceneInfo(info.scenes, info.speed_kmh, info.intruding, info.impact_pct,
                     info.collision_s, info.first_visible_s, seen)
    p = rng.random((n_int + n_non, F)) ** 3                 # the AEB's (gated) risk
    p_warn = rng.random((n_int + n_non, F))                   # the warning's: another one
    impact = np.where(rng.random((n_int + n_non, F + 1)) < 0.5, np.nan, 25.0)
    thresholds = np.linspace(0.05, 0.95, 19)
    curve = operating_curve(p, info, impact, thresholds, times)
    for t, row in zip(thresholds, curve.itertuples()):
        res = scene_results(p_warn, info, impact, times, warning_threshold=0.5,
                            aeb_threshold=t, decision_delay_s=0.1, p_aeb=p)
        m = summarise(res, n_bootstrap=100, seed=0)
        assert row.avoided_rate == pytest.approx(m["avoided_rate"])
        assert row.avoided_after_visible_rate == pytest.approx(m["avoided_after_visible_rate"])
        assert row.false_activation_rate == pytest.approx(m["false_activation_rate"])
    assert (curve.avoided_after_visible_rate < curve.avoided_rate).any()   # the case is live
    with pytest.raises(ValueError, match="operating_curve: frame_times"):
        operating_curve(p, info, impact, thresholds, times[:-1])


def test_the_threshold_grid_is_even_in_the_unit_interval_plus_its_tail():
    assert aeb_thresholds(3).tolist() == [0.25, 0.5, 0.75]
    got = aeb_thresholds(99, (0.9999, 0.999, 0.99, 0.35))     # 0.99, 0.35 on the grid already
    assert len(got) == 101 and got[-2:].tolist() == [0.999, 0.9999]
    assert np.sum(np.isclose(got, 0.35, rtol=0, atol=1e-9)) == 1   # 0.35000000000000003 once
    assert np.all(np.diff(got) > 0)
    with pytest.raises(ValueError, match="aeb_thresholds: tail: expected thresholds in"):
        aeb_thresholds(9, (1.0,))
    assert aeb_thresholds(1, 0.999).tolist() == [0.5, 0.999]          # a scalar tail
    with pytest.raises(ValueError, match="aeb_thresholds: n: expected an integer >= 1"):
        aeb_thresholds(0)


def test_avoided_at_false_activation_reads_the_curve_at_each_level():
    """The operating characteristic of the case above, read at false-activation levels: at
    most 0 % gives the thresholds 0.3 and 0.95 (avoided 0.5 and 0.0), at most 50 % all three;
    no level below the curve's lowest false-activation rate is met (None)."""
    info = _info(2, 2)
    p = np.array([[0, 0.9, 0.9], [0, 0, 0.4], [0.2, 0.2, 0.2], [0, 0, 0]], float)
    impact = np.array([[np.nan, np.nan, 20.0, 30.0]] * 4)
    curve = operating_curve(p, info, impact, np.array([0.1, 0.3, 0.95]), np.array([0.0, 0.1, 0.2]))
    assert avoided_at_false_activation(curve, (0.0, 0.01, 0.5)) == {"0": 0.5, "0.01": 0.5,
                                                                     "0.5": 0.5}
    noisy = curve.assign(false_activation_rate=[0.5, 0.25, 0.25], avoided_rate=[1.0, 0.5, 0.0])
    assert avoided_at_false_activation(noisy, (0.1, 0.25, 1.0)) == {"0.1": None, "0.25": 0.5,
                                                                     "1": 1.0}


def test_oracle_tracks_schema_confirmation_coasting_and_restart():
    frames = [0, 1, 2, 3, 10, 11, 12]
    pts = pd.DataFrame({"scene": "a", "pedestrian": "p0", "frame": frames,
                        "x_m": 1.0 - 0.1 * np.array(frames), "y_m": 0.0})
    tr = oracle_tracks(pts, OracleConfig(0.5, 0.05, 2.0, 3, 2), 0.1, last_frame=13)
    assert list(tr.columns[:len(TRACK_COLUMNS)]) == list(TRACK_COLUMNS)
    first = tr[tr.track_id == 0]
    assert first.frame.tolist() == [0, 1, 2, 3, 4, 5]               # two coasted frames
    assert first.confirmed.tolist() == [False, False, True, True, True, True]
    assert first.coasting.tolist() == [False] * 4 + [True] * 2
    assert tr[tr.track_id == 1].frame.tolist() == [10, 11, 12, 13]   # a new track after the gap
    assert first.vx_mps.iloc[3] == pytest.approx(-1.0, abs=0.15)     # -0.1 m per 0.1 s frame


def test_histories_are_right_aligned_and_backfilled_at_constant_velocity():
    tr = pd.DataFrame({"group": "a", "track_id": 0, "frame": [5, 6, 7],
                       "x_m": [0.0, 0.1, 0.2], "y_m": 0.0})
    h = track_histories(tr, 4)
    assert np.isnan(h[0, :3]).all() and h[0, 3, 0] == 0.0
    assert h[2, 1:, 0].tolist() == pytest.approx([0.0, 0.1, 0.2])
    filled = BackfilledHistory(None, 6, "cv_backfill", k=2).fill(h[2:])
    assert filled[0, :, 0] == pytest.approx([-0.3, -0.2, -0.1, 0.0, 0.1, 0.2])
    held = BackfilledHistory(None, 6, "hold_first").fill(h[2:])
    assert held[0, :, 0] == pytest.approx([0.0, 0.0, 0.0, 0.0, 0.1, 0.2])


def test_only_fixed_window_predictors_get_their_history_backfilled():
    from types import SimpleNamespace

    from blindspot.traj.baselines import ConstantVelocity

    calibrated = object()
    wrapped = with_backfill(calibrated, SimpleNamespace(window=20), "hold_first")
    assert isinstance(wrapped, BackfilledHistory)
    assert (wrapped.base, wrapped.window, wrapped.mode) == (calibrated, 20, "hold_first")
    assert with_backfill(calibrated, ConstantVelocity(), "cv_backfill") is calibrated


def test_warning_config_errors_name_the_key():
    from omegaconf import OmegaConf
    from pathlib import Path

    base = OmegaConf.to_container(OmegaConf.load(
        Path(__file__).resolve().parents[2] / "conf" / "warning" / "default.yaml"))
    WarningConfig.from_mapping(base)
    with pytest.raises(ConfigError, match="warning.warning_threshold"):
        WarningConfig.from_mapping({**base, "warning_threshold": 0.9, "aeb_threshold": 0.5})
    with pytest.raises(ConfigError, match="warning.aeb.decel_mps2"):
        WarningConfig.from_mapping({**base, "aeb": {**base["aeb"], "decel_mps2": -1.0}})
    with pytest.raises(ConfigError, match="warning.predictors"):
        WarningConfig.from_mapping({**base, "predictors": ["oracle"]})
    # the moving-object test's keys moved to the tracker (issue 42): an old key names its new one
    with pytest.raises(ConfigError, match="tracker.moving.doppler_llr"):
        WarningConfig.from_mapping({**base, "moving_doppler_llr": "marginal"})


def test_moving_config_errors_name_the_key():
    from omegaconf import OmegaConf
    from pathlib import Path

    from blindspot.track.config import MovingConfig

    base = OmegaConf.to_container(OmegaConf.load(
        Path(__file__).resolve().parents[2] / "conf" / "tracker" / "gnn_cv.yaml"))["moving"]
    MovingConfig.from_mapping(base)
    with pytest.raises(ConfigError, match="tracker.moving.doppler_log_ratio_floor"):
        MovingConfig.from_mapping({**base, "doppler_log_ratio_floor": -1.0})
    with pytest.raises(ConfigError, match="tracker.moving.doppler_llr"):
        MovingConfig.from_mapping({**base, "doppler_llr": "exact"})
    for bad in ([0.5, 0.5], [0.8, 0.3], [0.0, 0.8], [0.3]):      # equal, swapped, zero, one
        with pytest.raises(ConfigError, match="tracker.moving.doppler_spread_std_mps"):
            MovingConfig.from_mapping({**base, "doppler_spread_std_mps": bad})
    ok = MovingConfig.from_mapping({**base, "doppler_spread_std_mps": [0.27, 0.79]})
    assert ok.doppler_spread_std_mps == (0.27, 0.79)


def test_a_skipped_frame_inside_a_history_is_interpolated_from_its_past_neighbours():
    h = np.array([[[np.nan, np.nan], [0.0, 0.0], [np.nan, np.nan], [0.2, 0.0], [0.3, 0.0]]])
    filled = BackfilledHistory(None, 5, "cv_backfill", k=2).fill(h)
    assert np.isfinite(filled).all()
    assert filled[0, :, 0] == pytest.approx([-0.1, 0.0, 0.1, 0.2, 0.3])
