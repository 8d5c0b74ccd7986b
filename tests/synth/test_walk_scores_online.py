"""The benchmark's adaptive conformal ellipses: each walk's share inside them comes from the walks
before it only, its points ranked with the prior's scores of the same forecast step."""

from __future__ import annotations

import numpy as np
import pytest

from blindspot.synth.walk_scores import _check_online, _online_shares
from blindspot.traj.conformal import AdaptiveConformal

LEVELS = (0.5, 0.9, 0.95)


def test_a_walk_sees_only_the_walks_before_it():
    rng = np.random.default_rng(0)
    n, h, steps = 400, 5, 8
    d2 = rng.exponential(2.0, (n, h))
    lead = rng.integers(0, 3, n)
    prior = rng.exponential(2.0, (100, steps))
    online = AdaptiveConformal(LEVELS, 0.005, 100)
    base = _online_shares(online, prior, d2, lead)
    later = d2.copy()
    later[200:] *= 50.0                                      # every walk from 200 on changes
    after = _online_shares(online, prior, later, lead)
    for key in base:
        np.testing.assert_array_equal(after[key][:200], base[key][:200])   # before the change
        assert not np.array_equal(after[key][201:], base[key][201:])
    # exchangeable with the prior: each level's mean share within 2.5 pp of nominal
    for level in LEVELS:
        assert np.mean(base[f"online_coverage_{round(100 * level)}"]) == pytest.approx(
            level, abs=0.025)


def test_points_are_ranked_by_forecast_step_not_by_point_index():
    """The prior's steps differ tenfold in scale; walks with lead 2 have their point j at step
    j + 2: placed by step, their points are judged against the right step's scores."""
    rng = np.random.default_rng(1)
    steps, h, n = 6, 3, 600
    scale = np.array([1, 1, 10, 10, 10, 10.0])
    prior = rng.exponential(2.0, (300, steps)) * scale
    lead = np.full(n, 2)
    d2 = rng.exponential(2.0, (n, h)) * scale[2:2 + h]
    shares = _online_shares(AdaptiveConformal(LEVELS, 0.0, 300), prior, d2, lead)
    assert np.mean(shares["online_coverage_50"]) == pytest.approx(0.5, abs=0.03)
    # a walk whose points fall after the prior's last step has none scored: NaN, not 0
    out = _online_shares(AdaptiveConformal(LEVELS, 0.0, 300), prior, d2[:2],
                         np.array([2, steps]))
    assert np.isfinite(out["online_coverage_90"][0]) and np.isnan(out["online_coverage_90"][1])


def test_each_calibrated_predictor_gets_its_own_recorded_setting():
    from blindspot.synth.walk_scores import online_by_predictor
    from blindspot.traj.scale_tracker import ScaleTracker

    window, tracker = AdaptiveConformal(LEVELS, 0.005, 100, 3), ScaleTracker(LEVELS, 0.05, 100.0)
    priors = {"kalman": np.ones((3, 4)), "lstm": np.ones((3, 4))}
    got = online_by_predictor({"kalman": window.setting, "lstm": tracker.setting,
                               "not_calibrated": window.setting}, priors)
    assert got == {"kalman": window, "lstm": tracker}
    with pytest.raises(ValueError, match="expected a setting for every calibrated predictor, "
                                         "found none for \\['lstm'\\]"):
        online_by_predictor({"kalman": window.setting}, priors)
    with pytest.raises(TypeError, match="settings: expected a mapping .*found list"):
        online_by_predictor([window.setting], priors)
    with pytest.raises(TypeError, match="score_scene_walks: online: expected a mapping"):
        _check_online(window, priors, "score_scene_walks")     # one setting for all: refused
