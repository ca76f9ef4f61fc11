"""A robot's controller connection, deployments to it and what a reconcile found."""

from __future__ import annotations

from typing import Annotated, get_args

from pydantic import BaseModel, BeforeValidator, Field, JsonValue, SecretStr, create_model

from app.schemas.common import Reason, ShortText, StoredWord, StrictModel, Timestamp, json_integer
from app.vendors.abb.symbol import SYMBOL_PATTERN
from app.vendors.registry import (
    ACTIVE_TOOLS,
    DEFAULT_PORTS,
    LIVE_MAKER_OR,
    LIVE_MAKERS,
    LIVE_TOOL_UNSAID,
    LIVE_TOOL_UNSAID_WHY,
    PENDANT_FORMATS,
    SERVICE_PORTS,
    STORED_MAKERS,
    SYMBOL_MAKERS,
    USERNAMES,
    USERNAMES_SENT,
    WIRE_PROTOCOLS,
)
from app.words import (
    DeploymentScope,
    DeploymentStatus,
    PoseFormat,
    ProtocolName,
    RobotState,
    SettledHolds,
    ToolState,
)

Host = Annotated[
    str,
    Field(
        min_length=1,
        max_length=253,
        description="a host name (RFC 1123 labels) or an IPv4/IPv6 address",
        examples=["192.168.1.20", "kr16-cell12.plant.local"],
    ),
]
Port = Annotated[
    int,
    Field(ge=1, le=65535, description="TCP port; default: the protocol's"),
    BeforeValidator(json_integer),
]
#: What `controller_symbol` is (a tool's create, update and view, and the symbol's type).
SYMBOL_DESCRIPTION = f'{SYMBOL_MAKERS}: the PERS tooldata of this tool, "TASK/MODULE/SYMBOL"'
ControllerSymbol = Annotated[
    str,
    Field(
        max_length=100,
        pattern=SYMBOL_PATTERN.pattern,
        description=SYMBOL_DESCRIPTION,
        examples=["T_ROB1/user/tTorch"],
    ),
]
ServiceName = Annotated[
    str,
    Field(
        min_length=1,
        max_length=40,
        description="a service of the protocol: "
        + "; ".join(f"{name} {' | '.join(services)}" for name, services in SERVICE_PORTS.items()),
    ),
]
PROTOCOL_DESCRIPTION = "; ".join(
    [
        *(f"{name}: default port {port}" for name, port in DEFAULT_PORTS.items()),
        *(
            f"{name}: default ports "
            + ", ".join(f"{service} {port}" for service, port in services.items())
            for name, services in SERVICE_PORTS.items()
        ),
    ]
)
DEFAULT_PORTS_BY_PROTOCOL: dict[str, JsonValue] = {
    **{name: {"port": port} for name, port in DEFAULT_PORTS.items()},
    **{name: dict(services) for name, services in SERVICE_PORTS.items()},
}
PORTS_DESCRIPTION = (
    f"a protocol of several services ({', '.join(SERVICE_PORTS)}), in place of `port`: the "
    "port of each service, each defaulting to the real one ("
    + "; ".join(
        f"{name} "
        + ", ".join(f"{service} {port}" for service, port in services.items())
        + (" (UDP)" if WIRE_PROTOCOLS[name].udp else "")
        for name, services in SERVICE_PORTS.items()
    )
    + ")"
)


class ControllerIn(StrictModel):
    """How to reach a robot's controller. `password` is write-only (stored encrypted); left
    out, the stored one is kept; null removes it."""

    protocol: ProtocolName = Field(
        description=PROTOCOL_DESCRIPTION,
        # The same defaults, for a form (the console's) to read: {protocol: {"port": N}} or
        # {protocol: {service: N, ...}} for a protocol of several services.
        json_schema_extra={"x-default-ports": DEFAULT_PORTS_BY_PROTOCOL},
    )
    host: Host = Field(description="the controller's host name or IP address")
    port: Port | None = Field(
        default=None,
        description="a single-service protocol's TCP port; default: the protocol's. A "
        "protocol of several services takes `ports` instead",
    )
    ports: Annotated[dict[ServiceName, Port], Field(max_length=8)] | None = Field(
        default=None, description=PORTS_DESCRIPTION
    )
    username: ShortText | None = Field(default=None, description=USERNAMES_SENT)
    password: Annotated[SecretStr | None, Field(max_length=200)] = Field(
        default=None,
        description="write-only, stored encrypted under TCPCAL_SECRET_KEY; left out: the "
        "stored one is kept; null: removed",
    )
    timeout_s: float = Field(
        default=5.0,
        ge=0.1,
        le=60,
        allow_inf_nan=False,
        strict=True,
        description="connect and read timeout",
    )
    tls_verify: bool = Field(
        default=True, strict=True, description="abb_rws2: check the controller's certificate"
    )


