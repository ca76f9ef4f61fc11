"""What a calibrated subject declares, as one `Subject` in its package (the tool's:
app.services.tools.subject), the way a maker declares its `Maker` (app.vendors.maker): its
name, its tables and the words its messages use. The lifecycle (app.services.lifecycle)
takes the declaration and never branches on which subject it is.

Storage: a table per subject, its versions' and its activations' tables, each of one shape
(tests/services/lifecycle/test_subject.py holds that every declared subject's tables have
the columns the lifecycle reads): the subject's row `id`, `robot_id`, `name`, `tolerance`,
the counters `active_version`, `last_version`, `revision`, `updated_at`, `archived_at` and
the drift trend `drift`, `drift_crosses_at`; a version's `<key>`, `version`, `position_mm`,
`quaternion`, `source`, `status`, `calibration_id`, `note`, `created_at`, `created_by`; an
activation's `<key>`, `version`, `previous_version`, `reason`, `reason_text`,
`activated_at`, `activated_by`. `key` ("tool_id") names the subject in its versions, its
activations, the audit trail and the outbox alike.

At the controller (a subject that declares its `controller` side: app.services.controllers
deploys, reconciles and settles it): its deployments' table, a row an attempt, `id`,
`<key>`, `robot_id`, `version`, `protocol`, `target`, `status`, `scope`, `previous`,
`read_back`, `deviation_mm`, `deviation_deg`, `error`, `reason`, `settled`, `actor`,
`created_at`; its controller states' table, a row a subject (`<key>` its primary key),
`robot_id`, `state`, `since`, `checked_at`, `target`, `deviation_mm`, `deviation_deg`,
`controller`, `active_version`, `error`. Its place in a controller is read from its row
(`ControllerSide.target`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any, Generic, Protocol, TypeVar

from pydantic import BaseModel
from sqlalchemy import Column, Table

from app.jsontypes import JsonArray, JsonObject
from app.storage.models import AuditEvent, Base, table_of
from app.vendors.connector import Connector
from app.words import AuditAction, DeploymentScope, ResourceType, Status, VersionSource


class Owned(Protocol):
    """A subject as any reader names it: its id, its robot's, its name."""

    @property
    def id(self) -> str: ...
    @property
    def robot_id(self) -> str: ...
    @property
    def name(self) -> str: ...


class SubjectRow(Owned, Protocol):
    """What the lifecycle reads of a subject's ORM row (a models.Tool)."""

    __tablename__: str

    @property
    def tolerance(self) -> JsonObject: ...
    @property
    def active_version(self) -> int | None: ...
    @property
    def revision(self) -> int: ...
    @property
    def archived_at(self) -> datetime | None: ...
    @property
    def drift(self) -> JsonObject | None: ...


class Valued(Protocol):
    """What serving a version reads of it: its number, its values, its method and time (a
    models.TcpVersion, or a hot read's columns: app.services.lifecycle.hot_read.HotVersion)."""

    @property
    def version(self) -> int: ...
    @property
    def position_mm(self) -> JsonArray: ...
    @property
    def quaternion(self) -> JsonArray: ...
    @property
    def source(self) -> VersionSource: ...
    @property
    def created_at(self) -> datetime: ...


class VersionRow(Valued, Protocol):
    """What the lifecycle reads of a version's ORM row (a models.TcpVersion)."""

    __tablename__: str

    @property
    def status(self) -> Status: ...
    @property
    def calibration_id(self) -> str | None: ...


@dataclass(slots=True)
class Locked:
    """A live subject read under its row lock (FOR UPDATE; BEGIN IMMEDIATE on SQLite), with its
    robot's model: what numbering and activating versions read and change."""

    id: str
    robot_id: str
    name: str
    tolerance: JsonObject | None
    active_version: int | None
    last_version: int
    revision: int
    kinematics: JsonObject | None
    #: When a deferred write (add_version or activate with `deferred`) changed the counters.
    updated_at: datetime | None = None

    @property
    def next_version(self) -> int:
        """The number the subject's next version gets."""
        return self.last_version + 1


class Held(Protocol):
    """What a controller holds of a subject, as its connector reads and writes it: a frame,
    and whatever the subject adds to it (a tool's load: app.vendors.tool.ToolData)."""

    @property
    def position_mm(self) -> tuple[float, float, float]: ...
    @property
    def quaternion(self) -> tuple[float, float, float, float]: ...


TargetT = TypeVar("TargetT")
HeldT = TypeVar("HeldT", bound=Held)


