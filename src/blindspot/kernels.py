"""One set of CPU kernels on every x86-64 machine, so the committed ``dvc.lock`` holds elsewhere.

numpy, OpenBLAS, PyTorch, MKL and oneDNN each pick their compute kernels at run time from the
CPU's instruction sets (SSE4, AVX2, AVX-512). Different kernels sum in a different order and round
differently, so the same code and seed give outputs that differ in their last bits from one CPU to
the next, and DVC then sees changed outputs and reruns everything after them (issue 10: a fresh
clone on an AVX-512 machine reran simulate, detect, recordings and paths, and the scene LSTM's
weights moved enough to swing its path error by 40 %). Measured on the project's AMD EPYC machine
(AVX2 kernels pinned), each selector alone changes the bytes (``benchmarks/bench_kernels.py``
reruns this):

* the simulated frames and detections of the tiny profile: ``OPENBLAS_CORETYPE=Sandybridge``
  and ``NPY_DISABLE_CPU_FEATURES=X86_V3`` (numpy's SSE4 instead of AVX2 loops) each give other
  frame and detection hashes;
* 30 Adam steps of a 64-unit LSTM: ``ATEN_CPU_CAPABILITY=default``, ``MKL_CBWR=COMPATIBLE`` and
  ``ONEDNN_MAX_CPU_ISA=SSE41`` each give other weights.

:data:`PINS` fixes each selector at the AVX2 level (x86-64-v3: every x86 server and desktop CPU
since about 2015 has it), and keeps numpy off its AVX-512 loops, so an AVX-512 machine computes
with the kernels an AVX2 machine uses. The values are read when each library loads, so they
must be in the environment before numpy/torch are imported: :func:`pin_kernels` runs when the
``blindspot`` package is imported (this module imports only the standard library), and the stage
runner re-executes a stage whose process imported numpy first (:func:`needs_reexec`).

Not covered: CPUs without AVX2 and other architectures (ARM, e.g. Apple silicon) run their own
kernels (nothing is pinned there, and their bytes may differ); a value the user set is kept (and
reported). Nor does ``MKL_CBWR=AVX2`` make MKL agree across CPU vendors: Intel's oneMKL
developer guide ("Getting Started with Conditional Numerical Reproducibility") states that on
non-Intel CPUs this setting uses the AUTO branch (the CPU's own dispatch) instead, and the same
training inputs gave other network weights on an AMD EPYC (Zen 4) than on an Intel Xeon
(2026-12-03). ``MKL_CBWR=COMPATIBLE`` (SSE2 without rcpps/rsqrtps) is the branch documented for
both; it is not pinned yet, as it is untested on an Intel machine. The radar stages never reach
MKL (numpy/scipy only; import contract ``radar-bytes-without-mkl`` in ``.importlinter``): the
stages that were numpy-only before gave the same bytes on both vendors; paths, driving_detect and
driving_measure, torch-free since 2026-12-03, have run on the AMD EPYC only. The stages that train
a network are not yet portable. ``BLINDSPOT_NATIVE_KERNELS=1`` turns the pinning off (fastest
kernels, machine-dependent bytes).

Sources for the variables: OpenBLAS README ("Runtime CPU detection ... OPENBLAS_CORETYPE"),
numpy "CPU build options / runtime dispatch" (``NPY_DISABLE_CPU_FEATURES``), PyTorch
``ATEN_CPU_CAPABILITY`` (aten/src/ATen/native/DispatchStub.cpp), Intel MKL "Conditional
Numerical Reproducibility" (``MKL_CBWR``), oneDNN "CPU dispatcher control"
(``ONEDNN_MAX_CPU_ISA``).
"""

from __future__ import annotations

import os
import platform
import sys
from collections.abc import MutableMapping
from dataclasses import dataclass, field

__all__ = ["PINS", "OPT_OUT_ENV", "REEXEC_ENV", "KernelPins", "cpu_has_avx2", "pin_kernels",
           "needs_reexec", "STATE"]

