"""What every calibration method shares: its registry entry, request base, context and outcome.

A method is one module: a request model (a `MethodRequest` with `method: Literal[name]`), a
pure-ish `run(request, ctx) -> Solved` over one solver, and a `Method` entry naming both.
`run` reads what it needs from the context (the tool's active TCP, a stored reference
point, the robot's kinematics), so the same function serves stored calibrations (a
database-backed context) and POST /v1/solve (a stateless one). Every `loc` a method raises
is relative to the request body; the service roots it.
"""

from __future__ import annotations

import typing
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Annotated, Generic, Protocol, TypeVar

from pydantic import BaseModel, GetCoreSchemaHandler, GetJsonSchemaHandler
from pydantic.json_schema import JsonSchemaValue
from pydantic_core import PydanticCustomError, core_schema

from app.arrays import FloatArray
from app.errors import InputKind
from app.jsontypes import JsonObject
from app.schemas.common import (
    MAX_POSES,
    Activate,
    LongText,
    Pose,
    StrictModel,
    Units,
)
from app.schemas.results import QualityOut, ResultExtras
from app.schemas.tools import Tolerance
from app.solvers.orientation import angle_between_deg
from app.words import Algorithm, MethodName, PoseFormat


# ---- the request ----------------------------------------------------------------------------
def input_error(kind: InputKind, template: str, context: JsonObject) -> PydanticCustomError:
    """A schema check's failure, answered as the problem `kind` (app.api.problems reads the
    error type as the kind): a PydanticCustomError whose type mypy checks is an InputKind."""
    return PydanticCustomError(kind, template, context)


Item = TypeVar("Item")


@dataclass(frozen=True)
class PoseCount:
    """How many poses (or frame touches: `noun`) a method takes; checked by the schema, shown
    in /v1/methods.

    Too few is answered as `too-few-poses`, too many (for a method that takes an exact
    number) as `invalid-pose`, each with the method's own sentence saying what to send.
    """

    min: int
    max: int = MAX_POSES
    hint: str = ""
    noun: str = "poses"

    def _check(self, poses: list[Item]) -> list[Item]:
        n = len(poses)
        wanted = f"exactly {self.min}" if self.min == self.max else f"at least {self.min}"
        if n < self.min:
            raise input_error(
                "too-few-poses",
                "{wanted} {noun} needed, got {n}{hint}",
                {
                    "wanted": wanted,
                    "noun": self.noun,
                    "n": n,
                    "hint": f": {self.hint}" if self.hint else "",
                },
            )
        if n > self.max:
            kind: InputKind = "invalid-pose" if self.min == self.max else "validation"
            raise input_error(
                kind,
                "{wanted} {noun} allowed, got {n}{hint}",
                {
                    "wanted": wanted if self.min == self.max else f"at most {self.max}",
                    "noun": self.noun,
                    "n": n,
                    "hint": f": {self.hint}" if self.hint else "",
                },
            )
        return poses

    def __get_pydantic_core_schema__(
        self, source: type[object], handler: GetCoreSchemaHandler
    ) -> core_schema.CoreSchema:
        return core_schema.no_info_after_validator_function(self._check, handler(source))

    def __get_pydantic_json_schema__(
        self, schema: core_schema.CoreSchema, handler: GetJsonSchemaHandler
    ) -> JsonSchemaValue:
        out = handler(schema)
        if out.get("type") == "array":
            out["minItems"], out["maxItems"] = self.min, self.max
        return out


class MethodRequest(StrictModel):
    """The fields every calibration submission shares; each method adds its own."""

    method: MethodName
    format: PoseFormat | None = None
    poses: list[Pose] | None = None
    units: Units | None = None
    activate: Activate = "auto"
    note: LongText | None = None


class PosesRequired(MethodRequest):
    """A submission whose input is a pose list (every method but `manual`)."""

    format: PoseFormat
    poses: Annotated[list[Pose], PoseCount(1)]


# ---- what a method may look up --------------------------------------------------------------
@dataclass(frozen=True)
class ActiveFrame:
    """A tool's trusted TCP: position (mm, flange), orientation [w, x, y, z], 3x3 covariance."""

    position_mm: FloatArray
    quaternion: FloatArray
    covariance_mm2: FloatArray | None
    version: int | None = None


@dataclass(frozen=True)
class StoredPoint:
    """A point in the robot base frame (mm) and its 3x3 covariance (mm^2) when known."""

    position_mm: FloatArray
    covariance_mm2: FloatArray | None


class ReadsPoses(Protocol):
    """A context that reads poses in the body's format (with the robot's kinematics for
    `joints`): a tool's method context, and a frame's."""

    def parse_poses(
        self,
        fmt: PoseFormat,
        poses: Sequence[Pose],
        units: Units | None,
        *,
        loc: Sequence[str | int],
    ) -> tuple[FloatArray, FloatArray]:
        """Poses -> flange rotations (N, 3, 3), positions (N, 3) mm."""
        ...


