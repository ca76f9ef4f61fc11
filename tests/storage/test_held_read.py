"""A held read's rows are of the NamedTuple declared beside its statement, and a row type that
is not the statement's columns is refused when the read is built (at import)."""

from __future__ import annotations

from datetime import datetime
from pathlib import Path
from typing import NamedTuple

import pytest
from sqlalchemy import Column, Integer, MetaData, String, Table, bindparam, select

from app.storage.db import HeldRead, make_engine

_THINGS = Table(
    "things",
    MetaData(),
    Column("id", String(36), primary_key=True),
    Column("size", Integer),
)
_BY_ID = select(_THINGS.c.id, _THINGS.c.size.label("size_mm")).where(
    _THINGS.c.id == bindparam("id")
)


class Thing(NamedTuple):
    id: str
    size_mm: int | None


def test_a_held_read_returns_its_row_type(tmp_path: Path) -> None:
    engine = make_engine(f"sqlite:///{tmp_path / 'things.db'}")
    _THINGS.metadata.create_all(engine)
    with engine.begin() as conn:
        conn.execute(_THINGS.insert().values(id="a", size=3))
    read = HeldRead(Thing, _BY_ID)
    assert read.one_or_none(engine, id="a") == Thing(id="a", size_mm=3)
    assert type(read.one_or_none(engine, id="a")) is Thing
    assert read.one_or_none(engine, id="b") is None
    engine.dispose()


class Unlabelled(NamedTuple):
    id: str
    size: int | None  # the statement labels it size_mm


class OneShort(NamedTuple):
    id: str


class Reordered(NamedTuple):
    size_mm: int | None
    id: str


class OneMore(NamedTuple):
    id: str
    size_mm: int | None
    created_at: datetime


@pytest.mark.parametrize(
    ("row", "says"),
    [
        (Unlabelled, r"missing \['size_mm'\], not selected \['size'\]"),
        (OneShort, r"missing \['size_mm'\], not selected \[\]"),
        (Reordered, r"missing \[\], not selected \[\], in another order than \['id', 'size_mm'\]"),
        (OneMore, r"missing \[\], not selected \['created_at'\]"),
    ],
)
def test_a_row_type_other_than_the_statements_columns_is_refused(
    row: type[tuple[object, ...]], says: str
) -> None:
    with pytest.raises(TypeError, match=says):
        HeldRead(row, _BY_ID)


def test_a_row_type_is_a_named_tuple() -> None:
    with pytest.raises(TypeError, match="NamedTuple, not tuple"):
        HeldRead(tuple, _BY_ID)
