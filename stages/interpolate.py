"""interpolate: fill the frames where the pedestrian was hidden behind the car (paper Fig. 8).

For each scene with the car, the track of radar points is filled by every method in
eval.interpolation_methods (the paper's forward LSTM rollout, the Kalman smoother, our two-sided
LSTM blend); the filled points are scored against the simulated truth on the hidden frames.
"""

import numpy as np
import pandas as pd

from blindspot import experiment, tracking
from blindspot.cli import main_stage
from blindspot.io import write_json, write_parquet
from blindspot.traj.interpolation import find_gaps, interpolate
from blindspot.traj.lstm import LSTMPredictor


def run(cfg):
    points = pd.read_parquet(experiment.data_path(cfg, "localise", "points.parquet"))
    truth = pd.read_parquet(experiment.data_path(cfg, "simulate", "truth.parquet"))
    lstm = LSTMPredictor.load(experiment.data_path(cfg, "train", "model.pt"))
    kalman = experiment.kalman(cfg)
    scenes = {n: s for n, s in experiment.scenes(cfg).items() if s.with_car}
    rows, metrics = [], {}
    for name, sc in scenes.items():
        track = experiment.scene_track(points, name, sc.n_frames)
        tr = truth[truth.scene == name].sort_values("frame")
        xy_true = tr[["x_m", "y_m"]].to_numpy()
        observed = ~np.isnan(track).any(axis=1)
        gap = np.zeros(len(track), bool)
        for a, b in find_gaps(observed):
            gap[a:b] = True
        hidden_gap = gap & tr.occluded.to_numpy()
        for method in cfg.eval.interpolation_methods:
            filled = interpolate(track, method, predictor=lstm, smoother=kalman.smooth)
            err = np.hypot(*(filled - xy_true).T)
            metrics.setdefault(method, {})[name] = {
                "hidden_mean_m": float(err[hidden_gap].mean()),
                "hidden_median_m": float(np.median(err[hidden_gap])),
                "hidden_max_m": float(err[hidden_gap].max()),
                "all_gaps_mean_m": float(err[gap].mean()),
                "n_hidden_filled": int(hidden_gap.sum()),
                "n_filled": int(gap.sum()),
            }
            rows.append(pd.DataFrame({
                "scene": name, "method": method, "frame": tr.frame.to_numpy(),
                "time_s": tr.time_s.to_numpy(), "x_m": filled[:, 0], "y_m": filled[:, 1],
                "observed": observed, "filled": gap, "hidden": tr.occluded.to_numpy(),
            }))
    for method, per in metrics.items():
        per["all_scenes"] = {"hidden_mean_m": float(np.mean([m["hidden_mean_m"] for m in per.values()]))}
    write_parquet(experiment.data_path(cfg, "interpolate", "tracks.parquet"), pd.concat(rows, ignore_index=True))
    write_json(experiment.reports_path(cfg, "metrics", "interpolate.json"), metrics)
    tracking.current().log_metrics(metrics)
    for method, per in metrics.items():
        print(f"interpolate {method}: mean error on hidden frames "
              + ", ".join(f"{s} {m['hidden_mean_m']:.3f} m" for s, m in per.items()))


if __name__ == "__main__":
    main_stage(run, "interpolate")
