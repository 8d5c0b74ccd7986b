"""interpolate: fill the frames where the pedestrian was hidden behind the car (paper Fig. 8).

For each scene with the car, the track of radar points is filled by every method in
eval.interpolation_methods (the paper's forward LSTM rollout, the Kalman smoother, our two-sided
LSTM blend); the filled points are scored against the simulated truth on the hidden frames
(blindspot.traj.evaluation.score_interpolation).
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import numpy as np
import pandas as pd

from blindspot.cli import main_stage
from blindspot.io import write_json, write_parquet
from blindspot.radar.config import RadarConfig
from blindspot.radar.scene import load_scenes
from blindspot.stage import StageResult
from blindspot.traj.baselines import kalman_baseline
from blindspot.traj.config import EvalConfig
from blindspot.traj.evaluation import gap_mask, mean_over_scenes, score_interpolation
from blindspot.traj.interpolation import interpolate
from blindspot.traj.interpolation import scene_track
from blindspot.traj.lstm import LSTMPredictor
from blindspot.typed_config import jobs


def run(cfg, ctx):
    points = pd.read_parquet(ctx.dep("points.parquet"))
    truth = pd.read_parquet(ctx.dep("truth.parquet"))
    lstm = LSTMPredictor.load(ctx.dep("model.pt")).with_workers(jobs(cfg))
    kalman = kalman_baseline(EvalConfig.from_cfg(cfg), RadarConfig.from_cfg(cfg).frame_period_s)
    scenes = {n: s for n, s in load_scenes(cfg.scene).items() if s.with_car}
    rows, metrics = [], {}
    for name, sc in scenes.items():
        track = scene_track(points, name, sc.n_frames)
        tr = truth[truth.scene == name].sort_values("frame")
        xy_true = tr[["x_m", "y_m"]].to_numpy()
        observed = ~np.isnan(track).any(axis=1)
        gap = gap_mask(observed)
        for method in cfg.eval.interpolation_methods:
            filled = interpolate(track, method, predictor=lstm, smoother=kalman.smooth)
            metrics.setdefault(method, {})[name] = score_interpolation(
                filled, xy_true, observed, tr.occluded.to_numpy())
            rows.append(pd.DataFrame({
                "scene": name, "method": method, "frame": tr.frame.to_numpy(),
                "time_s": tr.time_s.to_numpy(), "x_m": filled[:, 0], "y_m": filled[:, 1],
                "observed": observed, "filled": gap, "hidden": tr.occluded.to_numpy(),
            }))
    metrics = mean_over_scenes(metrics)
    write_parquet(ctx.out("tracks.parquet"), pd.concat(rows, ignore_index=True))
    write_json(ctx.out("interpolate.json"), metrics)
    for method, per in metrics.items():
        print(f"interpolate {method}: mean error on hidden frames "
              + ", ".join(f"{s} {m['hidden_mean_m']:.3f} m" for s, m in per.items()))
    return StageResult(metrics=metrics)


if __name__ == "__main__":
    main_stage(run, "interpolate")
