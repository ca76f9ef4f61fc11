"""Field types shared by every request and response model."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Generic, Literal, TypeVar

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    PlainSerializer,
    PlainValidator,
    StringConstraints,
    WithJsonSchema,
)

from app.jsontypes import JsonObject
from app.solvers.noise_limits import MAX_TOUCH_NOISE_MM, MIN_TOUCH_NOISE_MM
from app.words import Angle, Length

#: Whether a calibration (or a guided session's finish) activates its TCP.
Activate = Literal["auto", "always", "never"]


def _served_as_stored(value: object) -> str:
    if not isinstance(value, str):
        raise ValueError("a stored word is a string")
    return value


_Word = TypeVar("_Word", bound=str)
#: A stored word an answer serves, as `StoredWord[TheLiteral]` (a Literal of app.words, a
#: protocol, a pose format): typed as its Literal, so that mypy holds a service to serving
#: one of its words, and served and documented as the string the row holds, as it always
#: was. Like the column (`Mapped[TheLiteral]`, not checked as it is read), it is not checked
#: again on the way out: a history (the audit trail, the versions, the activations) stays
#: readable whatever words an older or a newer version wrote, and these lists grow (a new
#: maker's protocol, a new audit action) without a client generated from the spec refusing
#: a word it does not know yet. A request takes the Literal itself (an enum: a word the
#: server does not know is a 422).
StoredWord = Annotated[_Word, PlainValidator(_served_as_stored), WithJsonSchema({"type": "string"})]

#: A number that refuses NaN and +-Infinity at the door (422 /non-finite), and is strict: a
#: boolean or a string is refused, not read as 0/1 or parsed (the spec says "number").
FiniteFloat = Annotated[float, Field(allow_inf_nan=False, strict=True)]
PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False, strict=True)]
NonNegativeFloat = Annotated[float, Field(ge=0, allow_inf_nan=False, strict=True)]


def json_integer(value: object) -> object:
    """An integer as JSON Schema has it: 3 and 3.0 are integers; true and "3" are not. Use as
    the last item of an Annotated, after the Field with its bounds (so that the bounds stay
    JSON Schema's minimum/maximum)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError("must be an integer (a JSON number), not a boolean or a string")
    return value


#: A touch noise figure (1-sigma per axis, mm) in the range the solvers accept.
TouchNoise = Annotated[
    float, Field(ge=MIN_TOUCH_NOISE_MM, le=MAX_TOUCH_NOISE_MM, allow_inf_nan=False, strict=True)
]
Vec3 = Annotated[list[FiniteFloat], Field(min_length=3, max_length=3)]
Quaternion = Annotated[
    list[FiniteFloat], Field(min_length=4, max_length=4, description="unit quaternion [w, x, y, z]")
]
# No control characters in names (PostgreSQL refuses NUL; a newline would break exports),
# C1 ones included, and no space at either end. Spelled without \s, whose meaning differs
# between Python's and JSON Schema's (ECMA) regular expressions.
Name = Annotated[
    str,
    Field(
        min_length=1,
        max_length=200,
        pattern=r"^[^\x00-\x20\x7f-\x9f]([^\x00-\x1f\x7f-\x9f]*[^\x00-\x20\x7f-\x9f])?$",
    ),
]
#: Text without control characters: a short stored word, and every text filter of a list
#: (PostgreSQL refuses NUL in a text parameter, and no stored name holds a control character).
NO_CONTROL_PATTERN = r"^[^\x00-\x1f\x7f]*$"
ShortText = Annotated[str, Field(max_length=200, pattern=NO_CONTROL_PATTERN)]
LongText = Annotated[str, Field(max_length=4000, pattern=r"^[^\x00-\x08\x0b\x0c\x0e-\x1f\x7f]*$")]
#: A person's reason for an activation, a rollback or a deployment: 1-500 characters once
#: trimmed, no control characters but tab and line breaks.
Reason = Annotated[
    str,
    StringConstraints(
        strip_whitespace=True,
        min_length=1,
        max_length=500,
        pattern=r"^[^\x00-\x08\x0b\x0c\x0e-\x1f\x7f]*$",
    ),
]
#: A resource id as this service issues them (UUIDs); anything else cannot exist.
ID_PATTERN = r"^[A-Za-z0-9_-]{1,64}$"
ResourceId = Annotated[str, Field(pattern=ID_PATTERN, description="resource id")]

#: One pose in the submission's format: a flat list of numbers, or a 4x4 nested matrix.
Pose = list[FiniteFloat] | list[Annotated[list[FiniteFloat], Field(max_length=4)]]
MAX_POSES = 1000
Poses = Annotated[list[Pose], Field(max_length=MAX_POSES)]


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
    length: Length | None = None
    angle: Angle | None = None


class StrictModel(BaseModel):
    """Request bodies: unknown fields are refused, so a typo is named instead of ignored."""

    model_config = ConfigDict(extra="forbid")


T = TypeVar("T")


class Page(BaseModel, Generic[T]):
    """One page of a list; pass next_cursor back as ?cursor= for the next."""

    items: list[T]
    next_cursor: str | None = None


def not_both(*pairs: tuple[str, str]) -> JsonObject:
    """`json_schema_extra` for a model where each pair of fields excludes each other (either,
    or neither, but never both given non-null), so the spec says what the validator enforces."""
    return {
        "allOf": [
            {
                "not": {
                    "required": [a, b],
                    "properties": {a: {"not": {"type": "null"}}, b: {"not": {"type": "null"}}},
                }
            }
            for a, b in pairs
        ]
    }


def one_of(*alternatives: tuple[tuple[str, ...], tuple[str, ...]]) -> JsonObject:
    """`json_schema_extra` for a model whose fields come in exclusive groups: each alternative
    is (fields that must be given, fields that must be absent or null). The spec then says
    what the model's validator enforces, so a generated body the schema allows is accepted."""
    return {
        "oneOf": [
            {
                "required": list(given),
                "properties": {
                    **{f: {"not": {"type": "null"}} for f in given},
                    **{f: {"type": "null"} for f in absent},
                },
            }
            for given, absent in alternatives
        ]
    }
