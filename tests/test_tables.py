"""blindspot.tables.check_columns: a table argument's missing columns named, with the caller, the
argument, the columns (sorted) and what the table is; a non-table refused by its type."""

from __future__ import annotations

import pandas as pd
import pytest

from blindspot.tables import check_columns


class SchemaError(ValueError):
    pass


def test_a_table_with_every_column_passes_whatever_else_it_holds():
    check_columns(pd.DataFrame(columns=["frame", "x_m", "y_m", "extra"]), ["x_m", "frame"],
                  "tracks")


def test_missing_columns_are_named_sorted_with_caller_argument_and_note():
    table = pd.DataFrame(columns=["frame"])
    with pytest.raises(SchemaError) as err:
        check_columns(table, {"y_m", "x_m", "frame"}, "tracks", error=SchemaError,
                      who="approach_z", note="the blindspot.track schema")
    assert str(err.value) == ("approach_z: tracks: missing columns ['x_m', 'y_m'] "
                              "(the blindspot.track schema)")


def test_without_who_or_note_the_message_is_the_argument_and_columns():
    with pytest.raises(ValueError, match=r"^data/points.parquet: missing columns \['scene'\]$"):
        check_columns(pd.DataFrame(columns=["frame"]), ["scene", "frame"],
                      "data/points.parquet")


@pytest.mark.parametrize("table", [None, [1, 2], {"x_m": [1.0]}, "x_m"])
def test_something_without_columns_is_refused_by_its_type(table):
    with pytest.raises(ValueError, match=f"tracks: expected a table with columns "
                                         rf"\['x_m'\], found {type(table).__name__}"):
        check_columns(table, ["x_m"], "tracks")