PINS: dict[str, str] = {
    "OPENBLAS_CORETYPE": "Haswell",                          # OpenBLAS: AVX2 kernels
    "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",  # numpy: no AVX-512 loops
    "ATEN_CPU_CAPABILITY": "avx2",                           # PyTorch's own CPU kernels
    "MKL_CBWR": "AVX2",                                      # MKL (PyTorch's BLAS/LAPACK)
    "ONEDNN_MAX_CPU_ISA": "AVX2",                            # oneDNN (PyTorch's LSTM, conv)
}
OPT_OUT_ENV = "BLINDSPOT_NATIVE_KERNELS"
REEXEC_ENV = "BLINDSPOT_KERNELS_REEXEC"


def cpu_has_avx2(cpuinfo: str | None = None) -> bool:
    """True on an x86-64 Linux CPU whose ``/proc/cpuinfo`` flags list avx2 and fma."""
    if cpuinfo is None:
        if platform.machine().lower() not in ("x86_64", "amd64"):
            return False
        try:
            with open("/proc/cpuinfo", encoding="ascii", errors="replace") as f:
                cpuinfo = f.read(200_000)
        except OSError:
            return False
    flags = next((line.split(":", 1)[1].split() for line in cpuinfo.splitlines()
                  if line.startswith("flags")), [])
    return "avx2" in flags and "fma" in flags


@dataclass
class KernelPins:
    """What :func:`pin_kernels` did: the values set, the user's own values kept, and why not.

    Attributes:
        applied: variables this call put into the environment (name -> value).
        kept: pinned variables the environment already had with another value (name -> value).
        skipped: why nothing was pinned ("" when pinning ran): opt-out, or no AVX2 CPU.
        late: libraries already imported when the pins were set (their kernels are not pinned).
    """

    applied: dict[str, str] = field(default_factory=dict)
    kept: dict[str, str] = field(default_factory=dict)
    skipped: str = ""
    late: tuple[str, ...] = ()

    def summary(self) -> str:
        if self.skipped:
            return f"kernels not pinned: {self.skipped}"
        parts = ["kernels pinned to AVX2"]
        if self.kept:
            parts.append("user values kept: " + ", ".join(f"{k}={v}" for k, v in self.kept.items()))
        if self.late:
            parts.append("imported before the pins (not pinned): " + ", ".join(self.late))
        return "; ".join(parts)


STATE = KernelPins(skipped="blindspot was not imported yet")
"""The result of the pinning done when the package was imported (set by ``blindspot/__init__``)."""


def pin_kernels(environ: MutableMapping[str, str] | None = None, *,
                cpuinfo: str | None = None) -> KernelPins:
    """Put :data:`PINS` into ``environ`` (default ``os.environ``) where not already set.

    Nothing is set when ``BLINDSPOT_NATIVE_KERNELS`` is 1/true/yes or the CPU lacks AVX2 (see
    :func:`cpu_has_avx2`). Returns what was done; the libraries already loaded in this process
    (numpy, torch, scipy) are listed in ``late``: their kernels were chosen before the pins.
    """
    env = os.environ if environ is None else environ
    pins = KernelPins()
    if env.get(OPT_OUT_ENV, "").strip().lower() in ("1", "true", "yes"):
        pins.skipped = f"{OPT_OUT_ENV} is set"
        return pins
    if not cpu_has_avx2(cpuinfo):
        pins.skipped = "not an x86-64 CPU with AVX2"
        return pins
    for name, value in PINS.items():
        if name not in env:
            env[name] = value
            pins.applied[name] = value
        elif env[name] != value:
            pins.kept[name] = env[name]
    if pins.applied:
        pins.late = tuple(m for m in ("numpy", "torch", "scipy") if m in sys.modules)
    return pins


def needs_reexec(pins: KernelPins | None = None,
                 environ: MutableMapping[str, str] | None = None) -> bool:
    """True when this process should restart itself to compute with the pinned kernels.

    That is when the pins were set after numpy or torch had loaded (a stage script that imports
    pandas before blindspot), and this process is not already such a restart.
    """
    env = os.environ if environ is None else environ
    pins = STATE if pins is None else pins
    return bool(pins.late) and not env.get(REEXEC_ENV)
