"""Speed (and, with --sweep, accuracy) of the next-point LSTM on this CPU.

Data: the paper-sized set built from synthetic paths (blindspot.traj.paths) passed through the
simple test noise model ``radar_like_noise`` (range quantised to 0.5 m bins, 1 deg angle noise,
5 % missed points, interior gaps filled linearly): 165 paths of 200 points, windows of 50 at
stride 1, split 20,000 / 4,000 / 500 by path.

    python benchmarks/bench_train.py [--threads N] [--epochs 2]
        training seconds per epoch (20,000 windows of 50) and inference milliseconds per rollout
        step at batch 1 and batch 512.
    python benchmarks/bench_train.py --sweep [--threads N] [--seeds K] [--angle-std-deg A] [--only NAME ...]
        trains each candidate model for the full 15 epochs (K training seeds each) and prints
        validation RMSE in metres against the noisy targets (what the paper reports) and against
        the clean truth, RMSE on a common held-out test set of 100 fresh paths, and seconds per
        epoch. The candidates and the numbers behind the defaults are in conf/model/lstm.yaml.

Every figure is printed; nothing is asserted. The machine may be shared: read seconds as upper
bounds and compare runs made side by side.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from dataclasses import replace

import numpy as np
import torch

from blindspot.traj.lstm import LSTMConfig, LSTMPredictor
from blindspot.traj.paths import PathSpec, radar_like_noise, random_paths
from blindspot.traj.train import TrainConfig, rmse_per_coordinate, train_lstm
from blindspot.traj.windows import WindowSet, interpolate_gaps, make_windows, paths_needed, split_by_path

COUNTS = (20000, 4000, 500)
WINDOW = 50


def noisy_windows(n_paths: int, stride: int, seed: int, angle_std_deg: float = 1.0) -> tuple[WindowSet, np.ndarray]:
    """Windows of measured (noisy, gap-filled) paths, and the clean (P, T, 2) truth paths."""
    clean = random_paths(n_paths, PathSpec(), seed=seed)
    measured = interpolate_gaps(radar_like_noise(clean, seed=seed + 1, angle_std_deg=angle_std_deg))
    return make_windows(measured, WINDOW, stride), clean


def clean_targets(ws: WindowSet, clean: np.ndarray) -> np.ndarray:
    """(N, 2) truth of each window's target point."""
    return clean[ws.path_id, ws.start + ws.window]


def paper_splits(
    stride: int = 1, seed: int = 0, angle_std_deg: float = 1.0
) -> tuple[tuple[WindowSet, ...], np.ndarray]:
    """20,000 / 4,000 / 500 windows (10 % more paths than the minimum to cover dropped windows)
    and the clean truth paths."""
    n_paths = int(np.ceil(1.1 * paths_needed(COUNTS, 200, WINDOW, stride)))
    ws, clean = noisy_windows(n_paths, stride, seed, angle_std_deg)
    return split_by_path(ws, COUNTS, seed=seed + 2), clean


def reference_rmse(ws: WindowSet, truth: np.ndarray) -> dict[str, float]:
    """Non-learned one-step references: measurement noise itself, and straight-line extrapolation."""
    t = np.arange(10.0)
    a = ws.x[:, -10:].astype(np.float64)  # least-squares line through the last 10 points
    slope = ((t - t.mean())[None, :, None] * (a - a.mean(axis=1, keepdims=True))).sum(1) / ((t - t.mean()) ** 2).sum()
    linfit = a.mean(axis=1) + slope * (10 - t.mean())
    return {
        "noise_floor_m": rmse_per_coordinate(ws.y, truth),
        "linfit10_vs_noisy_m": rmse_per_coordinate(linfit, ws.y),
        "linfit10_vs_clean_m": rmse_per_coordinate(linfit, truth),
    }


def time_rollout_step(pred: LSTMPredictor, batch: int, repeats: int = 50) -> float:
    """Median milliseconds of one rollout step (one network call on (batch, W, 2))."""
    x = torch.randn(batch, pred.window, 2) + 10.0
    for _ in range(5):
        pred.step(x)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        pred.step(x)
        times.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(times)


def speed(args: argparse.Namespace) -> dict[str, float]:
    (train, val, _), _ = paper_splits(angle_std_deg=args.angle_std_deg)
    model_cfg = LSTMConfig(window=WINDOW)
    train_cfg = TrainConfig(epochs=args.epochs, num_threads=args.threads)
    res = train_lstm(train, val, model_cfg, train_cfg, progress=False)
    torch.set_num_threads(args.threads)
    pred = res.predictor
    hist = np.asarray(val.x[:512], dtype=float)
    pred.predict(hist, 12)  # warm-up
    rollout = []
    for _ in range(5):
        t12 = time.perf_counter()
        pred.predict(hist, 12)
        rollout.append(time.perf_counter() - t12)
    out = {
        "threads": args.threads,
        "train_windows": len(train),
        "seconds_per_epoch": float(res.history["seconds"].median()),
        "ms_per_step_batch1": time_rollout_step(pred, 1),
        "ms_per_step_batch512": time_rollout_step(pred, 512),
        "ms_rollout12_batch512": 1e3 * statistics.median(rollout),
        "val_rmse_m_after_epochs": res.val_rmse_m,
    }
    print(f"model {model_cfg}\nthreads {args.threads}, torch {torch.__version__}")
    print(f"training: {out['seconds_per_epoch']:.2f} s/epoch on {len(train)} windows of {WINDOW} "
          f"(median of {args.epochs}; 15 epochs ~ {15 * out['seconds_per_epoch']:.0f} s)")
    print(f"rollout step: {out['ms_per_step_batch1']:.3f} ms at batch 1, "
          f"{out['ms_per_step_batch512']:.2f} ms at batch 512 "
          f"({1e3 * out['ms_per_step_batch512'] / 512:.1f} us per track)")
    print(f"12-step rollout of 512 tracks (predict(), median of 5): {out['ms_rollout12_batch512']:.1f} ms")
    return out


