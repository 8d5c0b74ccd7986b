import numpy as np

from blindspot.traj.evaluation import errors_at_horizons, score_prediction


def test_late_but_on_path_prediction_scores_well_only_on_the_paper_metric():
    truth = np.stack([np.arange(20) * 0.1, np.zeros(20)], axis=1)
    late = np.vstack([truth[:1].repeat(5, axis=0), truth[:15]])  # same path, 5 frames late
    s = score_prediction(late, truth, radar_track=truth, dt_s=0.1)
    assert s["path_error_mean_m"] == 0.0 and s["path_error_radar_mean_m"] == 0.0
    assert s["ade_m"] > 0.3 and abs(s["fde_m"] - 0.5) < 1e-12
    assert abs(s["fde_1s"] - 0.5) < 1e-12  # step 10: 0.5 m behind


def test_horizons_beyond_the_prediction_are_nan():
    e = errors_at_horizons(np.arange(1, 6, dtype=float), 0.1, (0.3, 1.0))
    assert e["ade_0.3s"] == 2.0 and e["fde_0.3s"] == 3.0
    assert np.isnan(e["ade_1s"]) and np.isnan(e["fde_1s"])
