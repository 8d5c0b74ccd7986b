"""How the ethucy stage's work spreads over worker processes: per-fold items (one worker trains
and scores every model of a fold) against (fold, model) items in longest-first order
(:func:`blindspot.traj.ethucy_protocol.benchmark_items`, what ``run_benchmark`` now hands out).

    PYTHONPATH=src BLINDSPOT_SHARED=/work/shared python benchmarks/bench_ethucy_schedule.py \
        [--folds eth,hotel,...] [--models cvm,kalman,lstm,mlp] [--workers 2] [--json]

Runs every (fold, model) item of the pipeline's settings (conf/ethucy/, through params.yaml) once
in this process, one thread, and prints the CPU seconds of each (``time.process_time``: steady
on a shared machine). From them it prints the makespan each schedule would have on ``--workers``
idle cores (greedy list scheduling as ``ProcessPoolExecutor.map`` hands items out: the next item
goes to the first worker free): per fold in the folds' order (the former ``run_benchmark``) and
per (fold, model) costliest first. Item order does not change any score (each model is seeded on
its own: tests/traj/test_ethucy.py). With ``--json`` the last line is
``{"items": {"fold/model": cpu_s}, "makespan_s": {"per_fold": .., "per_item": ..}}``.
"""

from __future__ import annotations

import argparse
import heapq
import json
import time

import blindspot  # noqa: F401  first: pins the CPU kernels
from omegaconf import OmegaConf

from blindspot.traj.config import EthUcyConfig
from blindspot.config import shared_dir
from blindspot.traj.ethucy_protocol import EthUcySettings, benchmark_items, run_fold


def makespan(costs: list[float], workers: int) -> float:
    """Finish time of ``costs`` handed in order to the first free of ``workers`` workers."""
    free = [0.0] * max(int(workers), 1)
    for c in costs:
        heapq.heappush(free, heapq.heappop(free) + c)
    return max(free)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--params", default="params.yaml")
    ap.add_argument("--folds", default=None, help="comma-separated subset (default: the config's)")
    ap.add_argument("--models", default=None, help="comma-separated subset (default: the config's)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    import torch
    from threadpoolctl import threadpool_limits

    cfg = OmegaConf.load(args.params)
    s = EthUcySettings.from_config(EthUcyConfig.from_cfg(cfg), shared_dir=shared_dir(cfg),
                                   seed=int(cfg.seed))
    folds = tuple(args.folds.split(",")) if args.folds else s.folds
    models = tuple(args.models.split(",")) if args.models else s.models
    cpu: dict[tuple[str, str], float] = {}
    with threadpool_limits(1):
        torch.set_num_threads(1)
        for fold, model in benchmark_items(models, folds):
            c0 = time.process_time()
            run_fold(s.data_dir, fold, (model,), s.lstm, progress=False, seq2seq=s.seq2seq,
                     calibration=s.calibration, speed_edges=s.speed_edges)
            cpu[(fold, model)] = time.process_time() - c0
            print(f"{fold:6s} {model:12s} {cpu[(fold, model)]:8.1f} CPU s", flush=True)
    per_fold = [sum(cpu[(f, m)] for m in models) for f in folds]
    per_item = [cpu[i] for i in benchmark_items(models, folds)]
    span = {"per_fold": makespan(per_fold, args.workers),
            "per_item": makespan(per_item, args.workers)}
    total = sum(per_item)
    print(f"total {total:.0f} CPU s; on {args.workers} idle cores: per fold "
          f"{span['per_fold']:.0f} s, per (fold, model) item {span['per_item']:.0f} s "
          f"(bound {total / args.workers:.0f} s)")
    if args.json:
        print(json.dumps({"items": {f"{f}/{m}": v for (f, m), v in cpu.items()},
                          "makespan_s": span}))


if __name__ == "__main__":
    main()