SCALED = LSTMConfig(normalise=True)  # the first sweeps' baseline: translate + fitted RMS scaling
CANDIDATES: dict[str, tuple[LSTMConfig, int, int]] = {
    # name: (model config, stride, batch size). "default" is conf/model/lstm.yaml; the others spell
    # out every setting they were measured with (recorded in that file's comments).
    # (target="absolute" with translate=True is the same model as "displacement": both targets
    # are next - last point then.)
    "default (translate, no scaling)": (LSTMConfig(), 1, 64),
    "scaled (translate + fitted RMS)": (SCALED, 1, 64),
    "scaled h32": (replace(SCALED, hidden_size=32), 1, 64),
    "scaled h128": (replace(SCALED, hidden_size=128), 1, 64),
    "scaled 2 layers h64": (replace(SCALED, num_layers=2), 1, 64),
    "scaled linear head (no ReLU)": (replace(SCALED, head_hidden=0), 1, 64),
    "scaled batch 32": (SCALED, 1, 32),
    "scaled stride 5 (more paths)": (SCALED, 5, 64),
    "z-score input, displacement target": (LSTMConfig(translate=False, normalise=True), 1, 64),
    "z-score absolute (no translate)": (LSTMConfig(translate=False, normalise=True, target="absolute"), 1, 64),
}


def sweep(args: argparse.Namespace) -> dict[str, dict[str, float]]:
    common, common_paths = noisy_windows(100, 5, seed=1000, angle_std_deg=args.angle_std_deg)  # fresh paths
    common_truth = clean_targets(common, common_paths)
    ref = reference_rmse(common, common_truth)
    print(f"common test set: {len(common)} windows; measurement noise of targets {ref['noise_floor_m']:.3f} m, "
          f"straight line through last 10 points: {ref['linfit10_vs_noisy_m']:.3f} m vs noisy, "
          f"{ref['linfit10_vs_clean_m']:.3f} m vs clean (per-coordinate RMSE)")
    data = {s: paper_splits(stride=s, angle_std_deg=args.angle_std_deg) for s in {v[1] for v in CANDIDATES.values()}}
    results = {}
    names = [n for n in CANDIDATES if not args.only or any(o in n for o in args.only)]
    print(f"angle noise {args.angle_std_deg} deg; RMSE per coordinate in metres, mean over {args.seeds} training "
          "seed(s); 'spread' = max - min of test_clean over the seeds")
    print(f"{'candidate':36s} {'val':>7s} {'val_clean':>9s} {'test':>7s} {'test_clean':>10s} "
          f"{'spread':>7s} {'s/epoch':>8s}")
    for name in names:
        cfg, stride, batch = CANDIDATES[name]
        (train, val, _), clean = data[stride]
        runs = []
        for seed in range(args.seeds):  # training seeds; the data stay the same
            tc = replace(TrainConfig(num_threads=args.threads), batch_size=batch, seed=seed)
            res = train_lstm(train, val, cfg, tc, progress=False)
            p = res.predictor
            pv = p.predict_next(val.x)
            pc = p.predict_next(common.x)
            runs.append({
                "val_rmse_m": res.val_rmse_m,
                "val_rmse_clean_m": rmse_per_coordinate(pv, clean_targets(val, clean)),
                "test_rmse_m": rmse_per_coordinate(pc, common.y),
                "test_rmse_clean_m": rmse_per_coordinate(pc, common_truth),
                "seconds_per_epoch": float(res.history["seconds"].median()),
            })
        r = {k: float(np.mean([run[k] for run in runs])) for k in runs[0]}
        r["test_rmse_clean_spread_m"] = float(np.ptp([run["test_rmse_clean_m"] for run in runs]))
        results[name] = r
        print(f"{name:36s} {r['val_rmse_m']:7.4f} {r['val_rmse_clean_m']:9.4f} {r['test_rmse_m']:7.4f} "
              f"{r['test_rmse_clean_m']:10.4f} {r['test_rmse_clean_spread_m']:7.4f} {r['seconds_per_epoch']:8.2f}",
              flush=True)
    return {"reference": ref, **results}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--threads", type=int, default=1, help="torch intra-op threads (default 1)")
    ap.add_argument("--epochs", type=int, default=2, help="epochs to time in speed mode (default 2)")
    ap.add_argument("--sweep", action="store_true", help="train the candidate models for 15 epochs and compare")
    ap.add_argument("--only", nargs="*", help="with --sweep: candidates whose name contains one of these")
    ap.add_argument("--seeds", type=int, default=1, help="with --sweep: training seeds per candidate (default 1)")
    ap.add_argument("--angle-std-deg", type=float, default=1.0, help="angle noise of the test noise model (default 1)")
    ap.add_argument("--json", action="store_true", help="print the figures as one JSON line at the end")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    out = sweep(args) if args.sweep else speed(args)
    if args.json:
        print(json.dumps(out))


if __name__ == "__main__":
    main()
