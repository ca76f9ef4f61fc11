"""Field types shared by every request and response model."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Generic, Literal, TypeVar

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, PlainSerializer

#: A float that refuses NaN and +-Infinity at the door (422 /non-finite).
FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegativeFloat = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Vec3 = Annotated[list[FiniteFloat], Field(min_length=3, max_length=3)]
Quaternion = Annotated[
    list[FiniteFloat], Field(min_length=4, max_length=4, description="unit quaternion [w, x, y, z]")
]
# No control characters in names (PostgreSQL refuses NUL; a newline would break exports).
Name = Annotated[
    str,
    Field(
        min_length=1,
        max_length=200,
        pattern=r"^[^\s\x00-\x1f\x7f]([^\x00-\x1f\x7f]*[^\s\x00-\x1f\x7f])?$",
    ),
]
ShortText = Annotated[str, Field(max_length=200, pattern=r"^[^\x00-\x1f\x7f]*$")]
LongText = Annotated[str, Field(max_length=4000, pattern=r"^[^\x00-\x08\x0b\x0c\x0e-\x1f\x7f]*$")]
#: A resource id as this service issues them (UUIDs); anything else cannot exist.
ID_PATTERN = r"^[A-Za-z0-9_-]{1,64}$"
ResourceId = Annotated[str, Field(pattern=ID_PATTERN, description="resource id")]

#: One pose in the submission's format: a flat list of numbers, or a 4x4 nested matrix.
Pose = list[FiniteFloat] | list[Annotated[list[FiniteFloat], Field(max_length=4)]]
MAX_POSES = 1000
Poses = Annotated[list[Pose], Field(max_length=MAX_POSES)]

PoseFormat = Literal[
    "matrix",
    "xyz_wxyz",
    "xyz_xyzw",
    "kuka_abc",
    "fanuc_wpr",
    "yaskawa_rxyz",
    "techman_rxyz",
    "ur_rotvec",
    "joints",
]
ControllerFormat = Literal["kuka", "abb", "fanuc", "ur", "yaskawa", "techman"]


def _rfc3339(value: datetime) -> str:
    return value.isoformat().replace("+00:00", "Z")


def _must_be_aware(value: datetime) -> datetime:
    if value.tzinfo is None:
        raise ValueError("timestamp must carry a time zone")
    return value


Timestamp = Annotated[
    datetime,
    AfterValidator(_must_be_aware),
    PlainSerializer(_rfc3339, return_type=str, when_used="json"),
]


class Units(BaseModel):
    """Overrides of a pose format's default units."""

    model_config = ConfigDict(extra="forbid")
    length: Literal["mm", "m"] | None = None
    angle: Literal["deg", "rad"] | None = None


class StrictModel(BaseModel):
    """Request bodies: unknown fields are refused, so a typo is named instead of ignored."""

    model_config = ConfigDict(extra="forbid")


T = TypeVar("T")


class Page(BaseModel, Generic[T]):
    """One page of a list; pass next_cursor back as ?cursor= for the next."""

    items: list[T]
    next_cursor: str | None = None
