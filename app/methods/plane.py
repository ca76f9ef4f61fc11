"""`xyz_plane`: touches of flat surfaces whose place is unknown -> TCP position (METHODS 7).

A touch is a pose in the submission's format, as for every method. With `options.planes`
(up to three labelled planes) each touch names the plane it touched: it is then an object
`{"plane": "a", "pose": [...]}` in `poses` instead of the bare pose. The labels are taken off
as the request is validated (kept beside the poses), so that everything else that reads a
submission's poses (the convention diagnosis, the report's 3-D view) reads plain poses in
the submission's format, whatever it is.
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import (
    ConfigDict,
    Field,
    ModelWrapValidatorHandler,
    PrivateAttr,
    ValidationError,
    field_validator,
    model_validator,
)
from pydantic_core import InitErrorDetails, PydanticCustomError
from scipy.spatial.transform import Rotation

from app.errors import InvalidInput
from app.jsontypes import JsonObject
from app.methods.base import (
    ActiveFrame,
    Method,
    MethodContext,
    PoseCount,
    PosesRequired,
    Solved,
    touch_noise,
)
from app.schemas.common import Pose, StrictModel, TouchNoise
from app.schemas.results import PlaneDetails, PlaneOut, QualityOut, ResultExtras
from app.solvers.plane import MIN_POSES, PlaneResult, check_predicted_sigma, solve_plane
from app.words import XyzPlane

PlaneLabel = Literal["a", "b", "c"]


class PlaneTouch(StrictModel):
    """One touch of a labelled plane: the pose in the submission's format, and the plane."""

    plane: PlaneLabel
    pose: Pose


class PlaneOptions(StrictModel):
    # uniqueItems: the spec states what _distinct enforces.
    planes: (
        Annotated[
            list[PlaneLabel],
            Field(min_length=1, max_length=3, json_schema_extra={"uniqueItems": True}),
        ]
        | None
    ) = Field(
        default=None,
        description="the labelled planes touched (up to 3); each touch then names its plane: "
        '{"plane": "a", "pose": [...]}. Without it, one plane and bare poses',
    )
    touch_noise_mm: TouchNoise | None = None

    @field_validator("planes")
    @classmethod
    def _distinct(cls, planes: list[str] | None) -> list[str] | None:
        if planes is not None and len(set(planes)) != len(planes):
            raise ValueError("each plane is listed once")
        return planes


def _touch_schema(schema: JsonObject) -> None:
    """The spec says what the validator takes: each item a bare pose or a labelled touch."""
    poses = schema["properties"]["poses"]
    poses["items"] = {"anyOf": [poses["items"], PlaneTouch.model_json_schema()]}
    poses["description"] = (
        "the touches: bare poses for one plane; with options.planes, each "
        '{"plane": "a" | "b" | "c", "pose": [...]}'
    )


Touches = Annotated[
    list[Pose],
    PoseCount(
        MIN_POSES,
        hint="touch one flat surface at 7 or more points spread across it, the tool tilted "
        "differently at each (15-40 deg from the surface's normal, in different directions): "
        "6 unknowns and one touch to spare",
    ),
]


class XyzPlaneCalibration(PosesRequired):
    model_config = ConfigDict(json_schema_extra=_touch_schema)

    method: XyzPlane
    poses: Touches
    options: PlaneOptions = Field(default_factory=PlaneOptions)
    #: each touch's plane label as sent (None for a bare pose), in pose order
    _labels: list[str | None] = PrivateAttr(default_factory=list)

    @model_validator(mode="wrap")
    @classmethod
    def _labelled_touches(
        cls, data: object, handler: ModelWrapValidatorHandler[XyzPlaneCalibration]
    ) -> XyzPlaneCalibration:
        """Take the plane labels off labelled touches, keeping the poses in their place."""
        labels: list[str | None] = []
        if isinstance(data, dict) and isinstance(data.get("poses"), list):
            poses, errors = [], []
            for i, item in enumerate(data["poses"]):
                if not isinstance(item, dict):
                    poses.append(item)
                    labels.append(None)
                    continue
                try:
                    touch = PlaneTouch.model_validate(item)
                except ValidationError as exc:
                    errors += [_located(error, i) for error in exc.errors()]
                    continue
                poses.append(touch.pose)
                labels.append(touch.plane)
            if errors:
                raise ValidationError.from_exception_data(cls.__name__, errors)
            data = {**data, "poses": poses}
        request = handler(data)
        if labels:
            request._labels = labels
        return request

    def touch_planes(self) -> list[str | None]:
        """Each touch's plane label as sent (None where a bare pose was sent)."""
        return list(self._labels) or [None] * len(self.poses)


def _located(error: object, index: int) -> InitErrorDetails:
    """A labelled touch's validation error, placed at poses.<index>.<field>."""
    assert isinstance(error, dict)
    return InitErrorDetails(
        type=PydanticCustomError(str(error["type"]), str(error["msg"])),
        loc=("poses", index, *error["loc"]),
        input=error.get("input"),
    )