class Controller(BaseModel):
    robot_id: str
    protocol: StoredWord[ProtocolName] = Field(description=" | ".join(get_args(ProtocolName)))
    host: str = Field(description="the controller's host name or IP address")
    port: int | None = Field(
        description="the port of a single-service protocol; null for a protocol of several "
        "services (see `ports`)"
    )
    ports: dict[str, int] | None = Field(
        default=None,
        description="a protocol of several services: the port each service is reached on, "
        "defaults filled in; null for a single-service protocol",
    )
    username: str | None = Field(description=USERNAMES)
    scope: DeploymentScope = Field(
        default="stored",
        description="where a deployment to it holds: stored (the controller keeps it) or live "
        f"({LIVE_MAKERS}: only for the running program; the next program start sets "
        "its own TCP)",
    )
    has_password: bool = Field(description="whether a password is stored (never served)")
    pose_format: StoredWord[PoseFormat] | None = Field(
        description="the pose format the controller's pendant shows a flange pose in, its "
        "maker's ("
        + "; ".join(f"{protocol}: {fmt}" for protocol, fmt in PENDANT_FORMATS.items())
        + "): what a session captured from it is typed in unless told otherwise; null for a "
        "protocol this tcpcal does not know",
    )
    timeout_s: float = Field(description="deadline of each connect and read, s")
    tls_verify: bool = Field(description="abb_rws2: whether the certificate is checked")
    created_at: Timestamp
    updated_at: Timestamp


class Frame(BaseModel):
    """A tool frame in the flange frame: position (mm) and orientation [w, x, y, z]."""

    position_mm: list[float] = Field(description="x, y, z of the TCP in the flange frame, mm")
    quaternion: list[float] = Field(description="unit quaternion [w, x, y, z]")


class DeploymentError(BaseModel):
    type: str = Field(description="the problem kind: controller-unreachable | -refused | -mismatch")
    detail: str = Field(description="what happened, in a sentence")
    controller_message: str | None = Field(
        default=None, description="the controller's own words when it refused"
    )


class DeploymentSettled(BaseModel):
    """What the reconcile round after an `unverified` deployment found the controller holding."""

    at: Timestamp = Field(description="when the round read the controller")
    holds: SettledHolds = Field(
        description="written: the deployed version; previous: the frame it held before the "
        "deployment; other: neither"
    )
    frame: Frame = Field(description="what the controller held")


class Deployment(BaseModel):
    id: str
    tool_id: str
    robot_id: str
    version: int = Field(description="the version written (the active one at the time)")
    protocol: StoredWord[ProtocolName] = Field(description="the controller's protocol")
    target: str = Field(description='where it was written: "$TOOL_DATA[3]", "UTOOL[3]", a symbol')
    scope: DeploymentScope = Field(
        description=f"stored: the controller keeps it ({STORED_MAKERS}); live: it "
        f"holds only for the running program ({LIVE_MAKERS}): the next program start "
        "sets its own TCP, and the reconcile rounds then show what the robot moves by"
    )
    status: DeploymentStatus = Field(
        description="verified (read back as written) | not_written (failed before the write "
        "was sent: the controller holds what it held) | unverified (failed after the write was "
        "sent: it may hold either frame; `settled` tells) | mismatch (read back otherwise)"
    )
    previous: Frame | None = Field(description="what the controller held before; null if unread")
    read_back: Frame | None = Field(description="what the controller held after the write")
    deviation_mm: float | None = Field(description="read back vs written: distance, mm")
    deviation_deg: float | None = Field(description="read back vs written: angle, deg")
    error: DeploymentError | None = Field(description="why it failed; null when verified")
    reason: str | None = Field(default=None, description="why it was deployed, if given")
    settled: DeploymentSettled | None = Field(
        default=None,
        description="unverified: what the next reconcile round found the controller holding; "
        "null until then (and for every other status)",
    )
    actor: str = Field(description="name of the API key that deployed")
    created_at: Timestamp


#: A frame's deployment (POST /v1/frames/{frame_id}/deployments): a tool's `Deployment`, field
#: for field, the frame named by `frame_id`; `previous`, `read_back` and `settled` hold poses in
#: the robot's base frame.
FrameDeployment: type[BaseModel] = create_model(
    "FrameDeployment",
    **{  # type: ignore[call-overload]
        ("frame_id" if name == "tool_id" else name): (field.annotation, field)
        for name, field in Deployment.model_fields.items()
    },
)


class DeploymentIn(StrictModel):
    """Deploys the tool's active version (and its load); optionally says why."""

    reason: Reason | None = Field(
        default=None,
        description="why it is deployed (1-500 characters); kept with the deployment and in "
        "the audit trail",
    )


class ActiveFrame(Frame):
    version: int = Field(description="the active version")


#: What a reconcile answer says alike of every subject it judged (ReconciledTool,
#: ReconciledFrame), field by field: a shared base would put these fields first, and the
#: subject's key is each answer's first (openapi.json's `required`, the answers' key order).
ReconciledActive = Annotated[
    ActiveFrame | None, Field(description="the active version; null without one")
]
ReconciledDeviationMm = Annotated[
    float | None, Field(description="controller vs active: distance, mm")
]
ReconciledDeviationDeg = Annotated[
    float | None, Field(description="controller vs active: angle, deg")
]
ReconciledError = Annotated[str | None, Field(description="why the controller could not be read")]


