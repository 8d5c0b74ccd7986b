"""windows: windows of 50 measured points -> the next point, split 20,000 / 4,000 / 500 with no
path in two splits (the paper's 24,500 pairs; path count and stride in conf/dataset)."""

import blindspot  # noqa: F401  first: pins the CPU kernels before numpy loads (blindspot.kernels)
import numpy as np
import pandas as pd

from blindspot.cli import main_stage
from blindspot.stage import StageResult
from blindspot.traj.config import DatasetConfig
from blindspot.traj.paths import table_to_arrays
from blindspot.traj.windows import WindowSet, interpolate_gaps, last_point_measured, make_windows, \
    split_by_path

SPLITS = ("train", "val", "test")


def run(cfg, ctx):
    d = DatasetConfig.from_cfg(cfg)
    table = pd.read_parquet(ctx.dep("paths.parquet"))
    truth, measured, _ = table_to_arrays(table)
    filled = interpolate_gaps(measured) if d.fill_gaps == "linear" else measured  # or "none"
    cut = make_windows(filled, d.window, d.stride)
    # a window ending in a filled gap was filled toward a point after it (its own target)
    ws = cut.subset(np.flatnonzero(last_point_measured(cut, measured)))
    if d.target == "truth":  # the true next position (known in simulation) instead of the measured one
        ws = WindowSet(ws.x, truth[ws.path_id, ws.start + d.window], ws.path_id, ws.start)
    counts = [getattr(d.split, s) for s in SPLITS]
    parts = split_by_path(ws, counts, seed=d.seed)
    for name, part in zip(SPLITS, parts):
        part.save(ctx.out(f"{name}.parquet"))
    stats = {"windows_available": len(ws), "windows_ending_in_a_gap": len(cut) - len(ws), **{f"n_{n}": len(p) for n, p in zip(SPLITS, parts)}}
    print("windows: " + ", ".join(f"{k} {v}" for k, v in stats.items()))
    return StageResult(metrics=stats)


if __name__ == "__main__":
    main_stage(run, "windows")
