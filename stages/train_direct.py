"""train_direct: the scenes' direct multi-step predictor (lstm_direct, blindspot.traj.direct) on
the radar path data set: ``direct.model.ensemble`` networks, pre-trained on ETH/UCY walks with
radar-like history errors (``direct.pretrain_epochs`` > 0; the recordings under
``paths.shared_dir``/``direct.pretrain_data``), trained on the training paths' pairs (measured
history, true future), each member's epoch chosen on the validation paths.

train_direct.json: ADE / FDE over 1, 2 and 3 s (and the model's whole horizon) on the validation
and held-out paths, beside the paper's next-point LSTM ensemble (data/train/model.pt, rolled out)
and constant velocity on the same pairs (one every calibration.stride points); each member's
chosen epoch. Training times go to MLflow and the log, not to the file, whose bytes a rerun
reproduces.
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import pandas as pd

from blindspot.traj.config import CalibrationConfig, DatasetConfig, DirectConfig, EvalConfig
from blindspot.cli import main_stage
from blindspot.config import shared_dir
from blindspot.io import write_json
from blindspot.stage import StageResult
from blindspot.traj.baselines import ConstantVelocity
from blindspot.traj.direct import (NAME, check_fits, direct_scores, path_splits,
                                   pretraining_walks, train_direct)
from blindspot.traj.lstm import LSTMPredictor
from blindspot.traj.paths import table_to_arrays
from blindspot.traj.train import torch_threads
from blindspot.traj.windows import WindowSet

STEPS_S = (1.0, 2.0, 3.0)


def run(cfg, ctx):
    d = DirectConfig.from_cfg(cfg)
    check_fits(d, DatasetConfig.from_cfg(cfg).window, CalibrationConfig.from_cfg(cfg).horizon_frames)
    dt = DatasetConfig.from_cfg(cfg).frame_period_s
    truth, measured, _ = table_to_arrays(pd.read_parquet(ctx.dep("paths.parquet")))
    ids = path_splits(len(truth), *(WindowSet.load(ctx.dep(f"{s}.parquet"))
                                    for s in ("train", "val")))
    walks = (pretraining_walks(shared_dir(cfg) / d.pretrain_data, measured[ids["train"]],
                               truth[ids["train"]], d, dt) if d.pretrain_epochs > 0 else None)
    model, reports, pre_reports = train_direct(measured, truth, ids, d, pretrain=walks)
    model_path = model.save(ctx.out("model.pt"))
    steps = tuple(sorted({min(int(round(s / dt)), d.model.horizon) for s in STEPS_S}
                         | {d.model.horizon}))
    predictors = {NAME: model,
                  "lstm": LSTMPredictor.load(ctx.dep("train/model.pt")),
                  "constant_velocity": ConstantVelocity(k=EvalConfig.from_cfg(cfg).cv_fit_points,
                                                        name="constant_velocity")}
    with torch_threads(1):
        # scored on the calibration stage's pairs (one every calibration.stride points), so the
        # scoring set does not change with the training pairs' stride
        stride = CalibrationConfig.from_cfg(cfg).stride
        scores = {s: direct_scores(predictors, measured[ids[s]], truth[ids[s]],
                                   d.model.obs_len, steps, stride) for s in ("val", "test")}
    metrics = {**{name: {s: scores[s][name] for s in scores} for name in predictors},
               "steps_frames": list(steps), "frame_period_s": dt,
               "n_paths": {s: int(len(v)) for s, v in ids.items()},
               "members": [{"seed": d.model.seed + k, "best_epoch": r.best_epoch,
                            "val_ade_m": r.best_val_ade} for k, r in enumerate(reports)],   # no wall times: same bytes each run
               "pretrain": {"epochs": d.pretrain_epochs,
                            "n_walks": 0 if walks is None else int(len(walks)),
                            "best_epochs": [r.best_epoch for r in pre_reports],
                            "val_ade_m": [r.best_val_ade for r in pre_reports]}}
    write_json(ctx.out("train_direct.json"), metrics)
    k = steps[min(2, len(steps) - 1)]
    pre = (f"pre-trained {d.pretrain_epochs} epochs on {len(walks)} ETH/UCY walks (best epochs "
           f"{[r.best_epoch for r in pre_reports]}, {max(r.seconds for r in pre_reports):.0f} s "
           "each at most), " if pre_reports else "")
    print(f"train_direct: {len(reports)} members, {pre}best epochs "
          f"{[r.best_epoch for r in reports]}, {max(r.seconds for r in reports):.0f} s each at "
          f"most; held-out ADE/FDE over {k * dt:.1f} s: "
          + ", ".join(f"{n} {v['test'][f'ade_{k}']:.3f}/{v['test'][f'fde_{k}']:.3f} m"
                      for n, v in metrics.items() if n in predictors))
    logged = {n: metrics[n] for n in predictors}
    logged["members"] = {f"seed{m['seed']}": {**{kk: v for kk, v in m.items() if kk != "seed"},
                                              "seconds": r.seconds}
                         for m, r in zip(metrics["members"], reports)}
    return StageResult(metrics=logged, model_files=[model_path])


if __name__ == "__main__":
    main_stage(run, "train_direct")