@dataclass(frozen=True)
class ControllerSide(Generic[TargetT, HeldT]):
    """How a subject lives in its robot's controller, declared with the subject:

    - `target`: its place there, read from its row (an ORM row or a row of its table's
      columns: a tool's `slot` and `controller_symbol`);
    - `problem`: why that place cannot address it under a protocol, in a sentence (None
      when it can); `field`: the field of its row a person sets about it under a protocol
      ("slot" or "controller_symbol");
    - `describe`: the place as the protocol's controllers name it ("$TOOL_DATA[3]"), read
      off the protocol's declaration, no session needed;
    - `read` and `write`: what the open session does with it (a connector's read and
      write of that subject);
    - `held`: what deploying writes, from the subject's row and its active version;
    - `scope`: where a deployment holds under a protocol (contract v1.3 `scope`);
    - `deploy_action`: the audit action of a deployment;
    - `deployment_schema`: a deployment as served (its routes' schema, the subject named by
      its key); `reconciled_schema`: the subject as a reconcile answers it;
    - `unaddressed`: the key its reconcile answer lists those it left out under
      ("not_addressable");
    - `moved_by`: the robot moves by the one of its kind a `live` scope deployment writes
      (a tool's TCP): that deployment tells the robot's live one
      (app.services.robots.live_tool).
    """

    target: Callable[[Any], TargetT]
    problem: Callable[[str, TargetT], str | None]
    field: Callable[[str], str]
    describe: Callable[[str, TargetT], str]
    read: Callable[[Connector, TargetT], HeldT]
    write: Callable[[Connector, TargetT, HeldT], None]
    held: Callable[[Any, Valued], HeldT]
    scope: Callable[[str], DeploymentScope]
    deploy_action: AuditAction
    deployment_schema: type[BaseModel]
    reconciled_schema: type[BaseModel]
    unaddressed: str = "not_addressable"
    moved_by: bool = False


#: A controller side of any target and held value, for the code that reads neither's type.
AnySide = ControllerSide[Any, Any]

Row = TypeVar("Row", bound=SubjectRow)
VersionT = TypeVar("VersionT", bound=VersionRow)
ActivationT = TypeVar("ActivationT", bound=Base)


@dataclass(frozen=True, eq=False)
class Subject(Generic[Row, VersionT, ActivationT]):
    """A calibrated subject, declared once in its package:

    - `kind`: the name its audit events carry as their resource type, and its messages use
      ("tool");
    - its ORM models: the subject, a version, an activation, and `calibration_model`, the
      calibrations a version's `calibration_id` names (their `result` holds the quality an
      out-of-tolerance refusal cites);
    - `key`: the column naming it in each lifecycle table ("tool_id");
    - `value`: what a version holds, in words ("TCP");
    - `plural`: the segment its routes and its MQTT topics start with ("tools":
      /v1/tools/..., {prefix}/tools/...); `leaf`: the last segment of the route and of the
      retained topic that serve its active version ("tcp"); `folder`: the OPC UA folder of a
      robot that holds them ("Tools");
    - `check_action`: the audit action of a check of its active version, which the drift
      trend reads back (None while it has no checks: its trend is its versions');
    - `served_detail`: the one JSON column of its own that its hot read serves (a tool's
      `load`; app.services.lifecycle.hot_read);
    - at the controller (None for a subject not deployed yet): `deployment_model`, a
      deployment's ORM model, `state_model`, its controller state's, and `controller`, how
      it is addressed, read and written there (`ControllerSide`).
    """

    kind: ResourceType
    model: type[Row]
    version_model: type[VersionT]
    activation_model: type[ActivationT]
    calibration_model: type[Base]
    key: str
    value: str
    plural: str
    leaf: str
    folder: str
    check_action: AuditAction | None
    served_detail: str | None = None
    deployment_model: type[Base] | None = None
    state_model: type[Base] | None = None
    controller: AnySide | None = None
    table: Table = field(init=False)
    versions: Table = field(init=False)
    activations: Table = field(init=False)
    calibrations: Table = field(init=False)
    #: its deployments' and its controller states' tables (None: not deployed)
    deployments: Table | None = field(init=False)
    states: Table | None = field(init=False)

    def __post_init__(self) -> None:
        tables = Base.metadata.tables
        object.__setattr__(self, "table", tables[self.model.__tablename__])
        object.__setattr__(self, "versions", tables[self.version_model.__tablename__])
        object.__setattr__(self, "activations", table_of(self.activation_model))
        object.__setattr__(self, "calibrations", table_of(self.calibration_model))
        deployment, state = self.deployment_model, self.state_model
        object.__setattr__(
            self, "deployments", None if deployment is None else table_of(deployment)
        )
        object.__setattr__(self, "states", None if state is None else table_of(state))

    @property
    def path(self) -> str:
        """Where its routes start ("/v1/tools")."""
        return f"/v1/{self.plural}"

    def version_key(self) -> Column[str]:
        """The versions' column naming the subject."""
        return self.versions.c[self.key]

    def activation_key(self) -> Column[str]:
        """The activations' column naming the subject."""
        return self.activations.c[self.key]

    def audit_key(self) -> Column[str]:
        """The audit trail's column naming the subject."""
        return table_of(AuditEvent).c[self.key]


#: A subject of any kind, for the functions that read nothing of its row types.
AnySubject = Subject[Any, Any, Any]
