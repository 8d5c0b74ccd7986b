"""calibration: each scene predictor (lstm, lstm_direct, constant velocity, Kalman) calibrated on
validation paths (blindspot.traj.calibration), scored on the held-out paths ("sim_paths") beside
the online ellipses it chose on validation streams (blindspot.traj.path_calibration); a dep ending
in calibration_ethucy.json is merged in. models.json: the fits; val_scores.npz: the online
ellipses' prior; online.json: each predictor's chosen setting (the walks stage reads all three)."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import numpy as np
import pandas as pd

from blindspot.cli import main_stage
from blindspot.io import atomic_open, write_json
from blindspot.radar.config import RadarConfig
from blindspot.stage import StageResult
from blindspot.traj.baselines import prediction_methods
from blindspot.traj.calibration import LEVELS, to_record
from blindspot.traj.config import CalibrationConfig, DatasetConfig, EvalConfig
from blindspot.traj.direct import NAME as DIRECT, path_splits
from blindspot.traj.lstm import LSTMPredictor
from blindspot.traj.online import online_candidates
from blindspot.traj.path_calibration import (calibrate_on_paths, coverage_line, held_out_pairs,
                                             merge_ethucy_folds)
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
    calibrated, prior, metrics, online = calibrate_on_paths(
        predictors, pairs, online_candidates(c, LEVELS), scale_method=c.scale_method,
        scale_level=c.scale_level, cv_fit_points=ev.cv_fit_points, n_test_paths=len(ids["test"]),
        val_streams=c.online_val_streams)
    write_json(ctx.out("calibration.json"), merge_ethucy_folds(metrics, ctx.files.deps))
    write_json(ctx.out("models.json"), {n: to_record(p) for n, p in calibrated.items()})
    with atomic_open(ctx.out("val_scores.npz"), "wb") as fh:
        np.savez(fh, **prior)
    write_json(ctx.out("online.json"), online)
    print(*filter(None, (coverage_line(n, m) for n, m in metrics.items())), sep="\n")
    return StageResult(metrics=_numbers(metrics))     # MLflow: the method names stay in the file


def _numbers(m: dict) -> dict:    # m without its string leaves (online_method): what MLflow logs
    return {k: _numbers(v) if isinstance(v, dict) else v for k, v in m.items()
            if not isinstance(v, str)}


if __name__ == "__main__":
    main_stage(run, "calibration")
