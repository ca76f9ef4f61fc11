"""Robot kinematics as stored on the robot: validated once, turned into a chain on demand."""

from __future__ import annotations

from typing import Any

from app.schemas.robots import Kinematics as KinematicsIn


def validate_kinematics(spec: KinematicsIn | None) -> dict[str, Any] | None:
    """The kinematics to store for a robot; 422 naming the field when it is unusable."""
    if spec is None:
        return None
    as_dict = spec.model_dump()
    from app.kinematics.dh import kinematics_from_spec  # built by the pose-format work

    try:
        kinematics_from_spec(as_dict)
    except ValueError as exc:
        from app.errors import InvalidInput

        raise InvalidInput("invalid-kinematics", str(exc), loc=("body", "kinematics")) from exc
    return as_dict
