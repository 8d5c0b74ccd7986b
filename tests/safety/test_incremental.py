"""incremental_kalman: the Kalman predictor from each track's filtered state, one filter pass
per track, equals re-filtering every row's history from the track's first point (what
risk_table did per frame, less the right-aligned window's leading NaN frames, through which the
old call coasted the prior and so widened it by the process noise of every empty frame)."""

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from blindspot.safety.predict import incremental_kalman, track_histories
from blindspot.traj.baselines import KalmanCV
from blindspot.traj.calibration import ScaledPredictor
from blindspot.traj.distribution import DistributionError


def _with_filter_spy(pred, spy, call):
    """Run ``call`` with ``pred.base.filter`` replaced by ``spy`` (restored after)."""
    base = pred.base
    cls = type(base)
    real = cls.filter
    cls.filter = lambda self, obs: spy(obs)
    try:
        return call()
    finally:
        cls.filter = real


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2**31 - 1), st.booleans())
def test_equals_refiltering_each_rows_history(seed, measured):
    rng = np.random.default_rng(seed)
    rows = []
    for g in range(2):
        for tid in range(3):
            f0, n = rng.integers(0, 10), rng.integers(1, 20)
            xy = rng.normal(size=2) + np.cumsum(rng.normal(0, 0.2, (n, 2)), axis=0)
            rows.append(pd.DataFrame({"group": f"s{g}", "track_id": tid,
                                      "frame": np.arange(f0, f0 + n), "x_m": xy[:, 0],
                                      "y_m": xy[:, 1]}))
    tr = pd.concat(rows, ignore_index=True).sort_values(["group", "track_id", "frame"])
    tr = tr.reset_index(drop=True)
    keep = rng.random(len(tr)) < 0.6
    keep[(tr.group == "s0").to_numpy() & (tr.track_id == 0).to_numpy()] = False  # never kept
    pred = ScaledPredictor(KalmanCV(dt=0.1, process_psd=0.7, meas_std=0.1),
                           np.linspace(1.0, 2.0, 8), (("measured", measured),), "kalman")
    hist = track_histories(tr, 30)[keep]
    filtered = []
    real_filter = pred.base.filter

    def spy(obs):
        filtered.append(obs.shape[0])
        return real_filter(obs)

    got = _with_filter_spy(pred, spy, lambda: incremental_kalman(pred, tr, keep, 8))
    kept_tracks = tr[keep].groupby(["group", "track_id"]).ngroups
    assert filtered == [kept_tracks]               # tracks never kept are not filtered
    for b, h in enumerate(hist):                  # the reference: each row on its own
        want = pred.predict_distribution(h[np.isfinite(h).all(-1)][None], 8)
        np.testing.assert_allclose(got.mean[b], want.mean[0], atol=1e-9)
        np.testing.assert_allclose(got.cov[b], want.cov[0], atol=1e-9)


def test_horizon_beyond_the_calibration_is_a_distribution_error():
    tr = pd.DataFrame({"group": "s0", "track_id": 0, "frame": np.arange(5),
                       "x_m": np.arange(5) * 0.1, "y_m": 0.0})
    pred = ScaledPredictor(KalmanCV(dt=0.1, process_psd=0.7, meas_std=0.1), np.ones(4), (),
                           "kalman")
    with pytest.raises(DistributionError, match="calibrated for 4 steps, asked for 8"):
        incremental_kalman(pred, tr, np.ones(5, bool), 8)
