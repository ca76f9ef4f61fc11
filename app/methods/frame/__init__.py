"""The frame method registry: one entry per frame calibration method, and what derives from it.

Adding a method is one module (its request model, its `run`, its `FrameMethod` entry) plus
one line in FRAME_METHODS. The request union of POST /v1/frames/{frame_id}/calibrations,
the method names and the frame methods of GET /v1/methods are read off this tuple.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Union

from pydantic import Field, TypeAdapter

from app.methods.frame import fit_points, fixed_npoint, four_point, manual, three_point
from app.methods.frame.base import FrameMethodRequest, RegisteredFrameMethod

#: Every frame calibration method this server runs, in the order /v1/methods lists them.
FRAME_METHODS: tuple[RegisteredFrameMethod, ...] = (
    three_point.THREE_POINT_FRAME,
    four_point.FOUR_POINT_FRAME,
    fit_points.FIT_POINTS_FRAME,
    fixed_npoint.FIXED_NPOINT_FRAME,
    manual.MANUAL_FRAME,
)
FRAME_METHODS_BY_NAME: dict[str, RegisteredFrameMethod] = {m.name: m for m in FRAME_METHODS}
FRAME_METHOD_NAMES: tuple[str, ...] = tuple(FRAME_METHODS_BY_NAME)

if TYPE_CHECKING:
    FrameCalibrationIn = FrameMethodRequest
else:
    #: POST /v1/frames/{frame_id}/calibrations' body: one model per method, by `method`.
    FrameCalibrationIn = Annotated[
        Union[tuple(m.request for m in FRAME_METHODS)],  # noqa: UP007 (a union built at runtime)
        Field(discriminator="method"),
    ]

#: Validates a frame calibration body given as Python data (a stored request read back).
FRAME_CALIBRATION_REQUESTS: TypeAdapter[FrameCalibrationIn] = TypeAdapter(FrameCalibrationIn)


def frame_method_of(request: FrameMethodRequest) -> RegisteredFrameMethod:
    """The registry entry of a validated request."""
    return FRAME_METHODS_BY_NAME[request.method]


def frame_openapi_examples() -> dict[str, dict[str, object]]:
    """One example body per frame method, for the request body in the OpenAPI spec."""
    return {m.name: {"summary": m.description, "value": m.example} for m in FRAME_METHODS}
