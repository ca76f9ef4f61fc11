"""The fleet's state as gauges, for each subject (app.services.subjects: tools, frames): how
many need attention and why, what their controllers hold, and how long ago each was
calibrated and checked.

Everything is read through the fleet service (`list_fleet`), the one place that judges a
subject's attention codes and reports its controller state: this module only counts what it
says, so a rule changed there changes the gauges and the alerts built on them.
"""

from __future__ import annotations

import types
import typing
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from datetime import datetime

from pydantic import BaseModel
from sqlalchemy.orm import Session

from app.services.audit import outbox
from app.services.fleet.fleet import FleetRow, fleet_of, list_fleet
from app.services.subjects import IN_FLEET, Served

#: Fleet rows read per query while walking the fleet (the list's maximum page).
PAGE = 500
#: The label value of a subject whose robot has no controller connection.
NO_CONTROLLER = "none"


@dataclass(frozen=True)
class Ages:
    """One live subject's labels and the seconds since its last calibration and check."""

    subject_id: str
    robot: str
    name: str
    calibration_age_s: float | None
    check_age_s: float | None
    attention: tuple[str, ...]


@dataclass(frozen=True)
class SubjectGauges:
    """Counts over one subject's live fleet (every tool, every frame), and each one's ages."""

    served: Served
    attention: dict[str, int] = field(default_factory=dict)
    controller: dict[str, int] = field(default_factory=dict)
    items: list[Ages] = field(default_factory=list)


@dataclass(frozen=True)
class FleetGauges:
    """Counts over the live fleet, subject by subject, and the publisher's."""

    subjects: list[SubjectGauges] = field(default_factory=list)
    outbox_oldest_age_s: float = 0.0
    outbox_undelivered: int = 0
    publisher_running: bool = False


def read_fleet_gauges(session: Session, *, now: datetime) -> FleetGauges:
    """Every subject's gauges (`read_subject_gauges`) and the publisher's."""
    return FleetGauges(
        subjects=[read_subject_gauges(session, served, now=now) for served in IN_FLEET],
        outbox_oldest_age_s=outbox.oldest_undelivered_age(session),
        outbox_undelivered=outbox.undelivered_count(session),
        publisher_running=outbox.publisher_running(session.get_bind().engine),
    )


def read_subject_gauges(session: Session, served: Served, *, now: datetime) -> SubjectGauges:
    """Walk every live subject once (pages of PAGE rows) and count what its fleet rows say.
    Codes and states its fleet row's schema declares are present with 0 when none has them."""
    row = fleet_of(served).side.row
    attention: Counter[str] = Counter(dict.fromkeys(declared_values(row, "attention"), 0))
    controller: Counter[str] = Counter(dict.fromkeys(_declared_controller_states(row), 0))
    items: list[Ages] = []
    for found in all_rows(session, served):
        codes = attention_codes(found)
        attention.update(codes)
        controller[controller_state(found)] += 1
        cal, chk = found.last_calibration, found.last_check
        items.append(
            Ages(
                subject_id=found.id,
                robot=found.robot_name,
                name=found.name,
                calibration_age_s=None if cal is None else _age(now, cal.created_at),
                check_age_s=None if chk is None else _age(now, chk.created_at),
                attention=codes,
            )
        )
    return SubjectGauges(
        served=served, attention=dict(attention), controller=dict(controller), items=items
    )


def all_rows(
    session: Session, served: Served, *, robot_id: str | None = None
) -> Iterator[FleetRow]:
    """Every live subject's fleet row (of one robot's), PAGE at a time."""
    cursor: str | None = None
    while True:
        rows, cursor = list_fleet(
            session,
            served,
            cell=None,
            robot_id=robot_id,
            q=None,
            status=None,
            limit=PAGE,
            cursor=cursor,
        )
        yield from rows
        if cursor is None:
            return


def _age(now: datetime, then: datetime) -> float:
    return max(0.0, (now - then).total_seconds())


def attention_codes(row: FleetRow) -> tuple[str, ...]:
    """The row's attention codes as the fleet service judged them (none when the fleet
    rows carry no `attention`)."""
    codes = getattr(row, "attention", None) or ()
    return tuple(str(c) for c in codes)


def controller_state(row: FleetRow) -> str:
    """The row's controller state as the fleet service reports it, NO_CONTROLLER when the
    robot has no controller (or the fleet rows carry no `controller`)."""
    controller = getattr(row, "controller", None)
    state = getattr(controller, "state", None)
    if state is None and isinstance(controller, dict):
        state = controller.get("state")
    return NO_CONTROLLER if state is None else str(state)


def _declared_controller_states(row: type[BaseModel]) -> tuple[str, ...]:
    annotation = row.model_fields.get("controller")
    for arg in typing.get_args(annotation.annotation) if annotation else ():
        if isinstance(arg, type) and issubclass(arg, BaseModel):
            return (NO_CONTROLLER, *declared_values(arg, "state"))
    return (NO_CONTROLLER,)


def declared_values(model: type[BaseModel], name: str) -> tuple[str, ...]:
    """The string values a model's field is declared to take (a Literal, or a list or an
    optional of one); empty when the field is absent or free text."""
    info = model.model_fields.get(name)
    return () if info is None else _literal_values(info.annotation)


def _literal_values(annotation: object) -> tuple[str, ...]:
    if typing.get_origin(annotation) is typing.Literal:
        return tuple(str(v) for v in typing.get_args(annotation))
    origin = typing.get_origin(annotation)
    if origin in (list, tuple, set, frozenset, typing.Union, types.UnionType):
        return tuple(v for arg in typing.get_args(annotation) for v in _literal_values(arg))
    return ()