class MethodContext(ReadsPoses, Protocol):
    """Lookups a method may need; the stateless context refuses those that need storage."""

    @property
    def tolerance(self) -> Tolerance: ...

    def active_frame(self) -> ActiveFrame | None: ...

    def reference_point(self, reference_point_id: str) -> StoredPoint: ...

    def tool_frame(self, tool_id: str) -> ActiveFrame: ...

    def laser_device(self, device_id: str) -> tuple[float, float, float]: ...


# ---- what a method computes -----------------------------------------------------------------
@dataclass
class Solved:
    """A method's outcome, before grading, versioning and storage."""

    position_mm: FloatArray
    quaternion: FloatArray | None  # None: a position-only method, the orientation is kept
    quality: QualityOut
    algorithm: Algorithm | None = None
    warnings: list[str] = field(default_factory=list)
    reference_point: StoredPoint | None = None  # the touched point, for xyz_npoint & co.
    graded: bool = True  # False for numbers entered by hand: no residuals to grade
    extras: ResultExtras = field(default_factory=ResultExtras)


# ---- the registry entry ---------------------------------------------------------------------
class RegistryEntry:
    """What a registry entry reads off its request model (`method: Literal[name]`, `options`)
    and its example body: shared by the tools' methods and the frames' (app.methods.frame)."""

    request: type[BaseModel]
    example_body: JsonObject

    @property
    def name(self) -> str:
        """The `method` value that selects this method (its request's Literal)."""
        (name,) = typing.get_args(self.request.model_fields["method"].annotation)
        return str(name)

    @property
    def example(self) -> JsonObject:
        """A body that solves (tests post it), shown in the OpenAPI spec."""
        return {"method": self.name, **self.example_body}

    @property
    def options(self) -> type[BaseModel] | None:
        """The model of `options`, when the method has options."""
        annotation = self.request.model_fields["options"].annotation
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            return annotation
        return None


R = TypeVar("R", bound=MethodRequest)


@dataclass(frozen=True)
class Method(RegistryEntry, Generic[R]):
    """One calibration method: its request schema, its runner and what /v1/methods says."""

    request: type[R]
    run: Callable[[R, MethodContext], Solved]
    description: str
    #: a body that solves, but its `method` (the name, added by `example`)
    example_body: JsonObject
    #: False for a TCP entered by hand: nothing was touched, so its summary says so and the
    #: drift trend leaves it out
    measured: bool = True

    @property
    def pose_count(self) -> PoseCount:
        """How many poses the request's schema accepts (min 0 where poses are optional)."""
        return declared_count(self.request, "poses")

    def solve(self, request: MethodRequest, ctx: MethodContext) -> Solved:
        """Run this method on a request validated by its schema."""
        if not isinstance(request, self.request):
            raise TypeError(f"{self.name} cannot run a {type(request).__name__}")
        return self.run(request, ctx)


class Listed(Protocol):
    """What /v1/methods says of any registry entry, a tool's method or a frame's."""

    @property
    def name(self) -> str: ...

    @property
    def description(self) -> str: ...

    @property
    def example(self) -> JsonObject: ...

    @property
    def measured(self) -> bool: ...

    @property
    def options(self) -> type[BaseModel] | None: ...


class RegisteredMethod(Listed, Protocol):
    """A registry entry seen from outside: any Method, whatever its own request model."""

    @property
    def request(self) -> type[MethodRequest]: ...

    @property
    def pose_count(self) -> PoseCount: ...

    def solve(self, request: MethodRequest, ctx: MethodContext) -> Solved: ...


def declared_count(request: type[BaseModel], field_name: str) -> PoseCount:
    """The PoseCount a request declares on a list field (min 0 where the list is optional)."""
    field = request.model_fields[field_name]
    metadata = list(field.metadata)
    for member in typing.get_args(field.annotation):  # `Annotated[...] | None`
        metadata += getattr(member, "__metadata__", ())
    count = next((m for m in metadata if isinstance(m, PoseCount)), PoseCount(0))
    return count if field.is_required() else PoseCount(0, count.max, count.hint, count.noun)


# ---- small helpers the methods share ---------------------------------------------------------
def orientation_change_deg(ctx: MethodContext, quaternion: Sequence[float]) -> float | None:
    """Angle (deg) from the tool's active orientation to a new one; None without one."""
    frame = ctx.active_frame()
    return None if frame is None else angle_between_deg(frame.quaternion, quaternion)


def touch_noise(option: float | None, ctx: MethodContext) -> float | None:
    """The touch noise (mm): the request's option, else the tool's configured one."""
    return option or ctx.tolerance.touch_noise_mm
