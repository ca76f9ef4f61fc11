"""What a subject declares to the fleet (app.services.fleet), beside its `Subject`: its fleet
row's schema, the columns of its own table a row shows (a tool's `slot`) and the parts its
rows show besides those every subject's row shows (a tool's `live`: which TCP its robot moves
by). Every other field of a row, its attention rules, its controller state, its CSV cells
and its gauges are the fleet's, read from the `Subject` alike for every subject.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import Any, Protocol, runtime_checkable

from pydantic import BaseModel
from sqlalchemy import ColumnElement, SQLColumnExpression

from app.schemas.fleet import AnyAttentionCode

#: A column of any type (of a subject's table, or a correlated subquery on it).
Column = SQLColumnExpression[Any]


@runtime_checkable
class LiveRead(Protocol):
    """What a `live` part says of what a round read (a tool's FleetLive, a frame's
    FleetFrameLive): its state, the version it matched and when it was read."""

    @property
    def state(self) -> str: ...
    @property
    def version(self) -> int | None: ...
    @property
    def checked_at(self) -> datetime | None: ...


def live_cells(live: object) -> list[str]:
    """A `live` part's CSV cells (live_state, live_version, live_checked_at)."""
    assert isinstance(live, LiveRead), live
    at = live.checked_at
    version = "" if live.version is None else str(live.version)
    return [live.state, version, "" if at is None else at.isoformat()]


@dataclass(frozen=True, eq=False)
class RowPart:
    """A field of a subject's fleet rows read by columns of their own (a tool's `live`):

    - `field`: the row's field it fills, `columns`: what the page's attention statement
      selects for it (correlated to the subject's table), `read`: the field's value from
      those columns' values, in their order;
    - `rules`: the attention codes it judges, each a condition on a fleet row, as the
      fleet's own rules are;
    - `csv_names` and `csv_cells`: its columns at the end of the CSV, and their cells of
      the field's value.
    """

    field: str
    columns: tuple[Column, ...]
    read: Callable[[Sequence[object]], BaseModel]
    rules: Mapping[AnyAttentionCode, ColumnElement[bool]]
    csv_names: tuple[str, ...]
    csv_cells: Callable[[object], list[str]]


@dataclass(frozen=True, eq=False)
class FleetSide:
    """A subject's fleet rows: `row`, their schema (the subject's, built with every field
    the fleet fills: id, name, robot_id, robot_name, cell, active_version, last_calibration,
    last_check, position_mm, quaternion, attention, controller, drift, each of `columns` and
    each part's field); `columns`, its own table's columns a row shows after its name (and
    the CSV after its name's cell); `parts`, what else it shows; `csv_file`, the name its
    CSV is downloaded as; `operation`, its route's name (the OpenAPI operationId, one per
    subject)."""

    row: type[BaseModel]
    csv_file: str
    columns: tuple[str, ...] = ()
    parts: tuple[RowPart, ...] = ()
    operation: str = "list_fleet"
