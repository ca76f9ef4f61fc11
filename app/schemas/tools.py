"""Tools, their tolerance and load, versions and the served TCP."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, BeforeValidator, Field, StrictBool

from app.jsontypes import JsonObject
from app.schemas.common import (
    LongText,
    Name,
    NonNegativeFloat,
    PositiveFloat,
    Quaternion,
    Reason,
    ShortText,
    StoredWord,
    StrictModel,
    Timestamp,
    TouchNoise,
    Vec3,
    json_integer,
)
from app.schemas.controllers import SYMBOL_DESCRIPTION, ControllerSymbol
from app.words import ActivationKind, MethodName, Status

Slot = Annotated[
    int,
    Field(ge=0, le=10_000, description="the controller's tool number"),
    BeforeValidator(json_integer),
]


class Load(StrictModel):
    mass_kg: NonNegativeFloat
    cog_mm: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])


class Tolerance(StrictModel):
    """When a calibration counts as good enough to activate automatically."""

    max_rms_mm: PositiveFloat = 0.5
    max_residual_mm: PositiveFloat = 1.0
    touch_noise_mm: TouchNoise | None = None
    check_mm: PositiveFloat = 1.0
    max_change_mm: PositiveFloat = Field(
        default=5.0,
        description="a result whose TCP lies further than this from the active one is stored "
        'but not activated by "auto"',
    )
    max_correction_mm: PositiveFloat = Field(
        default=2.0,
        description='a re-check (POST /v1/tools/{tool_id}/checks with "correct": '
        '"within_limits") corrects the TCP from its one touch when the deviation exceeds '
        "check_mm and stays within this; beyond it nothing changes and the tool needs "
        "recalibrating",
    )


class ToolCreate(StrictModel):
    name: Name
    slot: Slot | None = None
    serial: ShortText | None = None
    description: LongText | None = None
    load: Load | None = None
    tolerance: Tolerance = Field(default_factory=Tolerance)
    controller_symbol: ControllerSymbol | None = Field(default=None, description=SYMBOL_DESCRIPTION)


class ToolUpdate(StrictModel):
    name: Name | None = None
    slot: Slot | None = None
    serial: ShortText | None = None
    description: LongText | None = None
    load: Load | None = None
    tolerance: Tolerance | None = None
    controller_symbol: ControllerSymbol | None = Field(default=None, description=SYMBOL_DESCRIPTION)


class Tool(BaseModel):
    id: str
    robot_id: str
    name: str
    slot: int | None
    serial: str | None
    description: str | None
    load: Load | None
    tolerance: Tolerance
    controller_symbol: str | None = Field(default=None, description=SYMBOL_DESCRIPTION)
    active_version: int | None
    created_at: Timestamp
    updated_at: Timestamp


class Tcp(BaseModel):
    """A tool frame relative to the flange: position (mm) and orientation [w, x, y, z]."""

    position_mm: Vec3
    quaternion: Quaternion = Field(default_factory=lambda: [1.0, 0.0, 0.0, 0.0])


class Version(BaseModel):
    version: int
    tcp: Tcp
    source: StoredWord[MethodName]
    status: StoredWord[Status]
    calibration_id: str | None
    note: str | None
    created_at: Timestamp
    created_by: str
    active: bool


class ActivationRequest(StrictModel):
    """The optional body of an activation: why, and `force` for an out-of-tolerance version."""

    reason: Reason | None = Field(
        default=None,
        description="why this version goes live (1-500 characters); kept in the activation "
        "history and the audit trail; required with force",
    )
    force: StrictBool = Field(
        default=False,
        description="activate a version stored as out_of_tolerance (needs a reason)",
    )


class RollbackRequest(StrictModel):
    """The optional body of a rollback."""

    reason: Reason | None = Field(
        default=None,
        description="why the tool goes back (1-500 characters); kept in the activation history "
        "and the audit trail",
    )


class VersionList(BaseModel):
    items: list[Version]
    activations: list[ActivationOut] = Field(default_factory=list)


class ActivationOut(BaseModel):
    version: int
    previous_version: int | None
    reason: StoredWord[ActivationKind] = Field(
        description="the kind of activation: explicit, forced (an out-of-tolerance version, "
        "with force), rollback, calibration:auto, calibration:always or check_correction (a "
        "re-check corrected the TCP from one touch)"
    )
    reason_text: str | None = Field(
        default=None, description="the reason the person gave (the request's `reason`), if any"
    )
    activated_at: Timestamp
    activated_by: str


class ControllerText(BaseModel):
    format: str
    text: str
    values: JsonObject


class ActiveTcp(BaseModel):
    tool_id: str
    robot_id: str
    tool_name: str
    slot: int | None
    version: int
    tcp: Tcp
    calibrated_at: Timestamp
    method: StoredWord[MethodName]
    controller: ControllerText | None = None
    controller_error: dict[str, str] | None = Field(
        default=None, description="why this tool has no text in the requested format"
    )


class ToolTable(BaseModel):
    robot_id: str
    items: list[ActiveTcp]
    without_active_version: list[str] = Field(
        default_factory=list, description="ids of tools that have no active TCP"
    )


VersionList.model_rebuild()
