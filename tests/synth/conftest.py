"""DSP tests run their BLAS/OpenMP pools on one thread: the batched small matrix products and
eigendecompositions here are much slower with OpenBLAS threads competing for busy cores."""

import pytest
from threadpoolctl import threadpool_limits


@pytest.fixture(autouse=True, scope="session")
def _single_threaded_blas():
    with threadpool_limits(limits=1):
        yield
