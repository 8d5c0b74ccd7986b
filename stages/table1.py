"""table1: the paper's Table 1 (LSTM hyper-parameters, validation RMSE 0.07) with ours beside it,
including the constant-velocity and Kalman baselines' one-step RMSE on the same windows."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import json
from dataclasses import asdict

from blindspot.cli import main_stage
from blindspot.io import write_text
from blindspot.report.paper_values import VAL_RMSE
from blindspot.report.tables import table1_lstm
from blindspot.stage import StageResult
from blindspot.traj.config import LSTMConfig, TrainConfig

BASELINES = {"constant_velocity": "constant velocity", "kalman": "Kalman (CV)"}


def run(cfg, ctx):
    train = json.loads(ctx.dep("train.json").read_text())
    model, training = LSTMConfig.from_cfg(cfg), TrainConfig.from_cfg(cfg)
    counts = {**train["n_windows"], "window": model.window}
    text = table1_lstm(
        asdict(model), asdict(training),
        counts, val_rmse_m=train["lstm"]["val"]["rmse_m"], test_rmse_m=train["lstm"]["test"]["rmse_m"],
        baselines={label: train[key]["val"]["rmse_m"] for key, label in BASELINES.items() if key in train},
        member_val_rmse_m={m["seed"]: m["val"]["rmse_m"] for m in train["lstm"].get("members", [])})
    text += ("\nRMSE here is over both coordinates (root of the mean squared x and y error, metres), what "
             "Keras' RMSE metric reports on (x, y) targets; the Euclidean one-step RMSE of the LSTM "
             f"is {train['lstm']['val']['rmse_euclid_m']:.4f} m (validation).\n")
    out = write_text(ctx.out("table1.md"), text)
    print(f"table1: {out} (val RMSE {train['lstm']['val']['rmse_m']:.4f} m, paper {VAL_RMSE.value})")
    return StageResult(artifacts=[out])


if __name__ == "__main__":
    main_stage(run, "table1")
