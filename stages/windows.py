"""windows: windows of 50 measured points -> the next point, split 20,000 / 4,000 / 500 with no
path in two splits (the paper's 24,500 pairs; path count and stride in conf/dataset)."""

import pandas as pd

from blindspot.cli import main_stage
from blindspot.stage import StageResult
from blindspot.synth.path_dataset import table_to_arrays
from blindspot.traj.windows import WindowSet, interpolate_gaps, make_windows, split_by_path

SPLITS = ("train", "val", "test")


def run(cfg, ctx):
    d = cfg.dataset
    if int(cfg.model.window) != int(d.window):
        raise ValueError(f"config key 'model.window' = {cfg.model.window}: expected dataset.window = {d.window}")
    table = pd.read_parquet(ctx.dep("paths.parquet"))
    truth, measured, _ = table_to_arrays(table)
    if d.fill_gaps == "linear":
        measured = interpolate_gaps(measured)
    elif d.fill_gaps != "none":
        raise ValueError(f"config key 'dataset.fill_gaps' = {d.fill_gaps!r}: expected 'linear' or 'none'")
    ws = make_windows(measured, int(d.window), int(d.stride))
    if d.target == "truth":  # the true next position (known in simulation) instead of the measured one
        ws = WindowSet(ws.x, truth[ws.path_id, ws.start + int(d.window)], ws.path_id, ws.start)
    elif d.target != "measured":
        raise ValueError(f"config key 'dataset.target' = {d.target!r}: expected 'measured' or 'truth'")
    counts = [int(d.split[s]) for s in SPLITS]
    parts = split_by_path(ws, counts, seed=int(d.seed))
    for name, part in zip(SPLITS, parts):
        part.save(ctx.out(f"{name}.parquet"))
    stats = {"windows_available": len(ws), **{f"n_{n}": len(p) for n, p in zip(SPLITS, parts)}}
    print("windows: " + ", ".join(f"{k} {v}" for k, v in stats.items()))
    return StageResult(metrics=stats)


if __name__ == "__main__":
    main_stage(run, "windows")
