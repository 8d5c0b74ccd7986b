"""One validation helper for every array a public function of the traj room takes.

:func:`check_array` turns an argument into a float64 (or bool) array after checking, in one
vectorised pass, its dtype (real numbers only: no complex, object, string or bool where
positions are expected), its shape against a pattern with axis names (``("B", "T", 2)``, a
leading ``"..."`` for any batch dims) and its values (no inf; NaN only where the caller says a
NaN means "no point in that frame"). :func:`check_count` does the same for an integer argument.
Each module passes its own error class (a ``ValueError`` subclass: ``MetricShapeError``,
``HistoryError``, ...), so a caller catches the error of the module it called; every message
names the function, the argument, what was expected and what was found.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["check_array", "check_count", "describe_shape"]

# numpy dtype kinds accepted as real numbers: signed/unsigned integers and floats
_REAL = "iuf"


def describe_shape(shape: Sequence[Any]) -> str:
    """``("B", "T", 2)`` -> ``'(B, T, 2)'``; ``("...", "T", 2)`` -> ``'(..., T, 2)'``."""
    return "(" + ", ".join(str(s) for s in shape) + ")"


def check_array(value: Any, name: str, shape: Sequence[Any], *, error: type[ValueError] = ValueError,
                who: str = "", allow_nan: bool = False, dtype: type = float) -> np.ndarray:
    """``value`` as a float64 (``dtype=float``) or bool (``dtype=bool``) array, checked.

    Args:
        value: the argument as given (array or nested sequence).
        name: the argument's name, used in the message.
        shape: the expected shape: an int is a fixed size, a str an axis name of any size (an
            axis name used twice, as in ``("n", "n")``, means equal sizes), and a leading
            ``"..."`` any number (>= 0) of leading axes.
        error: the exception class to raise (the calling module's own ``ValueError`` subclass).
        who: the function or file named at the start of the message.
        allow_nan: NaN stands for a missing value here (inf is refused all the same).
        dtype: ``float`` (real numbers: integers or floats, returned as float64), ``int``
            (integers, or floats holding whole numbers, returned as int64; ids and indices) or
            ``bool``.

    Returns:
        The checked array (a view of ``value`` when it already had the right dtype).

    Raises:
        error: ``value`` is ragged, not real numbers (complex, object, strings, bools where
            numbers are expected), of the wrong rank or size, or holds inf / a refused NaN.
    """
    prefix = f"{who}: " if who else ""
    want = describe_shape(shape)
    kind = {bool: "booleans", int: "integers"}.get(dtype, "real numbers")
    try:
        arr = np.asarray(value)
    except (ValueError, TypeError) as exc:   # ragged nested sequences
        raise error(f"{prefix}{name}: expected an array of {kind} shaped {want}, found "
                    f"{type(value).__name__} that is not a regular array ({exc})") from None
    ok_kind = arr.dtype.kind == "b" if dtype is bool else arr.dtype.kind in _REAL
    if not ok_kind:
        raise error(f"{prefix}{name}: expected an array of {kind} shaped {want}, found dtype "
                    f"{arr.dtype} shape {arr.shape}")
    spec = list(shape)
    batch = bool(spec) and spec[0] == "..."
    fixed = spec[1:] if batch else spec
    if (arr.ndim < len(fixed)) if batch else (arr.ndim != len(fixed)):
        raise error(f"{prefix}{name}: expected shape {want}, found shape {arr.shape}")
    tail = arr.shape[arr.ndim - len(fixed):]
    named: dict[str, int] = {}
    for size, found in zip(fixed, tail):
        if isinstance(size, str):               # an axis name: the same name, the same size
            size = named.setdefault(size, found)
        if size != found:
            raise error(f"{prefix}{name}: expected shape {want}, found shape {arr.shape}")
    if dtype is bool:
        return arr
    if dtype is int:
        if arr.dtype.kind == "f":
            whole = np.isfinite(arr) & (arr == np.round(arr))
            if not whole.all():
                where = tuple(int(i) for i in np.argwhere(~whole)[0])
                raise error(f"{prefix}{name}: expected {kind}, found {arr[where].item()!r} at index "
                            f"{where}")
        return arr.astype(np.int64, copy=False)
    arr = arr.astype(np.float64, copy=False)
    finite = np.isfinite(arr)
    if not finite.all():
        bad = ~finite if not allow_nan else np.isinf(arr)
        if bad.any():
            where = tuple(int(i) for i in np.argwhere(bad)[0])
            what = ("finite values (no NaN, no inf)" if not allow_nan
                    else "finite values or NaN (missing), no inf")
            raise error(f"{prefix}{name}: expected {what}, found {arr[where].item()!r} at index "
                        f"{where} ({int(bad.sum())} such values)")
    return arr


def check_count(value: Any, name: str, *, ge: int = 0, error: type[ValueError] = ValueError,
                who: str = "") -> int:
    """``value`` as a Python int, checked to be an integer (not a bool, not 2.5) >= ``ge``.

    Raises:
        error: naming ``name``, the bound and the value found.
    """
    if (isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer))
            or value < ge):
        prefix = f"{who}: " if who else ""
        raise error(f"{prefix}{name}: expected an integer >= {ge}, found {value!r}")
    return int(value)
