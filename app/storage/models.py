"""Every table of tcpcal: SQLAlchemy 2 typed models with a constraint naming convention.

Robots and tools are archived, never deleted: their calibrations, versions, activations and
audit trail stay. A tool's `revision` counts every change to the tool, its versions or its
activation; the tool's ETag is derived from it.
"""

from __future__ import annotations

import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import UTC, datetime

from sqlalchemy import (
    JSON,
    BigInteger,
    Boolean,
    DateTime,
    Float,
    ForeignKey,
    Index,
    Integer,
    MetaData,
    String,
    Table,
    Text,
    UniqueConstraint,
    false,
    text,
)
from sqlalchemy.engine import Dialect
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column
from sqlalchemy.types import TypeDecorator

from app.jsontypes import JsonArray, JsonObject
from app.scopes import Scope
from app.words import (
    ActivationKind,
    Algorithm,
    AuditAction,
    DeploymentScope,
    DeploymentStatus,
    FrameKind,
    FrameMethodName,
    LaserDeviceSource,
    MethodName,
    PoseFormat,
    ProtocolName,
    ResourceType,
    SessionMethod,
    SessionStatus,
    Status,
    ToolState,
)

NAMING_CONVENTION = {
    "ix": "ix_%(column_0_label)s",
    "uq": "uq_%(table_name)s_%(column_0_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}

# SQLite only autoincrements INTEGER PRIMARY KEY; PostgreSQL gets a 64-bit identity.
AutoId = BigInteger().with_variant(Integer(), "sqlite")


#: Set only by `clock_at` (the demo writes a history that spans months); None: the real time.
_frozen_now: datetime | None = None


def utcnow() -> datetime:
    """The current time, timezone-aware UTC."""
    return _frozen_now or datetime.now(UTC)


@contextmanager
def clock_at(moment: datetime) -> Iterator[None]:
    """Stamp every row written inside the block with `moment` (single-threaded use only)."""
    global _frozen_now
    _frozen_now = moment
    try:
        yield
    finally:
        _frozen_now = None


def new_id() -> str:
    """A new random resource id."""
    return str(uuid.uuid4())


class UTCDateTime(TypeDecorator[datetime]):
    """Timezone-aware UTC on the way in and out, also on SQLite (which stores naive text)."""

    impl = DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            raise ValueError("naive datetime given to a UTC column")
        return value.astimezone(UTC)

    def process_result_value(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)


class Base(DeclarativeBase):
    metadata = MetaData(naming_convention=NAMING_CONVENTION)
    # SQLAlchemy reads this off the class; it is never mutated.
    type_annotation_map = {  # noqa: RUF012
        datetime: UTCDateTime(),
        JsonObject: JSON(),
        JsonArray: JSON(),
    }


def table_of(model: type[Base]) -> Table:
    """A model's table, typed as the Table it is (for Core insert and update statements, which
    the hot write paths use instead of ORM objects)."""
    return Base.metadata.tables[model.__tablename__]


class Robot(Base):
    __tablename__ = "robots"
    __table_args__ = (
        Index(
            "uq_robots_live_name",
            "name",
            unique=True,
            sqlite_where=text("archived_at IS NULL"),
            postgresql_where=text("archived_at IS NULL"),
        ),
        Index("ix_robots_created", "created_at", "id"),
    )

    id: Mapped[str] = mapped_column(String(36), primary_key=True, default=new_id)
    name: Mapped[str] = mapped_column(String(200))
    vendor: Mapped[str | None] = mapped_column(String(200))
    model: Mapped[str | None] = mapped_column(String(200))
    serial: Mapped[str | None] = mapped_column(String(200))
    cell: Mapped[str | None] = mapped_column(String(200), index=True)
    kinematics: Mapped[JsonObject | None] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    updated_at: Mapped[datetime] = mapped_column(default=utcnow)
    archived_at: Mapped[datetime | None] = mapped_column()


def subject_indexes(table: str) -> tuple[Index, ...]:
    """A subject table's indexes, named after it (`uq_<table>_live_name`, ...): name and slot
    unique among a robot's live ones, a robot's listed oldest first, and the live ones paged
    through oldest first (the fleet list, bench/scale.py)."""
    live = text("archived_at IS NULL")
    return (
        Index(
            f"uq_{table}_live_name",
            "robot_id",
            "name",
            unique=True,
            sqlite_where=live,
            postgresql_where=live,
        ),
        Index(
            f"uq_{table}_live_slot",
            "robot_id",
            "slot",
            unique=True,
            sqlite_where=text("archived_at IS NULL AND slot IS NOT NULL"),
            postgresql_where=text("archived_at IS NULL AND slot IS NOT NULL"),
        ),
        Index(f"ix_{table}_robot_created", "robot_id", "created_at", "id"),
        Index(
            f"ix_{table}_live_created",
            "created_at",
            "id",
            sqlite_where=live,
            postgresql_where=live,
        ),
    )


class SubjectColumns:
    """A calibrated subject's columns, for every subject's table alike (the row the lifecycle
    reads: app.services.lifecycle.subject); each table adds what its subject is besides (a
    tool's serial and load, a frame's kind) and takes its indexes from `subject_indexes`."""

    __tablename__: str
    id: Mapped[str] = mapped_column(String(36), primary_key=True, default=new_id)
    robot_id: Mapped[str] = mapped_column(ForeignKey("robots.id"))
    name: Mapped[str] = mapped_column(String(200))
    #: The controller's number for it (a tool's slot; a frame's number,
    #: app.vendors.maker.Maker.frame_numbers), where it has one.
    slot: Mapped[int | None] = mapped_column(Integer)
    #: Under a protocol addressing it by symbol: its RAPID variable (a tool's PERS tooldata),
    #: "TASK/MODULE/SYMBOL".
    controller_symbol: Mapped[str | None] = mapped_column(String(100))
    description: Mapped[str | None] = mapped_column(Text)
    tolerance: Mapped[JsonObject] = mapped_column(JSON)
    active_version: Mapped[int | None] = mapped_column(Integer)
    last_version: Mapped[int] = mapped_column(Integer, default=0)
    revision: Mapped[int] = mapped_column(Integer, default=1)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    updated_at: Mapped[datetime] = mapped_column(default=utcnow)
    archived_at: Mapped[datetime | None] = mapped_column()
    #: The drift trend (app.services.lifecycle.drift), refreshed when a version or a check is
    #: written; drift_crosses_at: when its projection leaves check_mm at 95 % confidence, if it
    #: does.
    drift: Mapped[JsonObject | None] = mapped_column(JSON)
    drift_crosses_at: Mapped[datetime | None] = mapped_column()


class Tool(SubjectColumns, Base):
    """A tool of a robot: its TCP versioned and activated by the lifecycle
    (app.services.tools.subject)."""

    __tablename__ = "tools"
    __table_args__ = subject_indexes("tools")

    serial: Mapped[str | None] = mapped_column(String(200))
    load: Mapped[JsonObject | None] = mapped_column(JSON)


class Calibration(Base):
    """One submission as received and what the solver made of it (also when out of tolerance)."""

    __tablename__ = "calibrations"
    __table_args__ = (Index("ix_calibrations_tool_created", "tool_id", "created_at", "id"),)

    id: Mapped[str] = mapped_column(String(36), primary_key=True, default=new_id)
    tool_id: Mapped[str] = mapped_column(ForeignKey("tools.id"))
    method: Mapped[MethodName] = mapped_column(String(40))
    algorithm: Mapped[Algorithm | None] = mapped_column(String(40))
    status: Mapped[Status] = mapped_column(String(40))
    request: Mapped[JsonObject] = mapped_column(JSON)
    result: Mapped[JsonObject] = mapped_column(JSON)
    version: Mapped[int | None] = mapped_column(Integer)
    #: A guided session's touches: where each came from ("typed" | "controller"), and what
    #: the controller printed for a captured one; null for a calibration not made touch by
    #: touch.
    touches: Mapped[JsonArray | None] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    created_by: Mapped[str] = mapped_column(String(200))


class VersionColumns:
    """A version's columns, for every subject's versions table alike; each table adds the
    column naming its subject, the method that made the version (`source`, in the subject's
    method names) and the calibration it came from (in the subject's calibrations table)."""

    id: Mapped[str] = mapped_column(String(36), primary_key=True, default=new_id)
    version: Mapped[int] = mapped_column(Integer)
    position_mm: Mapped[JsonArray] = mapped_column(JSON)
    quaternion: Mapped[JsonArray] = mapped_column(JSON)
    status: Mapped[Status] = mapped_column(String(40))
    note: Mapped[str | None] = mapped_column(Text)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    created_by: Mapped[str] = mapped_column(String(200))


class ActivationColumns:
    """An activation's columns, for every subject's activations table alike (the history
    behind the subject's `active_version`, with who and when); each table adds the column
    naming its subject."""

    id: Mapped[int] = mapped_column(AutoId, primary_key=True, autoincrement=True)
    version: Mapped[int] = mapped_column(Integer)
    previous_version: Mapped[int | None] = mapped_column(Integer)
    #: the kind (app.words.ActivationKind)
    reason: Mapped[ActivationKind] = mapped_column(String(40))
    #: the person's own words (activation or rollback body `reason`), when given
    reason_text: Mapped[str | None] = mapped_column(String(500))
    activated_at: Mapped[datetime] = mapped_column(default=utcnow)
    activated_by: Mapped[str] = mapped_column(String(200))


class TcpVersion(VersionColumns, Base):
    """Version n of a tool's TCP: immutable once written."""

    __tablename__ = "tcp_versions"
    __table_args__ = (UniqueConstraint("tool_id", "version", name="uq_tcp_versions_tool_version"),)

    tool_id: Mapped[str] = mapped_column(ForeignKey("tools.id"))
    #: the method that made the version (`manual` for a TCP entered by hand)
    source: Mapped[MethodName] = mapped_column(String(40))
    calibration_id: Mapped[str | None] = mapped_column(ForeignKey("calibrations.id"))


class Activation(ActivationColumns, Base):
    """One activation of a tool's version."""

    __tablename__ = "activations"
    __table_args__ = (Index("ix_activations_tool_seq", "tool_id", "id"),)

    tool_id: Mapped[str] = mapped_column(ForeignKey("tools.id"))


class Frame(SubjectColumns, Base):
    """A frame of a robot's cell: a base (work object, user frame) the robot's points are
    taught in, or a fixed tool standing in the cell (`kind`). Its value is a pose in the
    robot's base frame, versioned and activated by the lifecycle as a tool's TCP is
    (app.services.frames.subject)."""

    __tablename__ = "frames"
    __table_args__ = subject_indexes("frames")

    kind: Mapped[FrameKind] = mapped_column(String(20))


class FrameCalibration(Base):
    """One frame calibration as received and what its method made of it (also when out of
    tolerance): the touches, their points in the base frame, the pointer tool and its
    version, and the fiducials it kept."""

    __tablename__ = "frame_calibrations"
    __table_args__ = (Index("ix_frame_calibrations_frame_created", "frame_id", "created_at", "id"),)

    id: Mapped[str] = mapped_column(String(36), primary_key=True, default=new_id)
    frame_id: Mapped[str] = mapped_column(ForeignKey("frames.id"))
    method: Mapped[FrameMethodName] = mapped_column(String(40))
    status: Mapped[Status] = mapped_column(String(40))
    request: Mapped[JsonObject] = mapped_column(JSON)
    result: Mapped[JsonObject] = mapped_column(JSON)
    version: Mapped[int | None] = mapped_column(Integer)
    #: Where each touch came from (a guided session's, as a tool calibration's); null else.
    touches: Mapped[JsonArray | None] = mapped_column(JSON)
    #: Each touch's point in the base frame (mm), in the order touched.
    points_mm: Mapped[JsonArray] = mapped_column(JSON)
    #: The pointer tool and the TCP version its touches were computed with (null: none used).
    pointer_tool_id: Mapped[str | None] = mapped_column(ForeignKey("tools.id"))
    pointer_version: Mapped[int | None] = mapped_column(Integer)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    created_by: Mapped[str] = mapped_column(String(200))


class FrameVersion(VersionColumns, Base):
    """Version n of a frame: immutable once written."""

    __tablename__ = "frame_versions"
    __table_args__ = (
        UniqueConstraint("frame_id", "version", name="uq_frame_versions_frame_version"),
    )

    frame_id: Mapped[str] = mapped_column(ForeignKey("frames.id"))
    #: the method that made the version (`manual` for a frame entered by hand)
    source: Mapped[FrameMethodName] = mapped_column(String(40))
    calibration_id: Mapped[str | None] = mapped_column(ForeignKey("frame_calibrations.id"))


class FrameActivation(ActivationColumns, Base):
    """One activation of a frame's version."""

    __tablename__ = "frame_activations"
    __table_args__ = (Index("ix_frame_activations_frame_seq", "frame_id", "id"),)

    frame_id: Mapped[str] = mapped_column(ForeignKey("frames.id"))


class FrameFiducial(Base):
    """A point a frame calibration touched, kept with its coordinates in the frame
    (`nominal_mm`) to be touched again after a move; `name` is given by the method (a role,
    "p3") and can be renamed (PUT /v1/frames/{frame_id}/fiducials)."""

    __tablename__ = "frame_fiducials"
    __table_args__ = (
        UniqueConstraint("calibration_id", "name", name="uq_frame_fiducials_calibration_name"),
        Index("ix_frame_fiducials_frame", "frame_id", "calibration_id", "seq"),
    )

    id: Mapped[int] = mapped_column(AutoId, primary_key=True, autoincrement=True)
    frame_id: Mapped[str] = mapped_column(ForeignKey("frames.id"))
    calibration_id: Mapped[str] = mapped_column(ForeignKey("frame_calibrations.id"))
    #: the touch's place among the calibration's touches
    seq: Mapped[int] = mapped_column(Integer)
    name: Mapped[str] = mapped_column(String(100))
    nominal_mm: Mapped[JsonArray] = mapped_column(JSON)
    #: where the calibrated frame puts it in the base frame (mm)
    point_mm: Mapped[JsonArray] = mapped_column(JSON)


class ReferencePoint(Base):
    __tablename__ = "reference_points"
    __table_args__ = (
        UniqueConstraint("robot_id", "name", name="uq_reference_points_robot_name"),
        Index("ix_reference_points_robot_created", "robot_id", "created_at", "id"),
    )

    id: Mapped[str] = mapped_column(String(36), primary_key=True, default=new_id)
    robot_id: Mapped[str] = mapped_column(ForeignKey("robots.id"))
    name: Mapped[str] = mapped_column(String(200))
    position_mm: Mapped[JsonArray] = mapped_column(JSON)
    covariance_mm2: Mapped[JsonArray | None] = mapped_column(JSON)
    #: "numeric", the calibration's method, or "touch:<tool id>:v<version>": a description
    #: naming a tool, not a closed list of words (so `str`, not a Literal)
    source: Mapped[str] = mapped_column(String(100))
    calibration_id: Mapped[str | None] = mapped_column(ForeignKey("calibrations.id"))
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    created_by: Mapped[str] = mapped_column(String(200))


class LaserDevice(Base):
    __tablename__ = "laser_devices"
    __table_args__ = (
        UniqueConstraint("robot_id", "name", name="uq_laser_devices_robot_name"),
        Index("ix_laser_devices_robot_created", "robot_id", "created_at", "id"),
    )

    id: Mapped[str] = mapped_column(String(36), primary_key=True, default=new_id)
    robot_id: Mapped[str] = mapped_column(ForeignKey("robots.id"))
    name: Mapped[str] = mapped_column(String(200))
    beam_a_y_mm: Mapped[float] = mapped_column(Float)
    beam_b_x_mm: Mapped[float] = mapped_column(Float)
    plane_z_mm: Mapped[float] = mapped_column(Float)
    source: Mapped[LaserDeviceSource] = mapped_column(String(40))
    details: Mapped[JsonObject | None] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    created_by: Mapped[str] = mapped_column(String(200))


class ApiKey(Base):
    """An API key; only the SHA-256 of the secret is stored (keys are 256-bit random)."""

    __tablename__ = "api_keys"

    id: Mapped[str] = mapped_column(String(36), primary_key=True, default=new_id)
    name: Mapped[str] = mapped_column(String(200))
    scope: Mapped[Scope] = mapped_column(String(20))
    key_hash: Mapped[str] = mapped_column(String(64), unique=True)
    prefix: Mapped[str] = mapped_column(String(20))
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    created_by: Mapped[str | None] = mapped_column(String(200))
    revoked_at: Mapped[datetime | None] = mapped_column()
    #: The robot cells the key is limited to (a list of names); null: every cell.
    cells: Mapped[JsonArray | None] = mapped_column(JSON)


class IdempotencyRecord(Base):
    """The first response to a keyed submission, replayed for the same key and body."""

    __tablename__ = "idempotency_records"
    __table_args__ = (UniqueConstraint("api_key_id", "key", name="uq_idempotency_records_key"),)

    id: Mapped[int] = mapped_column(AutoId, primary_key=True, autoincrement=True)
    api_key_id: Mapped[str] = mapped_column(String(36))
    key: Mapped[str] = mapped_column(String(200))
    request_hash: Mapped[str] = mapped_column(String(64))
    status_code: Mapped[int] = mapped_column(Integer)
    response: Mapped[JsonObject] = mapped_column(JSON)
    created_at: Mapped[datetime] = mapped_column(default=utcnow, index=True)


#: The columns of audit_events and outbox that name a calibrated subject, one per subject
#: (app.services.lifecycle.subject.Subject.key; tests/services/lifecycle holds them equal).
SUBJECT_KEYS: tuple[str, ...] = ("tool_id", "frame_id")


class AuditEvent(Base):
    """Every write, with who, when and in which request: the audit trail.

    GET /v1/audit reads it newest first (by id) under any one filter through an index that
    ends in id, so that a filtered page is a seek whatever the length of the trail.
    """

    __tablename__ = "audit_events"
    __table_args__ = (
        Index("ix_audit_events_resource", "resource_type", "resource_id"),
        Index("ix_audit_events_tool_action", "tool_id", "action", "id"),
        Index("ix_audit_events_tool", "tool_id", "id"),
        Index("ix_audit_events_frame_action", "frame_id", "action", "id"),
        Index("ix_audit_events_frame", "frame_id", "id"),
        Index("ix_audit_events_robot", "robot_id", "id"),
        Index("ix_audit_events_action", "action", "id"),
        Index("ix_audit_events_actor", "actor", "id"),
        Index("ix_audit_events_at", "at", "id"),
    )

    id: Mapped[int] = mapped_column(AutoId, primary_key=True, autoincrement=True)
    at: Mapped[datetime] = mapped_column(default=utcnow)
    actor: Mapped[str] = mapped_column(String(200))
    api_key_id: Mapped[str | None] = mapped_column(String(36))
    action: Mapped[AuditAction] = mapped_column(String(60))
    resource_type: Mapped[ResourceType] = mapped_column(String(40))
    resource_id: Mapped[str] = mapped_column(String(36))
    robot_id: Mapped[str | None] = mapped_column(String(36))
    tool_id: Mapped[str | None] = mapped_column(String(36))
    frame_id: Mapped[str | None] = mapped_column(String(36))
    #: The TCP version the change concerns (a calibration's, an activation's, a check's).
    version: Mapped[int | None] = mapped_column(Integer)
    #: The X-Request-ID of the request that made the change (null from the command line).
    request_id: Mapped[str | None] = mapped_column(String(128))
    details: Mapped[JsonObject | None] = mapped_column(JSON)


class GuidedSession(Base):
    """A guided calibration in progress: its settings and the touches made so far.

    Everything a client sees (estimate, outliers, next pose, done) is computed from these
    rows, so any worker or instance continues a session where another left it.
    """

    __tablename__ = "guided_sessions"
    __table_args__ = (
        Index("ix_guided_sessions_tool_created", "tool_id", "created_at", "id"),
        Index("ix_guided_sessions_frame_created", "frame_id", "created_at", "id"),
    )

    id: Mapped[str] = mapped_column(String(36), primary_key=True, default=new_id)
    #: the tool a session calibrates, or the pointer a frame session touches with
    tool_id: Mapped[str] = mapped_column(ForeignKey("tools.id"))
    #: the frame a frame session calibrates; null for a tool's session
    frame_id: Mapped[str | None] = mapped_column(ForeignKey("frames.id"))
    method: Mapped[SessionMethod] = mapped_column(String(40))
    format: Mapped[PoseFormat] = mapped_column(String(40))
    units: Mapped[JsonObject | None] = mapped_column(JSON)
    target_sigma_mm: Mapped[float | None] = mapped_column(Float)
    #: a tool session's reachable cone; null for a frame session
    max_tilt_deg: Mapped[float | None] = mapped_column(Float)
    max_spin_deg: Mapped[float | None] = mapped_column(Float)
    options: Mapped[JsonObject] = mapped_column(JSON)
    poses: Mapped[JsonArray] = mapped_column(JSON)
    #: One entry per pose, in order: {"source": app.words.TouchOrigin, "read_at", ...}.
    touches: Mapped[JsonArray] = mapped_column(JSON, default=list)
    status: Mapped[SessionStatus] = mapped_column(String(20), default="open")
    calibration_id: Mapped[str | None] = mapped_column(ForeignKey("calibrations.id"))
    #: the frame calibration a frame session's finish stored
    frame_calibration_id: Mapped[str | None] = mapped_column(ForeignKey("frame_calibrations.id"))
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    updated_at: Mapped[datetime] = mapped_column(default=utcnow)
    created_by: Mapped[str] = mapped_column(String(200))


class RobotController(Base):
    """How to reach a robot's controller. The password is stored encrypted
    (app.security.secretbox)."""

    __tablename__ = "robot_controllers"

    robot_id: Mapped[str] = mapped_column(ForeignKey("robots.id"), primary_key=True)
    protocol: Mapped[ProtocolName] = mapped_column(String(20))
    host: Mapped[str] = mapped_column(String(253))
    #: a single-service protocol's port; null for one of several services (`ports`)
    port: Mapped[int | None] = mapped_column(Integer)
    #: a protocol of several services: {service: port}, defaults filled in; else null
    ports: Mapped[dict[str, int] | None] = mapped_column(JSON)
    username: Mapped[str | None] = mapped_column(String(200))
    password_encrypted: Mapped[str | None] = mapped_column(Text)
    timeout_s: Mapped[float] = mapped_column(Float)
    tls_verify: Mapped[bool] = mapped_column(Boolean)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    updated_at: Mapped[datetime] = mapped_column(default=utcnow)


class DeploymentColumns:
    """A deployment's columns, for every subject's deployments table alike (the one shape
    app.services.controllers reads: tests/services/lifecycle/test_subject.py); each table adds
    the column naming its subject."""

    id: Mapped[int] = mapped_column(AutoId, primary_key=True, autoincrement=True)
    robot_id: Mapped[str] = mapped_column(String(36))
    version: Mapped[int] = mapped_column(Integer)
    protocol: Mapped[ProtocolName] = mapped_column(String(20))
    target: Mapped[str] = mapped_column(String(300))
    status: Mapped[DeploymentStatus] = mapped_column(String(20))
    #: stored (the controller keeps it) | live (only for the running program), by protocol
    scope: Mapped[DeploymentScope] = mapped_column(String(10))
    previous: Mapped[JsonObject | None] = mapped_column(JSON)
    read_back: Mapped[JsonObject | None] = mapped_column(JSON)
    deviation_mm: Mapped[float | None] = mapped_column(Float)
    deviation_deg: Mapped[float | None] = mapped_column(Float)
    error: Mapped[JsonObject | None] = mapped_column(JSON)
    #: the person's own words for deploying (the request's `reason`), when given
    reason: Mapped[str | None] = mapped_column(String(500))
    #: an `unverified` one: what the next reconcile round found the controller holding
    #: {"at", "holds": app.words.SettledHolds, "frame"}; null until then
    settled: Mapped[JsonObject | None] = mapped_column(JSON)
    actor: Mapped[str] = mapped_column(String(200))
    created_at: Mapped[datetime] = mapped_column(default=utcnow)


class StateColumns:
    """A controller state's columns, for every subject's states table alike (the subject's
    key, its primary key, is the table's own)."""

    robot_id: Mapped[str] = mapped_column(String(36), index=True)
    state: Mapped[ToolState] = mapped_column(String(20))
    since: Mapped[datetime] = mapped_column()
    checked_at: Mapped[datetime] = mapped_column()
    target: Mapped[str | None] = mapped_column(String(300))
    deviation_mm: Mapped[float | None] = mapped_column(Float)
    deviation_deg: Mapped[float | None] = mapped_column(Float)
    controller: Mapped[JsonObject | None] = mapped_column(JSON)
    active_version: Mapped[int | None] = mapped_column(Integer)
    error: Mapped[str | None] = mapped_column(Text)


class Deployment(DeploymentColumns, Base):
    """One attempt to write a tool's active version into its controller, verified or not."""

    __tablename__ = "deployments"
    __table_args__ = (
        Index("ix_deployments_tool_seq", "tool_id", "id"),
        # a live-TCP robot's last deployment (app.services.controllers.reconcile.live_scope)
        Index("ix_deployments_robot_seq", "robot_id", "id"),
    )

    tool_id: Mapped[str] = mapped_column(ForeignKey("tools.id"))


class ToolControllerState(StateColumns, Base):
    """What the last reconcile found in the controller for a tool, and since when."""

    __tablename__ = "tool_controller_states"

    tool_id: Mapped[str] = mapped_column(ForeignKey("tools.id"), primary_key=True)


class FrameDeployment(DeploymentColumns, Base):
    """One attempt to write a frame's active version into its controller, verified or not."""

    __tablename__ = "frame_deployments"
    __table_args__ = (
        Index("ix_frame_deployments_frame_seq", "frame_id", "id"),
        Index("ix_frame_deployments_robot_seq", "robot_id", "id"),
    )

    frame_id: Mapped[str] = mapped_column(ForeignKey("frames.id"))


class FrameControllerState(StateColumns, Base):
    """What the last reconcile found in the controller for a frame, and since when."""

    __tablename__ = "frame_controller_states"

    frame_id: Mapped[str] = mapped_column(ForeignKey("frames.id"), primary_key=True)


def controller_state_models() -> list[type[StateColumns]]:
    """Every subject's controller-state model (each of StateColumns): what a controller was
    found holding, which is forgotten with the controller."""
    return [
        mapper.class_ for mapper in Base.registry.mappers if issubclass(mapper.class_, StateColumns)
    ]


class RobotLiveTool(Base):
    """The tool frame a robot moved by when the last reconcile round read it (contract
    v1.3 LiveTool), and since when it moves by that one. `read` is False when the controller
    did not say (its interface names no tool a program moves by), its connector cannot read a
    pose yet, or the read failed (`error`)."""

    __tablename__ = "robot_live_tools"

    robot_id: Mapped[str] = mapped_column(ForeignKey("robots.id"), primary_key=True)
    read: Mapped[bool] = mapped_column(Boolean)
    number: Mapped[int | None] = mapped_column(Integer)
    frame: Mapped[JsonObject | None] = mapped_column(JSON)
    since: Mapped[datetime] = mapped_column()
    checked_at: Mapped[datetime] = mapped_column()
    error: Mapped[str | None] = mapped_column(Text)
    #: the frame is the bare flange (tool 0, a null tool, a zero TCP offset:
    #: app.services.robots.live_tool.bare_flange): no tool is selected, which is no unknown TCP
    flange: Mapped[bool] = mapped_column(Boolean, default=False, server_default=false())


class RobotLiveFrame(Base):
    """The frame a robot moved in when the last reconcile round read it (contract v1.4,
    "Frames at the controller": its number, name and value where the controller says, the
    connector's LiveFrame), beside its live tool (robot_live_tools), and the version of one
    of its frames that equals it (`frame_id`, `version`; none: an unknown frame). `read` is
    False when the controller did not say or the read failed."""

    __tablename__ = "robot_live_frames"

    robot_id: Mapped[str] = mapped_column(ForeignKey("robots.id"), primary_key=True)
    read: Mapped[bool] = mapped_column(Boolean)
    number: Mapped[int | None] = mapped_column(Integer)
    name: Mapped[str | None] = mapped_column(Text)
    frame: Mapped[JsonObject | None] = mapped_column(JSON)
    frame_id: Mapped[str | None] = mapped_column(String(36))
    version: Mapped[int | None] = mapped_column(Integer)
    since: Mapped[datetime] = mapped_column()
    checked_at: Mapped[datetime] = mapped_column()


class WatchLease(Base):
    """Which instance reads a robot's controller this round (PostgreSQL, several instances
    sharing the watcher: app.services.controllers.leases). A robot is claimed when `due_at`
    has come and no lease holds it (`leased_until` past or null); the claim moves `due_at`
    one interval on, and the holder renews `leased_until` while its read is in flight."""

    __tablename__ = "watch_leases"

    robot_id: Mapped[str] = mapped_column(
        ForeignKey("robots.id", ondelete="CASCADE"), primary_key=True
    )
    holder: Mapped[str | None] = mapped_column(String(100))
    due_at: Mapped[datetime] = mapped_column(index=True)
    leased_until: Mapped[datetime | None] = mapped_column()


class WatcherSeen(Base):
    """An instance whose watcher shares the rounds, and when it last said so: robots are
    shared out among the ones seen within the last few claims."""

    __tablename__ = "watchers"

    holder: Mapped[str] = mapped_column(String(100), primary_key=True)
    seen_at: Mapped[datetime] = mapped_column()


class RobotLiveMatch(Base):
    """A version of one of the robot's tools equal to the frame it moved by at the last read
    (LiveTool.matches; the active flag is the tool's own, read when shown). A table, not a
    JSON list, so that the fleet's attention rules are index seeks in SQL."""

    __tablename__ = "robot_live_matches"

    robot_id: Mapped[str] = mapped_column(ForeignKey("robot_live_tools.robot_id"), primary_key=True)
    tool_id: Mapped[str] = mapped_column(ForeignKey("tools.id"), primary_key=True)
    version: Mapped[int] = mapped_column(Integer, primary_key=True)


class OutboxMessage(Base):
    """A change a consumer of the plant must see (MQTT, OPC UA), written in the transaction
    of the change by app.services.audit.outbox and read by `tcpcal publish` (app.publish).

    `id` orders the messages as their transactions committed (app.services.audit.outbox says how);
    `delivered_at` is set once every sink acknowledged the message, and delivered rows are
    pruned by the publisher.
    """

    __tablename__ = "outbox"
    __table_args__ = (
        # The publisher's drain: undelivered rows in id order, and the oldest one's age.
        Index(
            "ix_outbox_undelivered",
            "id",
            sqlite_where=text("delivered_at IS NULL"),
            postgresql_where=text("delivered_at IS NULL"),
        ),
        Index("ix_outbox_delivered_at", "delivered_at"),
    )

    id: Mapped[int] = mapped_column(AutoId, primary_key=True, autoincrement=True)
    created_at: Mapped[datetime] = mapped_column(default=utcnow)
    action: Mapped[AuditAction] = mapped_column(String(60))
    robot_id: Mapped[str | None] = mapped_column(String(36))
    tool_id: Mapped[str | None] = mapped_column(String(36))
    frame_id: Mapped[str | None] = mapped_column(String(36))
    #: The event as published: action, tool_id, robot_id, version, actor, at, request_id.
    payload: Mapped[JsonObject] = mapped_column(JSON)
    delivered_at: Mapped[datetime | None] = mapped_column()
