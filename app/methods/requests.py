"""The calibration request bodies, as unions over the method registry.

`CalibrationRequest` is POST /v1/tools/{id}/calibrations' body: one model per method,
chosen by `method`. `SolveRequest` is POST /v1/solve's: the same models plus what a method
needs when nothing is stored (a robot or inline kinematics, a tolerance). Both are built
from app.methods.METHODS, never listed by hand. For the type checker each is the common
base `MethodRequest`; services find the method's own model through the registry.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Union, cast

from pydantic import Field, TypeAdapter, create_model

from app.methods import METHODS
from app.methods.base import MethodRequest
from app.schemas.common import ResourceId, StrictModel
from app.schemas.robots import Kinematics
from app.schemas.tools import Tolerance


class StatelessFields(StrictModel):
    """What POST /v1/solve takes besides a calibration body."""

    robot_id: ResourceId | None = None
    kinematics: Kinematics | None = None
    tolerance: Tolerance | None = None


def _stateless(model: type[MethodRequest]) -> type[MethodRequest]:
    name = "Solve" + model.__name__.removesuffix("Calibration")
    bases: tuple[type[MethodRequest], ...] = (model, StatelessFields)  # type: ignore[assignment]
    # Kept as a module attribute: importable by name, so a body pickles to a solver process.
    globals()[name] = create_model(name, __base__=bases, __module__=__name__)
    return cast("type[MethodRequest]", globals()[name])


SOLVE_MODELS: tuple[type[MethodRequest], ...] = tuple(_stateless(m.request) for m in METHODS)

if TYPE_CHECKING:
    CalibrationRequest = MethodRequest
    SolveRequest = MethodRequest
else:
    CalibrationRequest = Annotated[
        Union[tuple(m.request for m in METHODS)],  # noqa: UP007 (a union built at runtime)
        Field(discriminator="method"),
    ]
    SolveRequest = Annotated[Union[SOLVE_MODELS], Field(discriminator="method")]  # noqa: UP007

#: Validates a submission given as Python data (a stored request read back, the demo's).
CALIBRATION_REQUESTS: TypeAdapter[CalibrationRequest] = TypeAdapter(CalibrationRequest)
