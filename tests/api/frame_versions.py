"""A frame's version stored as a calibration stores one (the lifecycle's add_version), for
the tests of what is done with versions: activation, rollback, the served frame."""

from __future__ import annotations

from app.security.auth import Principal
from app.services.frames.subject import FRAME
from app.services.lifecycle import versions as lifecycle
from app.storage.db import session_scope
from app.words import Status
from tests.conftest import Api

ACTOR = Principal(key_id="test-calibrate", name="test-calibrate", scope="calibrate")


def add_frame_version(frame_id: str, position: list[float], status: Status = "accepted") -> int:
    """Version n+1 of the frame, stored and not activated; its number."""
    with session_scope(write=True) as session:
        locked = lifecycle.lock(session, FRAME, frame_id)
        return lifecycle.add_version(
            session,
            FRAME,
            locked=locked,
            position_mm=position,
            quaternion=[1.0, 0.0, 0.0, 0.0],
            source="manual",
            status=status,
            calibration_id=None,
            note=None,
            actor=ACTOR,
        )


def base_at_two_versions(
    api: Api, robot_id: str, slot: int, v1: list[float], v2: list[float]
) -> str:
    """A base frame "fixture-a" of the robot at `slot`: v1 as first taught, v2 (active) as
    calibrated since; its id."""
    made = api.post(
        f"/v1/robots/{robot_id}/frames", {"name": "fixture-a", "kind": "base", "slot": slot}
    )
    assert made.status_code == 201, made.text
    frame_id = str(made.json()["id"])
    assert add_frame_version(frame_id, v1) == 1
    assert add_frame_version(frame_id, v2) == 2
    activated = api.post(f"/v1/frames/{frame_id}/versions/2/activate", scope="calibrate")
    assert activated.status_code == 200, activated.text
    return frame_id
