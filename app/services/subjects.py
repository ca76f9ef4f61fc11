"""The calibrated subjects tcpcal serves, each declared in its package as one
`Subject` (app.services.lifecycle.subject), listed here as app.vendors.registry lists the
makers: what the lifecycle serves for every subject alike (the publisher's topics, the
fleet, the plant's address space) reads this list. tests/services/lifecycle/test_subject.py
holds that each declared subject's tables are of the shape the lifecycle reads.

Adding a subject: its package (models, schemas, methods, routes) declaring its `Subject`,
its line here, its key in app.storage.models.SUBJECT_KEYS (a column of audit_events and
outbox, by a migration) and its resource type in app.words.ResourceType.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from pydantic import BaseModel
from sqlalchemy.orm import Session

from app.schemas.fleet import FleetTool
from app.schemas.frames import FleetFrame
from app.services.frames.live import FRAME_LIVE
from app.services.frames.subject import FRAME
from app.services.frames.versions import served_frame
from app.services.lifecycle.fleet import FleetSide
from app.services.lifecycle.subject import AnySubject
from app.services.tools.live import TOOL_LIVE
from app.services.tools.subject import TOOL
from app.services.tools.versions import served_tcp


@dataclass(frozen=True)
class Served:
    """A subject and what its read route serves of its active version (the subject's own
    document and its ETag: a tool's GET /v1/tools/{id}/tcp), which the publisher publishes;
    `document` raises the route's 404 when it serves none (archived, no active version);
    `fleet`, what its fleet rows show of its own (app.services.lifecycle.fleet; None: it
    has no fleet rows yet, and the plant's address space does not show it either);
    `value_in`, the frame its versions' values are given in, in words (what the plant's
    address space says of them)."""

    subject: AnySubject
    document: Callable[[Session, str], tuple[BaseModel | None, str]]
    fleet: FleetSide | None = None
    value_in: str = ""


def _tool_document(session: Session, tool_id: str) -> tuple[BaseModel | None, str]:
    return served_tcp(session, tool_id=tool_id, fmt=None, if_none_match=None)


def _frame_document(session: Session, frame_id: str) -> tuple[BaseModel | None, str]:
    return served_frame(session, frame_id=frame_id, if_none_match=None)


#: Every calibrated subject with what it serves, tools first.
SERVED: tuple[Served, ...] = (
    Served(
        TOOL,
        _tool_document,
        FleetSide(FleetTool, "tcpcal-fleet.csv", ("slot",), (TOOL_LIVE,)),
        value_in="the flange frame",
    ),
    Served(
        FRAME,
        _frame_document,
        FleetSide(
            FleetFrame,
            "tcpcal-frames.csv",
            ("kind", "slot"),
            (FRAME_LIVE,),
            operation="list_frame_fleet",
        ),
        value_in="the robot's base frame",
    ),
)
#: Every calibrated subject, tools first.
SUBJECTS: tuple[AnySubject, ...] = tuple(served.subject for served in SERVED)
#: The subjects that have fleet rows (and are shown in the plant's address space).
IN_FLEET: tuple[Served, ...] = tuple(served for served in SERVED if served.fleet is not None)
#: The subjects by kind (their audit resource type).
BY_KIND: dict[str, AnySubject] = {subject.kind: subject for subject in SUBJECTS}
