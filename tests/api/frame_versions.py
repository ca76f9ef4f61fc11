"""A frame's version stored as a calibration stores one (the lifecycle's add_version), for
the tests of what is done with versions: activation, rollback, the served frame."""

from __future__ import annotations

from app.security.auth import Principal
from app.services.frames.subject import FRAME
from app.services.lifecycle import versions as lifecycle
from app.storage.db import session_scope
from app.words import Status

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
