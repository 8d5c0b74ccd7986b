"""One check for array arguments: number of axes, element kind, finiteness, axis lengths.

Every public function of the library rooms that takes arrays calls :func:`checked_array` on them
and raises its own module's error class (a ``ValueError`` subclass, e.g.
:class:`blindspot.dsp.cfar.CfarError`), so a user sees one kind of message wherever the bad
array enters:

    ``cfar_2d: power must be an |X|^2 map (..., range, doppler) of real numbers; found
    complex128 array of shape (4, 8)``

instead of numpy's ``could not convert string to float`` or a ``LinAlgError`` three calls deeper.

Non-finite values are counted only when the cheap test fails: the sum of a finite float array is
finite unless it overflows, so a finite array costs one reduction (about 1 ms for one MMWCAS
frame, 3.1 M complex64 samples) instead of an ``isfinite`` mask of its size.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal

import numpy as np

__all__ = ["ArrayKind", "checked_array", "count_nonfinite"]

ArrayKind = Literal["real", "numeric", "integer", "bool", "index"]

# numpy dtype kinds accepted per ArrayKind: b bool, i/u integers, f float, c complex
_KINDS: dict[str, tuple[str, str]] = {
    "real": ("biuf", "real numbers"),
    "numeric": ("biufc", "numbers (real or complex)"),
    "integer": ("iu", "integers"),
    "index": ("iu", "non-negative integers"),
    "bool": ("b", "booleans"),
}


def count_nonfinite(x: np.ndarray) -> int:
    """Number of NaN or infinite elements of a numeric array (0 for integer and bool arrays)."""
    if x.dtype.kind not in "fc" or x.size == 0:
        return 0
    with np.errstate(over="ignore", invalid="ignore"):
        if np.isfinite(np.sum(x)):
            return 0
    return int(x.size - np.count_nonzero(np.isfinite(x)))


def _describe_found(x: np.ndarray) -> str:
    return f"{x.dtype} array of shape {x.shape}"


def checked_array(value: Any, name: str, error: type[Exception], *, axes: str,
                  ndim: int | tuple[int, ...] | None = None, min_ndim: int | None = None,
                  kind: ArrayKind = "real", finite: bool = True, nonnegative: bool = False,
                  lengths: Mapping[int, int] | None = None, min_lengths: Mapping[int, int] | None = None,
                  where: str = "") -> np.ndarray:
    """``value`` as an ndarray (no copy when it already is one), or ``error`` saying why not.

    Args:
        value: the argument (array-like).
        name: the argument's name in the message.
        error: the exception class raised (the calling module's own ``ValueError`` subclass).
        axes: what is expected, with its axes, e.g. ``"a map (frames, range, doppler)"``.
        ndim: the allowed number(s) of axes; ``min_ndim``: a lower bound instead.
        kind: allowed element kind: ``"real"`` (bool, int, float), ``"numeric"`` (also complex),
            ``"integer"``, ``"index"`` (integers >= 0), ``"bool"``. Object, string and other dtypes
            are always refused (no silent conversion of ``"3"``).
        finite: refuse NaN and infinite elements (counted in the message).
        nonnegative: refuse negative elements (real kinds).
        lengths: ``{axis: length}`` required lengths (negative axes count from the end).
        min_lengths: ``{axis: length}`` lower bounds of axis lengths.
        where: the calling function's name, prefixed to the message.

    Returns:
        ``np.asarray(value)``.

    Raises:
        error: naming ``name``, what was expected and what was found.
    """
    prefix = f"{where}: " if where else ""
    x = np.asarray(value)
    allowed, words = _KINDS[kind]

    def fail(expected: str, found: str) -> None:
        raise error(f"{prefix}{name} must be {expected}; found {found}")

    if x.dtype.kind not in allowed:
        fail(f"{axes} of {words}", _describe_found(x))
    if ndim is not None:
        ndims = (ndim,) if isinstance(ndim, int) else tuple(ndim)
        if x.ndim not in ndims:
            fail(f"{axes} ({' or '.join(map(str, ndims))} axes)", _describe_found(x))
    if min_ndim is not None and x.ndim < min_ndim:
        fail(f"{axes} with at least {min_ndim} axes", _describe_found(x))
    for axis, n in (lengths or {}).items():
        if x.shape[axis] != n:
            fail(f"{axes} with {n} along axis {axis}", _describe_found(x))
    for axis, n in (min_lengths or {}).items():
        if x.shape[axis] < n:
            fail(f"{axes} with at least {n} along axis {axis}", _describe_found(x))
    if finite and (bad := count_nonfinite(x)):
        fail(f"{axes} of finite values", f"{bad} NaN/inf value(s) of {x.size}")
    if (nonnegative or kind == "index") and x.dtype.kind in "iuf" and x.size and x.min() < 0:
        fail(f"{axes} of non-negative values", f"a minimum of {x.min()}")
    return x
