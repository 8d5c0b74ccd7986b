"""fig04: the paper's Fig. 4, LSTM rollouts on test paths (a, b approaching; c, d receding;
e perpendicular).

Cases are chosen deterministically from the test split's path ids by motion (lowest id first); when
the test split holds fewer paths of a motion than the figure needs, validation paths of that motion
follow (also unseen in training), then later windows of the same paths. The LSTM sees the window
exactly as in training (gaps filled) and is rolled out autoregressively for up to HORIZON steps
against the true continuation.
"""

import json

import numpy as np
import pandas as pd

from blindspot import experiment, tracking
from blindspot.cli import main_stage
from blindspot.report.path_figures import PathCase, fig04_lstm_paths
from blindspot.traj.lstm import LSTMPredictor
from blindspot.traj.metrics import ade
from blindspot.traj.windows import WindowSet

LAYOUT = (("approaching", 2), ("receding", 2), ("perpendicular", 1))  # the paper's five panels
HORIZON = 50  # rollout steps (5 s at 0.1 s): long enough to show the error growing


def choose_windows(splits: dict[str, WindowSet], motion_of: pd.Series, n_points: pd.Series,
                   horizon: int) -> list[tuple[str, str, int, int]]:
    """(motion, split, path_id, start) per panel of LAYOUT, deterministically.

    Paths of the wanted motion from the test split first (lowest id first), then from the
    validation split if the test split has too few (both are unseen in training); when a motion
    has fewer paths than panels, the next panel takes the latest window of a path already used.
    """
    chosen = []
    for motion, count in LAYOUT:
        candidates = [(name, int(p)) for name, ws in splits.items()
                      for p in np.unique(ws.path_id) if motion_of[p] == motion]
        if not candidates:
            raise ValueError(f"fig04: no {motion} path in the splits {list(splits)} (data/windows/)")
        for k in range(count):
            name, pid = candidates[k % len(candidates)]
            ws = splits[name]
            room = n_points[pid] - ws.window - min(horizon, n_points[pid] - ws.window)
            starts = np.sort(ws.start[(ws.path_id == pid) & (ws.start <= room)])
            if not len(starts):
                raise ValueError(f"fig04: {name} path {pid} has no window leaving room for a rollout")
            use = k // len(candidates)  # 0: earliest window; 1: latest; then stepping back
            chosen.append((motion, name, pid, int(starts[0] if use == 0 else starts[max(0, len(starts) - use)])))
    return chosen


def run(cfg):
    paths = pd.read_parquet(experiment.data_path(cfg, "paths", "paths.parquet"))
    splits = {s: WindowSet.load(experiment.data_path(cfg, "windows", f"{s}.parquet")) for s in ("test", "val")}
    lstm = LSTMPredictor.load(experiment.data_path(cfg, "train", "model.pt"))
    for name, ws in splits.items():
        if ws.start is None:
            raise ValueError(f"fig04: data/windows/{name}.parquet has no window start indices")
    by_path = paths.sort_values(["path_id", "point"]).groupby("path_id")
    motion_of = by_path.motion.first()
    n_points = by_path.size()
    cases = []
    for motion, split, pid, start in choose_windows(splits, motion_of, n_points, HORIZON):
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
    train = json.loads(experiment.reports_path(cfg, "metrics", "train.json").read_text())
    fig = fig04_lstm_paths(cases, dt_s=float(cfg.radar.frame_period_s),
                           val_rmse_m=train["lstm"]["val"]["rmse_m"])
    out = experiment.save_report_figure(cfg, fig, "fig04", dpi=110)
    tracking.current().log_metrics({f"fig04_ade_m.{c.motion}_{c.path_id}_{c.start}": c.ade_m for c in cases})
    print(f"fig04: {out} ("
          + ", ".join(f"{c.motion} {c.split} path {c.path_id}@{c.start} ADE {c.ade_m:.2f} m" for c in cases) + ")")


if __name__ == "__main__":
    main_stage(run, "fig04")
