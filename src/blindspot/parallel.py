"""Process-level parallelism for work split by scene or batch."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from functools import partial
from typing import Any


def parallel_map(fn: Callable[[Any], Any], items: Sequence[Any], jobs: int,
                 progress: str | None = None, *, cpus: int | None = None) -> list:
    """``[fn(x) for x in items]`` over ``jobs`` worker processes (1 = in this process), with BLAS
    pools pinned to one thread (in-process too): the chain's work is many small matrices, where
    BLAS threads only fight over the cores (measured: the six scenes' detection took 227 s with
    default pools, 21 s with two single-threaded processes). Order is kept. ``progress`` names a
    tqdm bar over the items (None = silent).

    ``cpus``: confine the workers to ``cpus`` of the CPUs this process may run on (Linux CPU
    affinity; ignored where the platform has none, and when ``cpus`` covers them all): the
    idlest ones over a 50 ms sample of ``/proc/stat`` (:func:`idlest_cpus`), so a pinned stage
    started beside a busy one (queued ``dvc exp`` runs, a multirun) avoids its cores; the choice
    is made once, at start (two stages started in the same instant on an idle machine may still
    pick the same cores; ties are broken by process id to make that less likely).
    E.g. ``jobs`` = one worker per equal-sized
    item that then time-share ``cpus`` cores and finish together: ``n / cpus`` item-times instead
    of ``ceil(n / cpus)`` rounds with idle cores in the last one (five ensemble members on two
    cores: 2.5 instead of 3)."""
    from threadpoolctl import threadpool_limits
    from tqdm.auto import tqdm

    def bar(it):
        return tqdm(it, total=len(items), desc=progress, disable=progress is None)

    if jobs <= 1 or len(items) <= 1:
        with threadpool_limits(1):
            return [fn(x) for x in bar(items)]
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    allowed = None
    if cpus is not None and hasattr(os, "sched_getaffinity"):
        if int(cpus) < 1:
            raise ValueError(f"parallel_map: cpus must be >= 1, found {cpus!r}")
        mine = sorted(os.sched_getaffinity(0))
        allowed = idlest_cpus(mine, int(cpus)) if int(cpus) < len(mine) else None
    with ProcessPoolExecutor(max_workers=min(jobs, len(items)), mp_context=mp.get_context("fork"),
                             initializer=partial(_single_threaded, allowed)) as pool:
        return list(bar(pool.map(fn, items)))


def _cpu_busy_ticks() -> dict[int, int]:
    """Per CPU: its non-idle clock ticks so far (``/proc/stat``: user nice system idle iowait
    irq softirq steal ...; idle and iowait are the idle ones). Empty where unreadable."""
    try:
        lines = open("/proc/stat", encoding="ascii").read().splitlines()
    except OSError:
        return {}
    out = {}
    for line in lines:
        name, *ticks = line.split()
        if name.startswith("cpu") and name[3:].isdigit():
            t = [int(v) for v in ticks[:8]]
            out[int(name[3:])] = sum(t) - t[3] - t[4]
    return out


def idlest_cpus(allowed: Sequence[int], n: int, sample_s: float = 0.05) -> list[int]:
    """The ``n`` CPUs of ``allowed`` with the fewest busy ticks over ``sample_s`` seconds
    (``/proc/stat`` counts in 10 ms ticks, so a 50 ms sample sees whole busy cores, not load
    fractions), sorted. Ties are broken by a rotation of ``allowed`` by this process's id;
    without ``/proc/stat``, the first ``n``."""
    import time

    allowed = list(allowed)
    before = _cpu_busy_ticks()
    time.sleep(sample_s)
    after = _cpu_busy_ticks()
    if not after:
        return sorted(allowed[:n])
    busy = {c: after.get(c, 0) - before.get(c, 0) for c in allowed}
    turn = os.getpid() % len(allowed)
    rank = {c: (i - turn) % len(allowed) for i, c in enumerate(allowed)}
    return sorted(sorted(allowed, key=lambda c: (busy[c], rank[c]))[:n])


def _single_threaded(allowed: list[int] | None = None) -> None:
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)
    if allowed:
        os.sched_setaffinity(0, allowed)
