"""blindspot: FMCW radar detection and path prediction of pedestrians hidden behind parked cars.

Importing the package pins the CPU kernels of numpy, OpenBLAS and PyTorch to one set on every
x86-64 machine with AVX2 (see :mod:`blindspot.kernels`), so outputs have the same bytes there.
"""

from blindspot import kernels as _kernels

_kernels.STATE = _kernels.pin_kernels()

__version__ = "0.1.0"
