"""Checks of table arguments (pandas DataFrames): a function's tracks, points or truth table
has the columns it reads, or the caller is told which are missing and what the table is.

:mod:`blindspot.arrays` checks array and scalar arguments; this module is its counterpart for
tables, kept apart so that the many stages that only check arrays do not depend on it.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

__all__ = ["check_columns"]


def check_columns(table: Any, columns: Iterable[str], name: str, *,
                  error: type[Exception] = ValueError, who: str = "", note: str = "") -> None:
    """Check that ``table`` (a pandas DataFrame, or anything with ``columns``) has every one of
    ``columns``: a function's own table argument, such as tracks, points or a truth table.

    Raises:
        error: naming ``who``, ``name``, the missing columns (sorted) and ``note`` (what the
            table is, e.g. the schema it follows), or that ``table`` has no columns at all (not a
            table: the caller's own error class, so a stage reports it as any other bad input).
        TypeError: ``columns`` is one string (it would be read as its characters).
    """
    prefix = f"{who}: " if who else ""
    if isinstance(columns, (str, bytes)):
        raise TypeError(f"check_columns: columns: expected column names (a list or set), found "
                        f"the string {columns!r}")
    found = getattr(table, "columns", None)
    if found is None:
        raise error(f"{prefix}{name}: expected a table with columns {sorted(set(columns))}, "
                    f"found {type(table).__name__}")
    missing = sorted(set(columns) - set(found))
    if missing:
        raise error(f"{prefix}{name}: missing columns {missing}" + (f" ({note})" if note else ""))
