"""train: the many-to-one LSTM of the paper's Table 1 on the radar-measured windows.

Logs the flattened config, per-epoch metrics, the model and the history to MLflow; checkpoints
every epoch under data/train/checkpoints (resume with train.resume=true). Validation and test
RMSE are reported beside the constant-velocity and Kalman one-step errors on the same windows.
"""

from omegaconf import OmegaConf

from blindspot import experiment, tracking
from blindspot.cli import main_stage
from blindspot.io import write_json, write_text
from blindspot.report.paper_values import VAL_RMSE
from blindspot.traj.baselines import ConstantVelocity
from blindspot.traj.lstm import LSTMConfig
from blindspot.traj.train import TrainConfig, evaluate, rmse_euclidean, rmse_per_coordinate, train_lstm
from blindspot.traj.windows import WindowSet


def baseline_rmse(predictor, ws: WindowSet) -> dict:
    pred = predictor.predict(ws.x, 1)[:, 0]
    return {"rmse_m": rmse_per_coordinate(pred, ws.y), "rmse_euclid_m": rmse_euclidean(pred, ws.y)}


def run(cfg):
    split = {s: WindowSet.load(experiment.data_path(cfg, "windows", f"{s}.parquet"))
             for s in ("train", "val", "test")}
    model_cfg = LSTMConfig.from_mapping(
        {k: v for k, v in OmegaConf.to_container(cfg.model).items() if k != "name"})
    train_cfg = TrainConfig.from_mapping(OmegaConf.to_container(cfg.train))
    tracker = tracking.current()
    result = train_lstm(
        split["train"], split["val"], model_cfg, train_cfg,
        on_epoch=lambda epoch, m: tracker.log_metrics(m, step=epoch),
        checkpoint_dir=experiment.data_path(cfg, "train", "checkpoints"),
        resume=bool(cfg.train.resume),
        progress=bool(cfg.progress),
    )
    model_path = result.predictor.save(experiment.data_path(cfg, "train", "model.pt"))
    history_path = experiment.data_path(cfg, "train", "history.csv")
    write_text(history_path, result.history.to_csv(index=False))
    baselines = {"constant_velocity": ConstantVelocity(), "kalman": experiment.kalman(cfg)}
    metrics = {
        "lstm": {"val": evaluate(result.predictor, split["val"]),
                 "test": evaluate(result.predictor, split["test"]),
                 "seconds_per_epoch": float(result.history.seconds.mean())},
        **{name: {"val": baseline_rmse(p, split["val"]), "test": baseline_rmse(p, split["test"])}
           for name, p in baselines.items()},
        "n_windows": {s: len(w) for s, w in split.items()},
        "paper": {"val_rmse": VAL_RMSE.value},
    }
    write_json(experiment.reports_path(cfg, "metrics", "train.json"), metrics)
    tracker.log_metrics({k: v for k, v in metrics.items() if k != "paper"})
    tracker.log_model_file(model_path)
    tracker.log_artifact(history_path)
    print(f"train: val RMSE {metrics['lstm']['val']['rmse_m']:.4f} m (paper {VAL_RMSE.value}), "
          f"test {metrics['lstm']['test']['rmse_m']:.4f} m; constant velocity val "
          f"{metrics['constant_velocity']['val']['rmse_m']:.4f} m, Kalman "
          f"{metrics['kalman']['val']['rmse_m']:.4f} m")


if __name__ == "__main__":
    main_stage(run, "train")
