"""train_direct: the scenes' direct multi-step predictor (lstm_direct, blindspot.traj.direct) on
the radar path data set: ``direct.model.ensemble`` networks, pre-trained on ETH/UCY walks with
radar-like history errors (``direct.pretrain_epochs`` > 0; the recordings under
``paths.shared_dir``/``direct.pretrain_data``), trained on the training paths' pairs (measured
history, true future), each member's epoch chosen on the validation paths.

train_direct.json: ADE / FDE over 1, 2 and 3 s (and the model's whole horizon) on the validation
and held-out paths, beside the paper's next-point LSTM ensemble (data/train/model.pt, rolled out)
and constant velocity on the same pairs (one every calibration.stride points); each member's
chosen epoch. Training times go to MLflow and the log, not to the file (same bytes each run).
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import pandas as pd

from blindspot.cli import main_stage
from blindspot.config import shared_dir
from blindspot.io import write_json
from blindspot.stage import StageResult
from blindspot.traj.baselines import ConstantVelocity
from blindspot.traj.config import CalibrationConfig, DatasetConfig, DirectConfig, EvalConfig
from blindspot.traj.direct import (NAME, check_fits, direct_line, direct_metrics, direct_scores,
                                   logged_direct, path_splits, pretraining_walks, score_steps,
                                   train_direct)
from blindspot.traj.lstm import LSTMPredictor
from blindspot.traj.paths import table_to_arrays
from blindspot.traj.train import torch_threads
from blindspot.traj.windows import WindowSet


def run(cfg, ctx):
    d, data, cal = (DirectConfig.from_cfg(cfg), DatasetConfig.from_cfg(cfg),
                    CalibrationConfig.from_cfg(cfg))
    check_fits(d, data.window, cal.horizon_frames)
    dt = data.frame_period_s
    truth, measured, _ = table_to_arrays(pd.read_parquet(ctx.dep("paths.parquet")))
    ids = path_splits(len(truth), *(WindowSet.load(ctx.dep(f"{s}.parquet"))
                                    for s in ("train", "val")))
    walks = (pretraining_walks(shared_dir(cfg) / d.pretrain_data, measured[ids["train"]],
                               truth[ids["train"]], d, dt) if d.pretrain_epochs > 0 else None)
    model, reports, pre_reports = train_direct(measured, truth, ids, d, pretrain=walks)
    model_path = model.save(ctx.out("model.pt"))
    steps = score_steps(dt, d.model.horizon)
    predictors = {NAME: model, "lstm": LSTMPredictor.load(ctx.dep("train/model.pt")),
                  "constant_velocity": ConstantVelocity(k=EvalConfig.from_cfg(cfg).cv_fit_points,
                                                        name="constant_velocity")}
    with torch_threads(1):
        # scored on the calibration stage's pairs (one every calibration.stride points), so the
        # scoring set does not change with the training pairs' stride
        scores = {s: direct_scores(predictors, measured[ids[s]], truth[ids[s]],
                                   d.model.obs_len, steps, cal.stride) for s in ("val", "test")}
    metrics = direct_metrics(scores, predictors, steps, dt, ids, d, reports, pre_reports, walks)
    write_json(ctx.out("train_direct.json"), metrics)
    print(direct_line(metrics, predictors, steps, dt, d, reports, pre_reports, walks))
    return StageResult(metrics=logged_direct(metrics, predictors, reports),
                       model_files=[model_path])


if __name__ == "__main__":
    main_stage(run, "train_direct")
