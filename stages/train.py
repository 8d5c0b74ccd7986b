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
from blindspot.radar.config import RadarConfig
from blindspot.traj.baselines import kalman_baseline
from blindspot.traj.config import EvalConfig, LSTMConfig, TrainConfig
from blindspot.cli import main_stage
from blindspot.io import write_json, write_text
from blindspot.report.paper_values import VAL_RMSE
from blindspot.stage import StageResult
from blindspot.traj.baselines import ConstantVelocity
from blindspot.traj.train import (
    evaluate, rmse_euclidean, rmse_per_coordinate, rollout_errors, torch_threads, train_ensemble,
)
from blindspot.traj.windows import WindowSet


def baseline_errors(predictor, ws: WindowSet, horizon: int) -> dict:
    pred = predictor.predict(ws.x, 1)[:, 0]
    return {"rmse_m": rmse_per_coordinate(pred, ws.y), "rmse_euclid_m": rmse_euclidean(pred, ws.y),
            **rollout_errors(predictor, ws, horizon)}


def scores(result, split: dict, baselines: dict, horizon: int, workers: int = 1) -> dict:
    """train.json's errors: the ensemble's and each member's one-step errors, every
    predictor's ``horizon``-frame rollout ADE/FDE, on the val and test windows (the ensemble's
    rollouts on ``workers`` threads; the same bits for any number)."""
    lstm = result.predictor.with_workers(workers)
    return {
        "lstm": {**{s: {**evaluate(lstm, split[s]),
                        **rollout_errors(lstm, split[s], horizon)}
                    for s in ("val", "test")},
                 "n_members": len(result.members),
                 "members": [{"seed": seed,
                              "val": evaluate(m.predictor, split["val"]),
                              "test": evaluate(m.predictor, split["test"])}
                             for seed, m in zip(result.seeds, result.members)]},
        **{name: {s: baseline_errors(p, split[s], horizon) for s in ("val", "test")}
           for name, p in baselines.items()},
        "val_horizon_frames": horizon,
        "n_windows": {s: len(w) for s, w in split.items()},
        "paper": {"val_rmse": VAL_RMSE.value},
    }


def run(cfg, ctx):
    split = {s: WindowSet.load(ctx.dep(f"{s}.parquet")) for s in ("train", "val", "test")}
    model_cfg = LSTMConfig.from_cfg(cfg)
    train_cfg = TrainConfig.from_cfg(cfg)
    result = train_ensemble(
        split["train"], split["val"], model_cfg, train_cfg,
        on_epoch=lambda epoch, m: ctx.log_step(m, epoch),
        checkpoint_dir=ctx.out("checkpoints"),
        resume=train_cfg.resume,
        progress=bool(cfg.progress),
    )
    if len(result.members) > 1 and train_cfg.jobs > 1:
        # members trained in worker processes could not log live: their epochs go to MLflow now
        for i, member in enumerate(result.members):
            for row in member.history.to_dict("records"):
                ctx.log_step({f"member{i}.{k}": v for k, v in row.items() if k != "epoch"},
                             int(row["epoch"]))
    model_path = result.predictor.save(ctx.out("model.pt"))
    # no wall times in the files (MLflow has them): a rerun reproduces their bytes
    history_path = write_text(ctx.out("history.csv"),
                              result.history.drop(columns="seconds").to_csv(index=False))
    baselines = {"constant_velocity": ConstantVelocity(), "kalman": kalman_baseline(EvalConfig.from_cfg(cfg), RadarConfig.from_cfg(cfg).frame_period_s)}
    horizon = train_cfg.val_horizon_frames
    with torch_threads(train_cfg.num_threads):   # the scoring as single-threaded as the training
        metrics = scores(result, split, baselines, horizon, workers=train_cfg.jobs)
    write_json(ctx.out("train.json"), metrics)
    val = {name: metrics[name]["val"] for name in ("lstm", *baselines)}
    print(f"train: val RMSE {val['lstm']['rmse_m']:.4f} m (paper {VAL_RMSE.value}), "
          f"test {metrics['lstm']['test']['rmse_m']:.4f} m; constant velocity val "
          f"{val['constant_velocity']['rmse_m']:.4f} m, Kalman {val['kalman']['rmse_m']:.4f} m; "
          f"val ADE/FDE over {horizon} frames: "
          + ", ".join(f"{k} {v['ade_m']:.3f}/{v['fde_m']:.3f} m" for k, v in val.items()))
    logged = {k: v for k, v in metrics.items() if k != "paper"}
    logged["lstm"] = {**{k: v for k, v in metrics["lstm"].items() if k != "members"},
                      **{f"seed{m['seed']}": {"val": m["val"], "test": m["test"]}
                         for m in metrics["lstm"]["members"]},
                      "seconds_per_epoch": float(result.history.seconds.mean())}
    return StageResult(metrics=logged,
                       artifacts=[history_path], model_files=[model_path])


if __name__ == "__main__":
    main_stage(run, "train")
