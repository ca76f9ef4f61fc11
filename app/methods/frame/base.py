"""What every frame calibration method shares: its request base, its context, its outcome and
its registry entry (API.md v1.4 "Frame touches and methods", METHODS.md 7).

A frame method is one module, as a tool's method is (app.methods.base): a request model (a
`FrameMethodRequest` with `method: Literal[name]`), `run(request, ctx) -> FrameSolved` over
one solver of app.solvers.frame, and a `FrameMethod` entry naming both. `run` reads what it
needs from a `FrameContext`: the pointer tool's TCP (its active version, or `tcp_version`),
the frame's kind and tolerance, and the robot's pose reading. The frame resource serves one
backed by the database; tests use a stateless one. Every `loc` a method raises is relative
to the request body; the service roots it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Annotated, Generic, Protocol, TypeVar

import numpy as np
from pydantic import BeforeValidator, Field

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.jsontypes import JsonObject
from app.methods.base import Listed, PoseCount, ReadsPoses, RegistryEntry, declared_count
from app.schemas.common import (
    Activate,
    LongText,
    Pose,
    ResourceId,
    StrictModel,
    TouchNoise,
    Units,
    json_integer,
)
from app.schemas.frame_results import Fiducial, FramePointer, FrameQuality
from app.schemas.frame_tolerance import FrameTolerance
from app.solvers.frame import FrameEstimate, Pointer, interval_scale, point_covariance
from app.solvers.frame.fit_points import rms
from app.words import FrameKind, FrameMethodName, PoseFormat

#: A TCP version number, as the tools' versions count them (1, 2, ...).
TcpVersionNumber = Annotated[int, Field(ge=1), BeforeValidator(json_integer)]


# ---- the request ----------------------------------------------------------------------------
class FrameTouch(StrictModel):
    """One touch: the flange pose (in the body's `format`) with the pointer on a point."""

    pose: Pose


class FrameMethodRequest(StrictModel):
    """The fields every frame calibration shares; each method adds its `touches` (typed as it
    needs them: with a role, with nominal_mm, or bare) and its `options`."""

    method: FrameMethodName
    tool_id: ResourceId | None = Field(
        default=None, description="the pointer tool whose TCP touched the points"
    )
    tcp_version: TcpVersionNumber | None = Field(
        default=None, description="the pointer's TCP version to use (default: its active one)"
    )
    format: PoseFormat | None = None
    units: Units | None = None
    activate: Activate = "auto"
    note: LongText | None = None


class TouchedFrameRequest(FrameMethodRequest):
    """A frame calibration from touches (every method but `manual`)."""

    tool_id: ResourceId = Field(description="the pointer tool whose TCP touched the points")
    format: PoseFormat


def touch_count(minimum: int, maximum: int | None = None, *, hint: str) -> PoseCount:
    """How many touches a method takes, as its schema checks and /v1/methods shows it."""
    if maximum is None:
        return PoseCount(minimum, hint=hint, noun="touches")
    return PoseCount(minimum, maximum, hint=hint, noun="touches")


class NoiseOption(StrictModel):
    """The options every touched method takes."""

    touch_noise_mm: TouchNoise | None = Field(
        default=None,
        description="1-sigma per axis of a touch (mm); default: the frame's "
        "tolerance.touch_noise_mm, else estimated from the residuals when there are spare "
        "touches",
    )


# ---- what a method may look up --------------------------------------------------------------
@dataclass(frozen=True)
class PointerTcp:
    """The pointer tool's TCP a frame is touched with: which version, and its value."""

    tool_id: str
    version: int
    pointer: Pointer

    @property
    def tcp_sigma_mm(self) -> FloatArray:
        """1-sigma of the TCP per flange axis, mm."""
        out: FloatArray = np.sqrt(np.clip(np.diag(self.pointer.tcp_covariance_mm2), 0.0, None))
        return out


class FrameContext(ReadsPoses, Protocol):
    """Lookups a frame method may need, and the robot's pose reading (`parse_poses`)."""

    @property
    def kind(self) -> FrameKind:
        """The frame's kind: `fixed_npoint` calibrates a fixed_tool only."""
        ...

    @property
    def tolerance(self) -> FrameTolerance:
        """The frame's tolerance, defaults filled in."""
        ...

    def pointer(self, tool_id: str, version: int | None) -> PointerTcp | None:
        """The pointer's TCP: version `version`, else its active one; None when the tool has
        no active version and none is named. An unknown tool, or a version it does not have,
        is refused (422 at loc ("tool_id",) or ("tcp_version",))."""
        ...


def touched_with(request: TouchedFrameRequest, ctx: FrameContext) -> PointerTcp:
    """The pointer TCP the touches are read with; refused when the tool has no TCP to trust."""
    found = ctx.pointer(request.tool_id, request.tcp_version)
    if found is None:
        raise InvalidInput(
            "unknown-reference",
            f"pointer tool {request.tool_id} has no active TCP version: its TCP is what turns "
            f"each touch into a point; calibrate it first (POST /v1/tools/{request.tool_id}/"
            "calibrations), or name a version with tcp_version",
            loc=("tool_id",),
        )
    return found


def parse_touches(
    ctx: FrameContext, fmt: PoseFormat, units: Units | None, touches: Sequence[FrameTouch]
) -> tuple[FloatArray, FloatArray]:
    """The touches' flange poses: rotations (N, 3, 3), positions (N, 3) mm. A pose that cannot
    be read is refused at its own loc ("touches", i, "pose")."""
    try:
        return ctx.parse_poses(fmt, [t.pose for t in touches], units, loc=("touches",))
    except InvalidInput as exc:
        loc = tuple(exc.loc)
        if len(loc) >= 2 and loc[0] == "touches" and isinstance(loc[1], int):
            exc.loc = (*loc[:2], "pose", *loc[2:])
        raise


def touch_noise_of(option: float | None, ctx: FrameContext) -> float | None:
    """The touch noise (mm): the request's option, else the frame's configured one."""
    return option if option is not None else ctx.tolerance.touch_noise_mm


def configured_noise(option: float | None, ctx: FrameContext, method: str) -> float:
    """The touch noise an exact construction needs: its touches leave no residual to estimate
    it from, so without one the frame's uncertainty and the angle check cannot be had."""
    noise = touch_noise_of(option, ctx)
    if noise is None:
        raise InvalidInput(
            "invalid-options",
            f"{method} touches exactly what it needs and leaves no residual to estimate the "
            "touch noise from: give options.touch_noise_mm (the 1-sigma of a touch, mm, e.g. "
            "0.05) or set the frame's tolerance.touch_noise_mm",
            loc=("options", "touch_noise_mm"),
        )
    return noise


def touches_covariance(
    rotations: FloatArray, touch_noise_mm: float, pointer: PointerTcp
) -> FloatArray:
    """The (3N, 3N) covariance of the touched points: the touch noise, and the pointer's TCP
    error common to every touch (turned by each touch's flange rotation)."""
    return point_covariance(rotations, touch_noise_mm, pointer.pointer.tcp_covariance_mm2)


# ---- what a method computes -----------------------------------------------------------------
@dataclass
class FrameSolved:
    """A frame method's outcome, before grading, versioning and storage."""

    position_mm: FloatArray  # (3,) origin, base frame
    quaternion: FloatArray  # (4,) [w, x, y, z], frame -> base
    quality: FrameQuality
    points_mm: FloatArray  # (N, 3) each touch's point, base frame
    tool: FramePointer | None  # None: nothing was touched (manual)
    summary: str
    fiducials: list[Fiducial]
    warnings: list[str] = field(default_factory=list)
    #: (6, 6) over [origin mm (base axes), rotation rad (frame axes)]; None for manual
    covariance: FloatArray | None = None
    graded: bool = True  # False for a frame entered by hand: no residuals to grade


def pointer_out(pointer: PointerTcp) -> FramePointer:
    """The pointer as a calibration reports it."""
    return FramePointer(
        tool_id=pointer.tool_id,
        version=pointer.version,
        tcp_sigma_mm=[float(s) for s in pointer.tcp_sigma_mm],
    )


def quality_of(estimate: FrameEstimate) -> FrameQuality:
    """The quality figures of an estimate (residuals over every touch, rms over those used)."""
    used = np.asarray(estimate.used, dtype=bool)
    residuals = np.asarray(estimate.residuals_mm, dtype=float)
    return FrameQuality(
        n_touches=int(residuals.size),
        rms_mm=rms(residuals[used]),
        max_mm=float(residuals[used].max()) if used.any() else 0.0,
        residuals_mm=[float(r) for r in residuals],
        position_sigma_mm=[float(s) for s in estimate.position_sigma_mm],
        angle_sigma_deg=[float(s) for s in estimate.angle_sigma_deg],
        sigma_source=estimate.sigma_source,
        interval95_scale=interval_scale(estimate.dof, 1),
        outliers=list(estimate.outliers),
    )


def extent_sentence(estimate: FrameEstimate) -> str:
    """The worst position error over the touched extent, in words."""
    reach, worst = estimate.extent()
    return f"a point {reach:.0f} mm from the origin is within {worst:.2f} mm (95 %)"


def solved_from_estimate(
    estimate: FrameEstimate,
    *,
    names: Sequence[str],
    pointer: PointerTcp,
    what: str,
) -> FrameSolved:
    """A method's outcome from a solver's estimate: `names` names each touch's fiducial,
    `what` says in words what was done ("three_point from 3 touches")."""
    quality = quality_of(estimate)
    summary = f"{what}: rms {quality.rms_mm:.3f} mm; {extent_sentence(estimate)}"
    if estimate.outliers:
        summary += f"; {len(estimate.outliers)} set aside"
    used = np.asarray(estimate.used, dtype=bool)
    return FrameSolved(
        position_mm=np.asarray(estimate.origin_mm, dtype=float),
        quaternion=estimate.quaternion_wxyz,
        quality=quality,
        points_mm=np.asarray(estimate.points_mm, dtype=float),
        tool=pointer_out(pointer),
        summary=summary,
        fiducials=[
            Fiducial(name=name, nominal_mm=[float(v) for v in nominal])
            for name, nominal, keep in zip(names, estimate.nominal_mm, used, strict=True)
            if keep
        ],
        warnings=list(estimate.warnings),
        covariance=np.asarray(estimate.covariance, dtype=float),
    )


# ---- the registry entry ---------------------------------------------------------------------
R = TypeVar("R", bound=FrameMethodRequest)


@dataclass(frozen=True)
class RoleSet:
    """The roles of a method's touches under one convention, each with what to touch."""

    convention: str | None
    words: Mapping[str, str]


@dataclass(frozen=True)
class FrameMethod(RegistryEntry, Generic[R]):
    """One frame calibration method: its request schema, its runner and what /v1/methods
    says of it."""

    request: type[R]
    run: Callable[[R, FrameContext], FrameSolved]
    description: str
    #: a body that solves, but its `method` (the name, added by `example`)
    example_body: JsonObject
    #: the frame kinds it calibrates
    kinds: tuple[FrameKind, ...] = ("base", "fixed_tool")
    #: the roles its touches take, by convention (none: its touches take no role)
    roles: tuple[RoleSet, ...] = ()
    #: False for a frame entered by hand
    measured: bool = True

    @property
    def touch_count(self) -> PoseCount:
        """How many touches the request's schema accepts (none for a frame entered by hand)."""
        if "touches" not in self.request.model_fields:
            return PoseCount(0, 0, noun="touches")
        return declared_count(self.request, "touches")

    def solve(self, request: FrameMethodRequest, ctx: FrameContext) -> FrameSolved:
        """Run this method on a request validated by its schema, for a frame of its kinds."""
        if not isinstance(request, self.request):
            raise TypeError(f"{self.name} cannot run a {type(request).__name__}")
        if ctx.kind not in self.kinds:
            raise InvalidInput(
                "unsupported",
                f"{self.name} calibrates a frame of kind {' or '.join(self.kinds)}, and this "
                f"frame is a {ctx.kind}: choose another method, or calibrate a frame of that "
                "kind",
                loc=("method",),
            )
        return self.run(request, ctx)


class RegisteredFrameMethod(Listed, Protocol):
    """A frame registry entry seen from outside: any FrameMethod, whatever its request."""

    @property
    def request(self) -> type[FrameMethodRequest]: ...

    @property
    def kinds(self) -> tuple[FrameKind, ...]: ...

    @property
    def roles(self) -> tuple[RoleSet, ...]: ...

    @property
    def touch_count(self) -> PoseCount: ...

    def solve(self, request: FrameMethodRequest, ctx: FrameContext) -> FrameSolved: ...
