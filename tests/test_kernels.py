"""CPU kernel pinning (blindspot.kernels): what is set, when, and the stage runner's restart."""

from __future__ import annotations

import os
import subprocess
import sys

from blindspot import kernels
from tests.conftest import REPO_ROOT

AVX2 = "processor : 0\nflags : fpu sse sse2 avx fma avx2 bmi2\n"
NO_AVX2 = "processor : 0\nflags : fpu sse sse2 avx\n"


def test_pins_are_set_where_missing_and_user_values_kept():
    env = {"MKL_CBWR": "COMPATIBLE"}
    pins = kernels.pin_kernels(env, cpuinfo=AVX2)
    assert env["OPENBLAS_CORETYPE"] == "Haswell" and env["ATEN_CPU_CAPABILITY"] == "avx2"
    assert env["MKL_CBWR"] == "COMPATIBLE" and pins.kept == {"MKL_CBWR": "COMPATIBLE"}
    assert set(pins.applied) == set(kernels.PINS) - {"MKL_CBWR"}
    assert "MKL_CBWR=COMPATIBLE" in pins.summary()


def test_nothing_is_pinned_without_avx2_or_when_opted_out():
    env: dict[str, str] = {}
    assert "AVX2" in kernels.pin_kernels(env, cpuinfo=NO_AVX2).skipped and env == {}
    env = {kernels.OPT_OUT_ENV: "1"}
    assert kernels.pin_kernels(env, cpuinfo=AVX2).skipped and set(env) == {kernels.OPT_OUT_ENV}


def _run(code: str, **extra: str) -> str:
    env = {k: v for k, v in os.environ.items() if k not in kernels.PINS and k != kernels.REEXEC_ENV}
    env.update(extra, PYTHONPATH=str(REPO_ROOT / "src"))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout.strip()


def test_importing_blindspot_first_pins_numpy_before_it_loads():
    out = _run("import blindspot, os, numpy; from blindspot import kernels as k;"
               "print(k.needs_reexec(), os.environ['OPENBLAS_CORETYPE'])")
    if kernels.cpu_has_avx2():
        assert out == "False Haswell"


def test_a_process_that_loaded_numpy_first_asks_for_a_restart_once():
    code = "import numpy, blindspot; from blindspot import kernels as k; print(k.needs_reexec())"
    if kernels.cpu_has_avx2():
        assert _run(code) == "True"
        assert _run(code, **{kernels.REEXEC_ENV: "1"}) == "False"
