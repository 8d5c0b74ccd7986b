"""One place for the checks of array arguments: axes, element kind, finiteness, axis lengths.

Every public function of the library rooms that takes arrays checks them here and raises its
own module's error class (a ``ValueError`` subclass, e.g.
:class:`blindspot.dsp.cfar.CfarError`), so a user sees one kind of message wherever the bad
array enters:

    ``cfar_2d: power must be an |X|^2 map (..., range, doppler) of real numbers; found
    complex128 array of shape (4, 8)``

instead of numpy's ``could not convert string to float`` or a ``LinAlgError`` three calls deeper.

Two entry points over the same kind and finiteness rules:

* :func:`checked_array` for signal data (cubes, maps, snapshots: complex allowed, returned as
  given, never copied), shapes described in words;
* :func:`check_array` for coordinates, ids and masks (the trajectory room): a shape pattern with
  axis names (``("B", "T", 2)``; one name used twice means equal sizes; a leading ``"..."`` any
  batch axes), returned as float64 / int64 / bool, NaN allowed where it means "no point";
  :func:`check_count` for an integer argument, :func:`check_number` for a real one (a speed,
  a margin, a period) with its bounds.

Non-finite values are counted only when the cheap test fails: the sum of a finite float array is
finite unless it overflows, so a finite array costs one reduction (about 3 ms for one MMWCAS
frame, 3.1 M complex64 samples, against 5.7 ms for an ``isfinite`` mask; measured on the project's
machine). The detection chain avoids even that: see :mod:`blindspot.dsp.range_doppler`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Literal

import numpy as np

__all__ = ["ArrayKind", "check_array", "check_count", "check_number", "check_same_shape",
           "checked_array", "count_nonfinite", "describe_shape"]

ArrayKind = Literal["real", "numeric", "integer", "bool", "index"]

# numpy dtype kinds accepted per ArrayKind: b bool, i/u integers, f float, c complex
_KINDS: dict[str, tuple[str, str]] = {
    "real": ("iuf", "real numbers"),
    "numeric": ("iufc", "numbers (real or complex)"),
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


def check_same_shape(error: type[Exception], where: str, what: str, **arrays: np.ndarray) -> None:
    """``error`` unless every array of ``arrays`` (name=array) has one shape, e.g. the
    per-detection arrays of one call: ``"{where}: {what} must have one shape; found a (3,), b (4,)"``."""
    if len({a.shape for a in arrays.values()}) > 1:
        shapes = ", ".join(f"{name} {a.shape}" for name, a in arrays.items())
        raise error(f"{where}: {what} must have one shape; found {shapes}")


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
        kind: allowed element kind: ``"real"`` (int, float), ``"numeric"`` (also complex),
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


# ------------------------------------------------------------------- trajectory-style checks
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
    ok_kind = arr.dtype.kind in _KINDS["bool" if dtype is bool else "real"][0]
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


def check_number(value: Any, name: str, *, gt: float | None = None, ge: float | None = None,
                 unit: str = "", error: type[ValueError] = ValueError, who: str = "") -> float:
    """``value`` as a finite Python float (not a bool, a string or an array), checked against
    the bounds ``gt`` (strictly greater) and ``ge`` (at least): a function's own scalar argument,
    such as a margin, a speed or a frame period.

    Raises:
        error: naming ``name``, what was expected (bounds and ``unit``) and the value found.
    """
    bounds = [f"> {gt:g}" if gt is not None else "", f">= {ge:g}" if ge is not None else ""]
    expected = " and ".join(b for b in bounds if b)
    expected = f"a finite number{' ' + expected if expected else ''}{' ' + unit if unit else ''}"
    ok = (not isinstance(value, (bool, np.bool_))
          and isinstance(value, (int, float, np.integer, np.floating))
          and bool(np.isfinite(value))
          and (gt is None or value > gt) and (ge is None or value >= ge))
    if not ok:
        prefix = f"{who}: " if who else ""
        raise error(f"{prefix}{name}: expected {expected}, found {value!r}")
    return float(value)
