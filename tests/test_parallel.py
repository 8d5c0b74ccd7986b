"""blindspot.parallel: order kept, and workers confined to the CPUs asked for."""

import os

import pytest

from blindspot.parallel import parallel_map


def _affinity(_):
    return sorted(os.sched_getaffinity(0))


def _square(x):
    return x * x


def test_order_is_kept_in_and_out_of_process():
    assert parallel_map(_square, range(7), 1) == parallel_map(_square, range(7), 3) == \
        [x * x for x in range(7)]


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity"), reason="no CPU affinity here")
def test_workers_are_confined_to_the_first_cpus():
    first = sorted(os.sched_getaffinity(0))[:1]
    seen = parallel_map(_affinity, range(3), 3, cpus=1)
    assert seen == [first] * 3
    with pytest.raises(ValueError, match="cpus"):
        parallel_map(_affinity, range(3), 2, cpus=0)
