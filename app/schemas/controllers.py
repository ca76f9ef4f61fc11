"""A robot's controller connection, deployments to it and what a reconcile found."""

from __future__ import annotations

import ipaddress
import re
from typing import Annotated, Literal

from pydantic import AfterValidator, BaseModel, BeforeValidator, Field, SecretStr

from app.controllers.base import ABB_SYMBOL_PATTERN, DEFAULT_PORTS, ProtocolName
from app.schemas.common import ShortText, StrictModel, Timestamp, json_integer

_LABEL = re.compile(r"^(?!-)[A-Za-z0-9-]{1,63}(?<!-)$")


def _host(value: str) -> str:
    """A host name (RFC 1123 labels) or an IPv4/IPv6 address, as a controller is reached."""
    try:
        ipaddress.ip_address(value)
        return value
    except ValueError:
        pass
    labels = value.rstrip(".").split(".")
    if not value or not all(_LABEL.match(label) for label in labels):
        raise ValueError(
            "must be a host name (letters, digits and -, in dot-separated labels of at most 63) "
            "or an IPv4/IPv6 address"
        )
    return value


Host = Annotated[
    str,
    Field(min_length=1, max_length=253, examples=["192.168.1.20", "kr16-cell12.plant.local"]),
    AfterValidator(_host),
]
Port = Annotated[
    int,
    Field(ge=1, le=65535, description="TCP port; default: the protocol's"),
    BeforeValidator(json_integer),
]
ControllerSymbol = Annotated[
    str,
    Field(
        max_length=100,
        pattern=ABB_SYMBOL_PATTERN.pattern,
        description='ABB: the PERS tooldata of this tool, "TASK/MODULE/SYMBOL"',
        examples=["T_ROB1/user/tTorch"],
    ),
]
PROTOCOL_DESCRIPTION = "; ".join(
    f"{name}: default port {port}" for name, port in DEFAULT_PORTS.items()
)


class ControllerIn(StrictModel):
    """How to reach a robot's controller. `password` is write-only (stored encrypted); left
    out, the stored one is kept; null removes it."""

    protocol: ProtocolName = Field(description=PROTOCOL_DESCRIPTION)
    host: Host
    port: Port | None = None
    username: ShortText | None = None
    password: Annotated[SecretStr | None, Field(max_length=200)] = None
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
    protocol: str
    host: str
    port: int
    username: str | None
    has_password: bool
    timeout_s: float
    tls_verify: bool
    created_at: Timestamp
    updated_at: Timestamp


class Frame(BaseModel):
    """A tool frame in the flange frame: position (mm) and orientation [w, x, y, z]."""

    position_mm: list[float]
    quaternion: list[float]


class DeploymentError(BaseModel):
    type: str
    detail: str
    controller_message: str | None = None


DeploymentStatus = Literal["verified", "failed", "mismatch"]


class Deployment(BaseModel):
    id: str
    tool_id: str
    robot_id: str
    version: int
    protocol: str
    target: str
    status: DeploymentStatus
    previous: Frame | None
    read_back: Frame | None
    deviation_mm: float | None
    deviation_deg: float | None
    error: DeploymentError | None
    actor: str
    created_at: Timestamp


class DeploymentIn(StrictModel):
    """Deploys the tool's active version (and its load); nothing to choose."""


ToolState = Literal["in_sync", "drifted", "no_active_version", "unreachable"]
RobotState = Literal["in_sync", "drifted", "unreachable"]


class ActiveFrame(Frame):
    version: int


class ReconciledTool(BaseModel):
    tool_id: str
    target: str | None
    state: ToolState
    controller: Frame | None
    active: ActiveFrame | None
    deviation_mm: float | None
    deviation_deg: float | None
    since: Timestamp
    error: str | None = Field(default=None, description="why the controller could not be read")


class NotAddressable(BaseModel):
    tool_id: str
    reason: str


class Reconciliation(BaseModel):
    robot_id: str
    checked_at: Timestamp
    state: RobotState
    tools: list[ReconciledTool]
    not_addressable: list[NotAddressable] = Field(
        default_factory=list,
        description="live tools left out: no slot or controller_symbol this protocol can use",
    )
