"""predict: the future path of each car scene from the track seen so far (paper Fig. 9).

From eval.prediction_start_s on, every method in eval.prediction_methods (the LSTM rolled out
autoregressively, constant velocity, Kalman) predicts the rest of the scene (or
eval.horizon_frames) from the points seen before the start, their gaps filled by
eval.prediction_input (the paper: its own forward LSTM interpolation) without look-ahead.
Each method's predictive distribution, calibrated on validation paths by the calibration stage
(data/calibration/models.json), gives the covariance of every predicted point (cov_*_m2 columns).
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import json
from functools import partial

import pandas as pd

from blindspot.cli import main_stage
from blindspot.io import write_parquet
from blindspot.radar.config import RadarConfig
from blindspot.radar.scene import load_scenes
from blindspot.stage import StageResult
from blindspot.traj.baselines import kalman_baseline, prediction_methods
from blindspot.traj.config import EvalConfig
from blindspot.traj.interpolation import interpolate
from blindspot.traj.lstm import LSTMPredictor
from blindspot.traj.scene_prediction import once_per_history, predict_scenes
from blindspot.typed_config import jobs


def run(cfg, ctx):
    points = pd.read_parquet(ctx.dep("points.parquet"))
    lstm = LSTMPredictor.load(ctx.dep("model.pt")).with_workers(jobs(cfg))
    ev, frame_period_s = EvalConfig.from_cfg(cfg), RadarConfig.from_cfg(cfg).frame_period_s
    fill = once_per_history(partial(interpolate, method=str(cfg.eval.prediction_input),
                                    predictor=lstm,
                                    smoother=kalman_baseline(ev, frame_period_s).smooth))
    records = json.loads(ctx.dep("models.json").read_text())   # the calibration stage's fits
    predictions = predict_scenes(points, load_scenes(cfg.scene),
                                 prediction_methods(ev, frame_period_s, lstm), records, fill,
                                 start_s=cfg.eval.prediction_start_s,
                                 horizon_frames=cfg.eval.horizon_frames,
                                 dt=float(cfg.radar.frame_period_s))
    write_parquet(ctx.out("predictions.parquet"), predictions)
    print(f"predict: {predictions.scene.nunique()} scenes x {predictions.method.nunique()} methods, "
          f"{predictions.step.max()} steps each")
    return StageResult(metrics={"n_predicted_points": len(predictions)})


if __name__ == "__main__":
    main_stage(run, "predict")
