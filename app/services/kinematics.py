"""Robot kinematics as stored on the robot: validated once, turned into a chain on demand."""

from __future__ import annotations

from typing import Any

from app.errors import InvalidInput
from app.kinematics.dh import kinematics_from_spec
from app.schemas.robots import Kinematics as KinematicsIn
from app.solvers.errors import SolveError


def validate_kinematics(spec: KinematicsIn | None) -> dict[str, Any] | None:
    """The kinematics to store for a robot; 422 naming the field when it is unusable."""
    if spec is None:
        return None
    as_dict = spec.model_dump()
    try:
        kinematics_from_spec(as_dict)
    except SolveError as exc:
        loc = ("body", "kinematics", *[p for p in exc.loc if p != "kinematics"])
        raise InvalidInput("invalid-kinematics", exc.detail, loc=loc) from exc
    return as_dict
