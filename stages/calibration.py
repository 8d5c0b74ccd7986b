"""calibration: every scene predictor's predictive distribution, calibrated on validation paths.

LSTM (an error model of its own validation errors in the walker's heading frame), the direct
multi-step LSTM (lstm_direct, the train_direct stage's: its own Gaussian head), constant
velocity (its fitted noise model) and Kalman (its own covariance) each get a per-step scale
fitted on (history, future) pairs of the windows split's validation paths
(blindspot.traj.calibration); coverage of the 50/90/95 % ellipses and NLL are scored on the test
paths ("sim_paths"), beside the coverage of the adaptive conformal ellipses (online_coverage_*,
each held-out path a stream: blindspot.traj.conformal). A declared dep ending in calibration_ethucy.json (the ETH/UCY folds, same
shape) is merged in. The fitted numbers go to data/calibration/models.json for the benchmark, each
predictor's scores on the validation pairs to data/calibration/val_scores.npz (where the
benchmark's adaptive conformal ellipses start).
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import json
from pathlib import Path

import numpy as np
import pandas as pd

from blindspot.radar.config import RadarConfig
from blindspot.traj.baselines import prediction_methods
from blindspot.traj.config import CalibrationConfig, DatasetConfig, EvalConfig
from blindspot.typed_config import jobs
from blindspot.cli import main_stage
from blindspot.io import atomic_open, write_json
from blindspot.stage import StageResult
from blindspot.traj.calibration import (ETHUCY_FILE, ETHUCY_NAMES, LEVELS, calibrate,
                                        calibration_scores, online_scores, path_pairs,
                                        forecast_scores, to_record)
from blindspot.traj.conformal import AdaptiveConformal
from blindspot.traj.direct import NAME as DIRECT, path_splits
from blindspot.traj.lstm import LSTMPredictor
from blindspot.traj.paths import table_to_arrays
from blindspot.traj.seq2seq import Seq2SeqEnsemble
from blindspot.traj.windows import WindowSet


def run(cfg, ctx):
    import torch

    torch.set_num_threads(1)      # a 64-unit LSTM on a few hundred windows: one thread is fastest
    c = CalibrationConfig.from_cfg(cfg)
    window = DatasetConfig.from_cfg(cfg).window
    truth, measured, _ = table_to_arrays(pd.read_parquet(ctx.dep("paths.parquet")))
    # held out ("test"): every path neither trained nor validated on
    ids = path_splits(len(truth), *(WindowSet.load(ctx.dep(f"{split}.parquet"))
                                    for split in ("train", "val")))
    pairs = {split: path_pairs(measured[ids[split]], truth[ids[split]], window, c.horizon_frames,
                               c.stride, with_index=split == "test") for split in ("val", "test")}
    lstm = LSTMPredictor.load(ctx.dep("train/model.pt")).with_workers(jobs(cfg))
    predictors = {**prediction_methods(EvalConfig.from_cfg(cfg), RadarConfig.from_cfg(cfg).frame_period_s, lstm),
                  DIRECT: Seq2SeqEnsemble.load(ctx.dep("train_direct/model.pt"))}
    calibrated = calibrate(predictors, *pairs["val"],
                           scale_method=c.scale_method, scale_level=c.scale_level,
                           cv_fit_points=EvalConfig.from_cfg(cfg).cv_fit_points)
    online = AdaptiveConformal(LEVELS, c.online_gamma, c.online_window,
                               c.online_rescale_after)
    # each calibrated predictor's scores on the validation pairs: where the adaptive conformal
    # ellipses start, here and in the benchmark (val_scores.npz)
    prior = {n: forecast_scores(p, *pairs["val"]) for n, p in calibrated.items()}
    metrics = {name: {"sim_paths": {**calibration_scores(p, *pairs["test"][:2]),
                                    **online_scores(p, online, prior[name], pairs["test"]),
                                    "n_paths": int(len(ids["test"]))}}
               for name, p in calibrated.items()}
    for path in ctx.files.deps:                 # the ETH/UCY folds, where the stage declares them
        if path.endswith(ETHUCY_FILE):
            for name, folds in json.loads(Path(path).read_text()).items():
                metrics.setdefault(ETHUCY_NAMES.get(name, name), {}).update(folds)
    write_json(ctx.out("calibration.json"), metrics)
    write_json(ctx.out("models.json"), {n: to_record(p) for n, p in calibrated.items()})
    with atomic_open(ctx.out("val_scores.npz"), "wb") as fh:
        np.savez(fh, **prior)
    for name, m in metrics.items():
        s = m.get("sim_paths")
        if s:
            print(f"calibration {name}: coverage 50/90/95 {s['coverage_50']:.3f} / "
                  f"{s['coverage_90']:.3f} / {s['coverage_95']:.3f}, NLL {s['nll']:.3f} "
                  f"({s['n_points']} points of {s['n_paths']} held-out paths); online "
                  f"{s['online_coverage_50']:.3f} / {s['online_coverage_90']:.3f} / "
                  f"{s['online_coverage_95']:.3f}")
    return StageResult(metrics=metrics)


if __name__ == "__main__":
    main_stage(run, "calibration")
