"""The method registry: one entry per calibration method, and everything derived from it.

Adding a method is one module (its request model, its `run`, its `Method` entry) plus one
line in METHODS. The request unions of the HTTP API, the method names and GET /v1/methods
are all read off this tuple.
"""

from __future__ import annotations

from app.methods import laser, manual, npoint, orientation, plane, reference
from app.methods.base import MethodRequest, RegisteredMethod

#: Every calibration method this server runs, in the order /v1/methods lists them.
METHODS: tuple[RegisteredMethod, ...] = (
    npoint.XYZ_NPOINT,
    plane.XYZ_PLANE,
    reference.XYZ_REFERENCE,
    orientation.TCP_Z_X,
    orientation.ABC_2POINT,
    orientation.ABC_WORLD,
    laser.LASER_BEAM,
    manual.MANUAL,
)
METHODS_BY_NAME: dict[str, RegisteredMethod] = {m.name: m for m in METHODS}
METHOD_NAMES: tuple[str, ...] = tuple(METHODS_BY_NAME)
#: The methods whose TCP is entered by hand, not measured (`Method.measured`).
ENTERED_BY_HAND: tuple[str, ...] = tuple(m.name for m in METHODS if not m.measured)


def method_of(request: MethodRequest) -> RegisteredMethod:
    """The registry entry of a validated request."""
    return METHODS_BY_NAME[request.method]


def openapi_examples() -> dict[str, dict[str, object]]:
    """One example body per method, for the request bodies in the OpenAPI spec."""
    return {m.name: {"summary": m.description, "value": m.example} for m in METHODS}
