"""blindspot.parallel: order kept, and workers confined to the CPUs asked for."""

import os

import pytest

from blindspot import parallel
from blindspot.parallel import parallel_map


def _affinity(_):
    return sorted(os.sched_getaffinity(0))


def _square(x):
    return x * x


def test_order_is_kept_in_and_out_of_process():
    assert parallel_map(_square, range(7), 1) == parallel_map(_square, range(7), 3) == \
        [x * x for x in range(7)]


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity"), reason="no CPU affinity here")
def test_workers_are_confined_to_the_cpus_asked_for():
    mine = sorted(os.sched_getaffinity(0))
    seen = parallel_map(_affinity, range(3), 3, cpus=1)
    assert len(seen[0]) == 1 and seen[0][0] in mine and seen == [seen[0]] * 3
    # cpus covering every allowed CPU: no pinning at all
    assert parallel_map(_affinity, range(2), 2, cpus=len(mine)) == [mine] * 2
    with pytest.raises(ValueError, match="cpus"):
        parallel_map(_affinity, range(3), 2, cpus=0)


def test_pinned_workers_take_the_idlest_cpus(monkeypatch):
    """Two pinned stages at once must not stack on CPU 0: the busy one is avoided."""
    samples = iter([{0: 100, 1: 100, 2: 100, 3: 100}, {0: 105, 1: 180, 2: 101, 3: 190}])
    monkeypatch.setattr(parallel, "_cpu_busy_ticks", lambda: next(samples))
    assert parallel.idlest_cpus([0, 1, 2, 3], 2, sample_s=0) == [0, 2]
    samples = iter([{}, {}])  # no /proc/stat: the first ones
    assert parallel.idlest_cpus([3, 5, 7], 2, sample_s=0) == [3, 5]
    # all idle: the tie goes by process id, so two processes need not take the same CPUs
    picks = set()
    for pid in (10, 11, 12):
        monkeypatch.setattr(parallel.os, "getpid", lambda pid=pid: pid)
        samples = iter([{0: 1, 1: 1, 2: 1}, {0: 1, 1: 1, 2: 1}])
        picks.add(tuple(parallel.idlest_cpus([0, 1, 2], 1, sample_s=0)))
    assert picks == {(0,), (1,), (2,)}
