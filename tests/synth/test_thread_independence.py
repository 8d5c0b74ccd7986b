"""The radar stages compute the same bytes whatever the thread settings (issue 10.0), and
PyTorch's kernel selectors cannot reach them.

The detect stage's work (simulate every frame, run the detection chain, MUSIC) is run in fresh
interpreters under two thread settings: BLAS/OpenMP/MKL pools of 1 thread in one process, and
pools of 2 threads with two worker processes. The simulated frames and the detections must be
identical to the last bit, so the committed dvc.lock holds whatever OMP_NUM_THREADS a user has.
The same holds for the paths stage's and the driving measurement's work (the reduced chains with
their own MUSIC: 17 walks in two chunks, 8 frames in two batches, so two jobs do use worker
processes), which must also give the same bytes with every PyTorch selector switched to
another kernel family (MKL_CBWR=COMPATIBLE, ATEN_CPU_CAPABILITY=default, ONEDNN_MAX_CPU_ISA=
SSE41): MKL's AVX2 branch computes other last bits on an AMD CPU than on an Intel one (a fresh
AMD clone reran paths and driving_measure when they used torch's MUSIC), so the radar code does
without torch (.importlinter), and these hashes show it.
Kernels of other CPUs (AVX-512 BLAS and numpy loops) cannot be run on this machine; they are
pinned instead (blindspot.kernels), and ``python benchmarks/bench_kernels.py`` shows that each
kernel selector does reach our bytes. The scripts run here are that benchmark's.
"""

from __future__ import annotations

import importlib.util

import pytest

from tests.conftest import REPO_ROOT

_spec = importlib.util.spec_from_file_location("bench_kernels",
                                               REPO_ROOT / "benchmarks" / "bench_kernels.py")
bench_kernels = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench_kernels)


def run_detect(threads: int, jobs: int) -> dict:
    return bench_kernels.chain_hashes("radar", {}, threads=threads, jobs=jobs)


@pytest.mark.slow  # two fresh interpreters simulating and detecting: about 1 min
@pytest.mark.timeout(900)
def test_detections_and_frames_do_not_depend_on_thread_settings():
    one = run_detect(threads=1, jobs=1)
    two = run_detect(threads=2, jobs=2)
    assert one["n_moving"] > 0, one  # the pedestrian is seen in these frames
    assert one == two


@pytest.mark.parametrize("work", ["paths", "driving"])
def test_measured_paths_and_driving_points_do_not_depend_on_threads_or_torch_kernels(work):
    hashes = bench_kernels.chain_hashes
    pinned = hashes(work, {}, threads=1, jobs=1)
    assert pinned["n_points"] > 0, pinned
    assert not pinned["torch_loaded"], \
        "the radar chain imported torch (MKL: vendor-dependent bytes)"
    assert hashes(work, {}, threads=2, jobs=2) == pinned
    assert hashes(work, bench_kernels.TORCH_SELECTORS, threads=1, jobs=1) == pinned
