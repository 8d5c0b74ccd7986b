"""fig04: the paper's Fig. 4, LSTM rollouts on test paths (a, b approaching; c, d receding;
e perpendicular).

Cases are chosen deterministically from the test split's path ids by motion (lowest id first); when
the test split holds fewer paths of a motion than the figure needs, validation paths of that motion
follow (also unseen in training), then later windows of the same paths
(blindspot.traj.windows.choose_windows). The LSTM sees the window
exactly as in training (gaps filled) and is rolled out autoregressively for up to HORIZON steps
against the true continuation.
"""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import json

import pandas as pd

from blindspot.cli import main_stage
from blindspot.io import save_figure
from blindspot.report.path_figures import PathCase, fig04_lstm_paths
from blindspot.stage import StageResult
from blindspot.traj.lstm import LSTMPredictor
from blindspot.traj.metrics import ade
from blindspot.traj.windows import WindowSet, choose_windows

LAYOUT = (("approaching", 2), ("receding", 2), ("perpendicular", 1))  # the paper's five panels
HORIZON = 50  # rollout steps (5 s at 0.1 s): long enough to show the error growing


def run(cfg, ctx):
    paths = pd.read_parquet(ctx.dep("paths.parquet"))
    splits = {s: WindowSet.load(ctx.dep(f"{s}.parquet")) for s in ("test", "val")}
    lstm = LSTMPredictor.load(ctx.dep("model.pt"))
    by_path = paths.sort_values(["path_id", "point"]).groupby("path_id")
    motion_of = by_path.motion.first()
    n_points = by_path.size()
    cases = []
    for motion, split, pid, start in choose_windows(splits, motion_of, n_points, LAYOUT, HORIZON):
        p = paths[paths.path_id == pid].sort_values("point")
        ws = splits[split]
        W = ws.window
        H = min(HORIZON, len(p) - start - W)
        x = ws.x[(ws.path_id == pid) & (ws.start == start)][:1]
        pred = lstm.predict(x, H)[0]
        true = p[["x_true_m", "y_true_m"]].to_numpy()
        fut = true[start + W: start + W + H]
        cases.append(PathCase(motion, pid, start, p[["x_m", "y_m"]].to_numpy()[start:start + W],
                              true[start:start + W], pred, fut, ade(pred, fut), split))
    train = json.loads(ctx.dep("train.json").read_text())
    fig = fig04_lstm_paths(cases, dt_s=float(cfg.radar.frame_period_s),
                           val_rmse_m=train["lstm"]["val"]["rmse_m"])
    out = save_figure(fig, ctx.out("fig04.png"), dpi=110)
    print(f"fig04: {out} ("
          + ", ".join(f"{c.motion} {c.split} path {c.path_id}@{c.start} ADE {c.ade_m:.2f} m" for c in cases) + ")")
    return StageResult(metrics={f"fig04_ade_m.{c.motion}_{c.path_id}_{c.start}": c.ade_m for c in cases},
                       artifacts=[out])


if __name__ == "__main__":
    main_stage(run, "fig04")
