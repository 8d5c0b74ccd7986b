"""The online ellipses' candidates of a config group, and a chosen setting rebuilt from what the
metrics files record of it."""

from __future__ import annotations

import pytest

from blindspot.traj.config import CalibrationConfig, EthUcyConfig
from blindspot.traj.conformal import AdaptiveConformal, ConformalError
from blindspot.traj.online import online_candidates, online_from_setting
from blindspot.traj.scale_tracker import ScaleTracker

LEVELS = (0.5, 0.9, 0.95)


def test_the_calibration_stage_chooses_among_the_ethucy_folds_candidates(composed_config):
    cal = CalibrationConfig.from_cfg(composed_config)
    eth = EthUcyConfig.from_cfg(composed_config)
    ours = online_candidates(cal, LEVELS)
    assert ours == online_candidates(eth, LEVELS)          # conf interpolates one grid
    n_window = len(cal.online_gammas) * len(cal.online_windows) * len(cal.online_rescales)
    assert len(ours) == n_window + len(cal.online_etas) * len(cal.online_kappas)
    assert all(isinstance(c, AdaptiveConformal) for c in ours[:n_window])    # windows first:
    assert all(isinstance(c, ScaleTracker) for c in ours[n_window:])        # ties go to them
    # the order the ETH/UCY stage has always had: gamma slowest, then window, then rescale;
    # eta, then kappa (a tie in the choice goes to the first, so the order is part of the result)
    assert ours == (*(AdaptiveConformal(LEVELS, g, w, k) for g in cal.online_gammas
                      for w in cal.online_windows for k in cal.online_rescales),
                    *(ScaleTracker(LEVELS, e, k) for e in cal.online_etas
                      for k in cal.online_kappas))
    with pytest.raises(ConformalError, match="expected an OnlineCandidatesConfig .*found dict"):
        online_candidates({"online_gammas": [0.005]}, LEVELS)


def test_a_recorded_setting_gives_back_the_same_ellipses(composed_config):
    for c in online_candidates(CalibrationConfig.from_cfg(composed_config), LEVELS):
        assert online_from_setting(c.setting, LEVELS) == c
    tracker = ScaleTracker(LEVELS, 0.05, 10.0, 7)
    assert online_from_setting(tracker.setting, LEVELS).prior_outcomes == 7


@pytest.mark.parametrize("setting, message", [
    ([0.005], "online.json: kalman: expected a mapping with online_method, found list"),
    ({"online_method": "window"}, "online_method: expected one of .*found 'window'"),
    ({"online_method": "scale_tracker", "online_eta": 0.05},
     "expected the keys .*online_kappa.* of scale_tracker, found"),
    ({"online_method": "aci_window", "online_gamma": 0.005, "online_window": 100,
      "online_rescale_after": 3, "online_eta": 0.1}, "expected the keys .*found"),
    ({"online_method": "scale_tracker", "online_eta": 2.0, "online_kappa": 10.0,
      "online_prior_outcomes": 50}, "online.json: kalman: eta: expected a number in"),
    ({"online_method": "aci_window", "online_gamma": "0.1", "online_window": 100,
      "online_rescale_after": 3}, "online.json: kalman: online_gamma: expected a number, found '0.1'"),
])
def test_a_malformed_setting_is_named(setting, message):
    with pytest.raises(ConformalError, match=message):
        online_from_setting(setting, LEVELS, where="online.json: kalman")
