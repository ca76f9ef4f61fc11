"""The JSON bodies the CLI reads from the server: the fields it prints, as TypedDicts.

Named after the server's schemas in openapi/openapi.json (which the app's pydantic models in
app.schemas define); the client declares only the members it reads and imports no model,
so `tcpcal` starts without pydantic's models. A body is typed where `.json()` is taken.
"""

from __future__ import annotations

from typing import Generic, NotRequired, TypedDict, TypeVar

from app.jsontypes import JsonObject

Item = TypeVar("Item")

#: A pose as the server gives one: numbers, or rows of numbers (a matrix).
Pose = list[float | list[float]]


def flat_pose(pose: Pose) -> list[float]:
    """A pose's numbers in one row (a matrix row after row), as a table or a line shows it."""
    return [float(v) for row in pose for v in (row if isinstance(row, list) else [row])]


class Page(TypedDict, Generic[Item]):
    items: list[Item]
    next_cursor: str | None


class Tcp(TypedDict):
    position_mm: list[float]


class Frame(TypedDict):
    position_mm: list[float]
    quaternion: list[float]


class LastCalibration(TypedDict):
    status: str
    rms_mm: float | None


class LastCheck(TypedDict):
    within_tolerance: bool
    verdict: NotRequired[str | None]
    correction_version: NotRequired[int | None]


class FleetController(TypedDict):
    state: str
    checked_at: str
    version: NotRequired[int | None]


class FleetTool(TypedDict):
    id: str
    name: str
    slot: int | None
    robot_name: str
    cell: str | None
    active_version: int | None
    last_calibration: LastCalibration | None
    last_check: LastCheck | None
    attention: list[str]
    controller: NotRequired[FleetController | None]


class MethodInfo(TypedDict):
    name: str
    guided: bool


class FrameMethodInfo(TypedDict):
    name: str
    kinds: list[str]
    touch_fields: dict[str, bool]


class MethodList(TypedDict):
    """GET /v1/methods, the fields the CLI reads: each method's name and which one guides."""

    items: list[MethodInfo]
    frame_methods: list[FrameMethodInfo]


class Quality(TypedDict):
    rms_mm: float | None
    n_poses: int


class Calibration(TypedDict):
    version: int
    status: str
    active: bool
    tcp: Tcp
    quality: Quality
    summary: str
    warnings: list[str]


class Estimate(TypedDict):
    tcp_mm: list[float]
    tcp_sigma_mm: list[float]
    rms_mm: float


class TouchSource(TypedDict):
    index: int
    source: str
    read_at: str | None


class NextTouch(TypedDict):
    tilt_deg: float
    lean_deg: float
    spin_deg: float


class Session(TypedDict):
    id: str
    tool_id: str
    status: str
    format: str
    units: dict[str, str] | None
    calibration_id: str | None
    estimate: Estimate | None
    n_poses: int
    poses: list[Pose]
    touches: list[TouchSource]
    outliers: list[int]
    target_sigma_mm: float
    messages: list[str]
    next_pose: Pose | None
    next_touch: NextTouch | None
    residuals_mm: list[float] | None
    done: bool


class Plan(TypedDict):
    poses: list[Pose]
    n_poses: int
    predicted_tcp_sigma_mm: list[float]
    predicted_sigma_mm: float


class Version(TypedDict):
    version: int
    status: str
    active: bool
    tcp: Tcp
    source: str
    created_by: str
    created_at: str
    note: str | None


class Activation(TypedDict):
    activated_at: str
    version: int
    previous_version: int | None
    reason: str
    reason_text: str | None
    activated_by: str


class VersionList(TypedDict):
    items: list[Version]
    activations: list[Activation]


class Tool(TypedDict):
    name: str
    active_version: int | None


class DeploymentError(TypedDict):
    type: str
    detail: str


class Correction(TypedDict):
    version: int
    previous_version: int
    delta_mm: list[float]
    deployment: Deployment | None


class CheckResult(TypedDict):
    summary: str
    within_tolerance: bool
    verdict: str
    correction: Correction | None


class ReferencePoint(TypedDict):
    id: str
    name: str


class Robot(TypedDict):
    id: str
    name: str
    vendor: str | None


class RobotFrame(TypedDict):
    id: str
    robot_id: str
    name: str
    kind: str
    slot: int | None
    controller_symbol: str | None
    active_version: int | None


class ActiveRobotFrame(TypedDict):
    version: int
    frame: Frame
    method: str
    calibrated_at: str


class FrameNext(TypedDict):
    role: str | None
    takes: str


class FrameSessionTouch(TypedDict):
    index: int
    role: str | None
    nominal_mm: list[float] | None
    source: str
    point_mm: list[float] | None


class FrameSession(TypedDict):
    id: str
    n_touches: int
    touches: list[FrameSessionTouch]
    next_role: str | None
    next: FrameNext | None
    done: bool
    messages: list[str]


class FrameQuality(TypedDict):
    position_sigma_mm: list[float] | None
    angle_sigma_deg: list[float] | None


class FrameCalibration(TypedDict):
    version: int | None
    status: str
    frame: Frame
    quality: FrameQuality
    summary: str


class AuditEvent(TypedDict):
    at: str
    actor: str
    action: str
    tool_id: str | None
    version: int | None
    detail: JsonObject | None


class Deployment(TypedDict):
    id: str
    version: int
    target: str
    status: str
    previous: Frame | None
    read_back: Frame | None
    deviation_mm: float | None
    deviation_deg: float | None
    reason: NotRequired[str | None]
    error: NotRequired[DeploymentError | None]
    scope: NotRequired[str]


class ActiveFrame(Frame):
    version: int


class ReconciledTool(TypedDict):
    tool_id: str
    target: str | None
    state: str
    error: str | None
    since: str
    controller: Frame | None
    active: ActiveFrame | None
    deviation_mm: float | None
    deviation_deg: float | None


class NotAddressable(TypedDict):
    tool_id: str
    reason: str


class Reconciliation(TypedDict):
    robot_id: str
    state: str
    tools: list[ReconciledTool]
    not_addressable: list[NotAddressable]
    scope: NotRequired[str]


class Controller(TypedDict):
    """How the server reaches a robot's controller (GET/PUT /v1/robots/{id}/controller)."""

    protocol: str
    host: str
    port: int | None
    ports: dict[str, int] | None
    username: str | None
    scope: str
    has_password: bool
    pose_format: str | None  # the pendant's, from the server's maker table
    timeout_s: float
    tls_verify: bool
