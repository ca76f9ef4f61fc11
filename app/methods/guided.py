"""What a guided session takes (POST /v1/tools/{tool_id}/sessions): the N-point method's
touches, one at a time. Here, not in app.schemas.sessions, because its check names the other
registered methods: schemas are built below the method registry, never over it.
"""

from __future__ import annotations

from pydantic import Field, field_validator

from app.methods import METHOD_NAMES
from app.methods.base import RegisteredMethod
from app.methods.npoint import XYZ_NPOINT, NPointOptions
from app.schemas.common import PositiveFloat, StrictModel, Units
from app.schemas.sessions import SpinDeg, TiltDeg
from app.words import PoseFormat, XyzNpoint

#: The method a guided session collects touches for (its `method`): GET /v1/methods marks it
#: `guided`, and the CLI and the console calibrate with it unless told otherwise.
GUIDED: RegisteredMethod = XYZ_NPOINT


class SessionCreate(StrictModel):
    method: XyzNpoint = Field(
        description="guided sessions guide touches of one point (xyz_npoint); other methods "
        "take their touches in one POST /v1/tools/{tool_id}/calibrations"
    )
    format: PoseFormat
    units: Units | None = None
    target_sigma_mm: PositiveFloat | None = Field(
        default=None, description="done at this 1-sigma, largest axis (default max_rms_mm / 2)"
    )
    max_tilt_deg: TiltDeg = 40.0
    max_spin_deg: SpinDeg = 90.0
    options: NPointOptions = Field(default_factory=NPointOptions)

    @field_validator("method", mode="before")
    @classmethod
    def _guided_method(cls, method: object) -> object:
        guided = GUIDED.name
        if isinstance(method, str) and method != guided and method in METHOD_NAMES:
            raise ValueError(
                f"guided sessions guide touches of one point ({guided}) only, not {method}: "
                "its next pose is planned to reach one point. Send the touches of "
                f"{method} in one POST /v1/tools/{{tool_id}}/calibrations"
            )
        return method
