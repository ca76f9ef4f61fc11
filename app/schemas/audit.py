"""The audit trail as read back: who changed what, when, in which request."""

from __future__ import annotations

from pydantic import BaseModel, Field

from app.jsontypes import JsonObject
from app.schemas.common import StoredWord, Timestamp
from app.words import AuditAction, ResourceType


class AuditEvent(BaseModel):
    """One change, as recorded in the transaction that made it."""

    id: str = Field(description="the event's id; ids grow with time, newest first in a list")
    at: Timestamp = Field(description="when the change was made (RFC 3339, UTC)")
    action: StoredWord[AuditAction] = Field(
        description="what was done, as resource.verb: robot.create, tool.update, "
        "calibration.create, version.activate, tool.check, key.revoke, session.touch_add, ..."
    )
    actor: str = Field(description="name of the API key (or cli:<user>) that made the change")
    request_id: str | None = Field(
        description="the X-Request-ID of the request that made it (as in the access log); "
        "null for changes made from the command line"
    )
    resource_type: StoredWord[ResourceType] = Field(
        description="the kind of thing changed: robot, tool, api_key, ..."
    )
    resource_id: str = Field(description="the id of the thing changed")
    robot_id: str | None
    tool_id: str | None
    frame_id: str | None = Field(default=None, description="the frame the change concerns")
    version: int | None = Field(
        description="the version (of the tool's TCP, of the frame) the change concerns, if any"
    )
    detail: JsonObject | None = Field(
        description="what changed: old and new values of an update, an activation's reason, "
        "a calibration's status and note, a check's figures (never a key or its hash)"
    )
