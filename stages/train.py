"""train: the many-to-one LSTM of the paper's Table 1 on the radar-measured windows.

Beside the one-step RMSE, every predictor's ADE/FDE of a ``train.val_horizon_frames`` rollout
from the validation (and test) windows (the hyper-parameter search's objective).

``train.ensemble`` networks are trained with seeds ``train.seed + i`` (``train.jobs`` at a time)
and averaged; train.json gives the ensemble's errors and each member's, so the spread a single
training run would carry is on record.

Per-epoch metrics go to MLflow as they come (``ctx.log_step``, the training's ``on_epoch``);
the model, the history and the final metrics are returned for the runner to log; checkpoints
every epoch under data/train/checkpoints (resume with train.resume=true). Validation and test
RMSE are reported beside the constant-velocity and Kalman one-step errors on the same windows.
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
from blindspot.cli import main_stage
from blindspot.io import write_json, write_text
from blindspot.radar.config import RadarConfig
from blindspot.report.paper_values import VAL_RMSE
from blindspot.stage import StageResult
from blindspot.traj.baselines import ConstantVelocity, kalman_baseline
from blindspot.traj.config import EvalConfig, LSTMConfig, TrainConfig
from blindspot.traj.train import (ensemble_scores, logged_scores, member_steps, scores_line,
                                  torch_threads, train_ensemble)
from blindspot.traj.windows import WindowSet


def run(cfg, ctx):
    split = {s: WindowSet.load(ctx.dep(f"{s}.parquet")) for s in ("train", "val", "test")}
    train_cfg = TrainConfig.from_cfg(cfg)
    result = train_ensemble(split["train"], split["val"], LSTMConfig.from_cfg(cfg), train_cfg,
                            on_epoch=lambda epoch, m: ctx.log_step(m, epoch),
                            checkpoint_dir=ctx.out("checkpoints"), resume=train_cfg.resume,
                            progress=bool(cfg.progress))
    if len(result.members) > 1 and train_cfg.jobs > 1:
        for metrics, epoch in member_steps(result):   # trained in workers: logged now
            ctx.log_step(metrics, epoch)
    model_path = result.predictor.save(ctx.out("model.pt"))
    # no wall times in the files (MLflow has them): a rerun reproduces their bytes
    history_path = write_text(ctx.out("history.csv"),
                              result.history.drop(columns="seconds").to_csv(index=False))
    kalman = kalman_baseline(EvalConfig.from_cfg(cfg), RadarConfig.from_cfg(cfg).frame_period_s)
    baselines = {"constant_velocity": ConstantVelocity(), "kalman": kalman}
    with torch_threads(train_cfg.num_threads):   # the scoring as single-threaded as the training
        metrics = ensemble_scores(result, split, baselines, train_cfg.val_horizon_frames,
                                  workers=train_cfg.jobs)
    metrics["paper"] = {"val_rmse": VAL_RMSE.value}
    write_json(ctx.out("train.json"), metrics)
    print(scores_line(metrics, baselines, VAL_RMSE.value))
    return StageResult(metrics=logged_scores(metrics, result),
                       artifacts=[history_path], model_files=[model_path])


if __name__ == "__main__":
    main_stage(run, "train")
