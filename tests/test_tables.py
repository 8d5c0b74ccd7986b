"""blindspot.tables.check_columns: a table argument's missing columns named, with the caller, the
argument, the columns (sorted whatever order they are asked in) and what the table is; a
non-table refused with the caller's error class; one string of column names refused."""

from __future__ import annotations

import pandas as pd
import pytest

from blindspot.tables import check_columns


class SchemaError(ValueError):
    pass


def test_a_table_with_every_column_passes_whatever_else_it_holds():
    check_columns(pd.DataFrame(columns=["frame", "x_m", "y_m", "extra"]), ["x_m", "frame"],
                  "tracks")


@pytest.mark.parametrize("asked", [["y_m", "x_m", "frame"], ("frame", "y_m", "x_m"),
                                   ["x_m", "y_m", "frame"]])
def test_missing_columns_are_named_sorted_with_caller_argument_and_note(asked):
    table = pd.DataFrame(columns=["frame"])
    with pytest.raises(SchemaError) as err:
        check_columns(table, asked, "tracks", error=SchemaError, who="approach_z",
                      note="the blindspot.track schema")
    assert str(err.value) == ("approach_z: tracks: missing columns ['x_m', 'y_m'] "
                              "(the blindspot.track schema)")


def test_without_who_or_note_the_message_is_the_argument_and_columns():
    with pytest.raises(ValueError, match=r"^data/points.parquet: missing columns \['scene'\]$"):
        check_columns(pd.DataFrame(columns=["frame"]), ["scene", "frame"],
                      "data/points.parquet")


@pytest.mark.parametrize("table", [None, [1, 2], {"x_m": [1.0]}, "x_m"])
def test_something_without_columns_is_refused_with_the_callers_error(table):
    with pytest.raises(SchemaError, match=f"^cut: tracks: expected a table with columns "
                                          rf"\['x_m'\], found {type(table).__name__}$"):
        check_columns(table, ["x_m"], "tracks", error=SchemaError, who="cut")


def test_one_string_of_columns_is_refused_not_split_into_characters():
    with pytest.raises(TypeError, match="columns: expected column names"):
        check_columns(pd.DataFrame(columns=["x", "_", "m"]), "x_m", "tracks")
