"""calibration: every scene predictor's predictive distribution, calibrated on validation paths.

LSTM, the direct multi-step LSTM (lstm_direct), constant velocity and Kalman each get a per-step
scale fitted on (history, future) pairs of the validation paths (blindspot.traj.calibration);
coverage of the 50/90/95 % ellipses and NLL on the held-out paths ("sim_paths"), beside the
online ellipses' (online_coverage_*, calibration.online_method). A declared dep ending in
calibration_ethucy.json (the ETH/UCY folds) is merged in. models.json: the fits for the walks
stage; val_scores.npz: the validation scores, the online ellipses' prior."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import numpy as np
import pandas as pd

from blindspot.cli import main_stage
from blindspot.io import atomic_open, write_json
from blindspot.radar.config import RadarConfig
from blindspot.stage import StageResult
from blindspot.traj.baselines import prediction_methods
from blindspot.traj.calibration import (LEVELS, calibrate_on_paths, coverage_line,
                                        held_out_pairs, merge_ethucy_folds, to_record)
from blindspot.traj.config import CalibrationConfig, DatasetConfig, EvalConfig
from blindspot.traj.direct import NAME as DIRECT, path_splits
from blindspot.traj.lstm import LSTMPredictor
from blindspot.traj.online import online_ellipses
from blindspot.traj.paths import table_to_arrays
from blindspot.traj.seq2seq import Seq2SeqEnsemble
from blindspot.traj.windows import WindowSet
from blindspot.typed_config import jobs


def run(cfg, ctx):
    import torch
    torch.set_num_threads(1)      # a 64-unit LSTM on a few hundred windows: one thread is fastest
    c, ev = CalibrationConfig.from_cfg(cfg), EvalConfig.from_cfg(cfg)
    truth, measured, _ = table_to_arrays(pd.read_parquet(ctx.dep("paths.parquet")))
    ids = path_splits(len(truth), *(WindowSet.load(ctx.dep(f"{split}.parquet"))  # test: the rest
                                    for split in ("train", "val")))
    pairs = held_out_pairs(measured, truth, ids, DatasetConfig.from_cfg(cfg).window,
                           c.horizon_frames, c.stride)
    lstm = LSTMPredictor.load(ctx.dep("train/model.pt")).with_workers(jobs(cfg))
    predictors = {**prediction_methods(ev, RadarConfig.from_cfg(cfg).frame_period_s, lstm),
                  DIRECT: Seq2SeqEnsemble.load(ctx.dep("train_direct/model.pt"))}
    calibrated, prior, metrics = calibrate_on_paths(
        predictors, pairs, online_ellipses(c, LEVELS), scale_method=c.scale_method,
        scale_level=c.scale_level, cv_fit_points=ev.cv_fit_points, n_test_paths=len(ids["test"]))
    write_json(ctx.out("calibration.json"), merge_ethucy_folds(metrics, ctx.files.deps))
    write_json(ctx.out("models.json"), {n: to_record(p) for n, p in calibrated.items()})
    with atomic_open(ctx.out("val_scores.npz"), "wb") as fh:
        np.savez(fh, **prior)
    print(*filter(None, (coverage_line(n, m) for n, m in metrics.items())), sep="\n")
    return StageResult(metrics=_numbers(metrics))     # MLflow: the method names stay in the file


def _numbers(m: dict) -> dict:    # m without its string leaves (online_method): what MLflow logs
    return {k: _numbers(v) if isinstance(v, dict) else v for k, v in m.items()
            if not isinstance(v, str)}


if __name__ == "__main__":
    main_stage(run, "calibration")