def touch_labels(request: XyzPlaneCalibration) -> list[str] | None:
    """The plane of every touch (None: one plane), checked against options.planes."""
    sent = request.touch_planes()
    listed = request.options.planes
    if listed is None:
        labelled = next((i for i, lab in enumerate(sent) if lab is not None), None)
        if labelled is not None:
            raise InvalidInput(
                "invalid-options",
                f"touch #{labelled + 1} names plane {sent[labelled]!r} but options.planes is "
                'not given: list the planes touched (options.planes, e.g. ["a", "b"]), or '
                "send bare poses for one plane",
                loc=("poses", labelled, "plane"),
            )
        return None
    missing = next((i for i, lab in enumerate(sent) if lab is None), None)
    if missing is not None:
        raise InvalidInput(
            "invalid-options",
            f"touch #{missing + 1} does not say which plane it touched; with options.planes "
            f'{listed} every touch is {{"plane": ..., "pose": [...]}}',
            loc=("poses", missing),
        )
    labels = [lab for lab in sent if lab is not None]
    for i, lab in enumerate(labels):
        if lab not in listed:
            raise InvalidInput(
                "invalid-options",
                f"touch #{i + 1} names plane {lab!r}, which options.planes {listed} does not "
                "list: add it there, or correct the touch's label",
                loc=("poses", i, "plane"),
            )
    for lab in listed:
        if lab not in labels:
            raise InvalidInput(
                "invalid-options",
                f"options.planes lists plane {lab!r} but no touch names it: touch it (3 or "
                "more times) or take it off the list",
                loc=("options", "planes"),
            )
    return labels


def _tool_frame_sigma(result: PlaneResult, frame: ActiveFrame | None) -> list[float]:
    """The TCP's 1-sigma along the axes of the tool frame the result will carry."""
    quaternion = frame.quaternion if frame is not None else np.array([1.0, 0.0, 0.0, 0.0])
    tool = Rotation.from_quat(quaternion, scalar_first=True).as_matrix()
    cov = np.asarray(result.quality.tcp_covariance_mm2)
    in_tool = tool.T @ cov @ tool
    return [float(np.sqrt(max(v, 0.0))) for v in np.diag(in_tool)]


def run(request: XyzPlaneCalibration, ctx: MethodContext) -> Solved:
    """TCP position and the planes' normals and offsets from touches of the planes."""
    labels = touch_labels(request)
    rotations, positions = ctx.parse_poses(
        request.format, request.poses, request.units, loc=("poses",)
    )
    frame = ctx.active_frame()
    noise = touch_noise(request.options.touch_noise_mm, ctx)
    limit = ctx.tolerance.max_rms_mm
    result = solve_plane(
        rotations,
        positions,
        planes=labels,
        touch_noise_mm=noise,
        start_tcp_mm=None if frame is None else frame.position_mm,
        # with a configured noise a set too weak for the tolerance is refused before anything
        max_tcp_sigma_mm=limit if noise is not None else None,
    )
    if noise is None and result.quality.rms_mm <= limit:
        # touches that agree within tolerance, yet a TCP that does not: the tilts, not the
        # touching, are what fails (noisier touches are graded out_of_tolerance instead)
        check_predicted_sigma(
            np.asarray(result.quality.tcp_covariance_mm2), limit, result.touch_noise_mm, False
        )
    planes = [
        PlaneOut(
            label=p.label,
            normal=[float(v) for v in p.normal],
            offset_mm=p.offset_mm,
            normal_sigma_deg=p.normal_sigma_deg,
            offset_sigma_mm=p.offset_sigma_mm,
            n_touches=p.n_touches,
        )
        for p in result.planes
    ]
    return Solved(
        position_mm=result.tcp_mm,
        quaternion=None,
        quality=QualityOut.from_solver(result.quality),
        algorithm=None,
        warnings=list(result.quality.warnings),
        extras=ResultExtras(
            details=PlaneDetails(
                planes=planes,
                touch_planes=labels if labels is not None else ["a"] * len(request.poses),
                tcp_sigma_tool_mm=_tool_frame_sigma(result, frame),
                touch_noise_mm=result.touch_noise_mm,
            )
        ),
    )


XYZ_PLANE = Method(
    request=XyzPlaneCalibration,
    run=run,
    description="N >= 7 touches of one flat surface, its place unknown, with the tool tilted "
    "differently at each -> TCP position and the plane (RoboDK's calibrate by plane); up to "
    "3 labelled planes",
    example_body={
        "format": "kuka_abc",
        "poses": [
            [773.872, -182.194, 415.969, -91.983, -19.054, -169.019],
            [849.739, -173.744, 411.137, 76.67, -23.309, -168.504],
            [724.155, -79.465, 396.282, 7.913, -8.089, 144.67],
            [678.004, -174.102, 413.083, -170.928, 22.99, -169.405],
            [920.585, -124.052, 405.646, -169.9, -23.887, -162.478],
            [822.67, -80.775, 428.689, -81.107, -4.384, -175.334],
            [779.363, -90.67, 399.554, -15.177, 1.165, 145.579],
            [801.991, -24.168, 408.556, 78.424, 27.994, 172.366],
        ],
        "note": "touched the fixture plate",
    },
)