class ReconciledTool(BaseModel):
    tool_id: str
    target: str | None = Field(description="where the tool lives in the controller")
    state: ToolState = Field(
        description="in_sync | drifted | no_active_version | unreachable | not_live (a robot "
        f"with one live TCP, {LIVE_MAKER_OR}: another tool was deployed to it last, and "
        "only that one is judged)"
    )
    controller: Frame | None = Field(description="what the controller holds; null if unread")
    active: ReconciledActive
    deviation_mm: ReconciledDeviationMm
    deviation_deg: ReconciledDeviationDeg
    since: Timestamp = Field(description="when the tool first entered its present state")
    error: ReconciledError = None


class NotAddressable(BaseModel):
    tool_id: str
    reason: str = Field(description="which field to set so the controller can address it")


class ReconciledFrame(BaseModel):
    frame_id: str
    target: str | None = Field(description="where the frame lives in the controller")
    state: ToolState = Field(
        description="in_sync | drifted | no_active_version | unreachable | not_live (a robot "
        "whose controller holds one live frame, a `live` scope: another frame was deployed "
        "to it last, and only that one is judged)"
    )
    controller: Frame | None = Field(
        description="what the controller holds, in the robot's base frame; null if unread"
    )
    active: ReconciledActive
    deviation_mm: ReconciledDeviationMm
    deviation_deg: ReconciledDeviationDeg
    since: Timestamp = Field(description="when the frame first entered its present state")
    error: ReconciledError = None


class FrameNotAddressable(BaseModel):
    frame_id: str
    reason: str = Field(
        description="which field to set so the controller can address it, or why no remote "
        "interface of the controller reads it"
    )


class Reconciliation(BaseModel):
    robot_id: str
    checked_at: Timestamp
    state: RobotState = Field(
        description="the worst of its tools' states; unreachable when the controller could "
        "not be reached"
    )
    scope: DeploymentScope = Field(
        default="stored",
        description="stored: every tool is judged against what the controller keeps for it; "
        f"live ({LIVE_MAKERS}): the robot has one live TCP, the tool deployed to it last "
        "is judged and its other tools are not_live (each unreachable when the controller "
        "could not be reached)",
    )
    tools: list[ReconciledTool] = Field(description="every live tool the controller addresses")
    not_addressable: list[NotAddressable] = Field(
        default_factory=list,
        description="live tools left out: no slot or controller_symbol this protocol can use",
    )
    frames: list[ReconciledFrame] = Field(
        default_factory=list,
        description="every live frame the controller addresses, read in the same round and "
        "connection as the tools",
    )
    frames_not_addressable: list[FrameNotAddressable] = Field(
        default_factory=list,
        description="live frames left out: no slot or controller_symbol this protocol can "
        "use, or a controller no remote interface of which reads frames",
    )
    live_tool: LiveToolOut | None = Field(
        default=None,
        description="the TCP the robot moves by, as this reconcile read it (number and frame "
        f"null where the controller does not say, as {LIVE_TOOL_UNSAID}); null when it could "
        "not be read",
    )
    live_tool_error: str | None = Field(
        default=None, description="why the live tool could not be read"
    )


class LiveToolMatch(BaseModel):
    tool_id: str
    version: int
    active: bool = Field(description="whether this version is the tool's active one")


class LiveToolOut(BaseModel):
    """The TCP the robot moves by right now, as its controller reports it."""

    number: int | None = Field(
        description=f"the controller's tool number ({ACTIVE_TOOLS}); "
        f"null where the controller does not say ({LIVE_TOOL_UNSAID})"
    )
    frame: Frame | None = Field(
        description="the live tool frame in the flange frame; null where the controller "
        f"does not say ({LIVE_TOOL_UNSAID_WHY})"
    )
    matches: list[LiveToolMatch] = Field(
        description="every version of this robot's tools equal to the live frame within "
        "0.01 mm and 0.01 deg"
    )


class ControllerPose(BaseModel):
    """Where the robot's flange is, read from its controller twice and found still."""

    pose: list[float] | list[list[float]] = Field(
        description="the flange in the robot's base frame, in `format`"
    )
    format: StoredWord[PoseFormat] = Field(description="the pose format of `pose`")
    joints_deg: list[float] | None = Field(description="the joint angles, deg; null if unread")
    read_at: Timestamp = Field(description="when the second, confirming read ended")
    protocol: StoredWord[ProtocolName] = Field(description="the controller's protocol")
    still: bool = Field(description="true: two reads 100 ms apart agreed (else 409)")
    live_tool: LiveToolOut = Field(description="the TCP the robot moves by right now")
    readings: dict[str, str] = Field(description="every value read, as the controller printed it")
