"""A tool's activation and rollback (app.services.lifecycle.activation, with the tool's
declaration): a version stored as `out_of_tolerance` goes live only with `force` and a
reason; a rollback returns along the activation history, never by number."""

from __future__ import annotations

from sqlalchemy.orm import Session

from app.schemas.tools import ActivationRequest, RollbackRequest
from app.security.auth import Principal
from app.services.lifecycle import activation
from app.services.lifecycle.activation import CHECK_CORRECTION, rollback_stack
from app.services.tools.subject import TOOL
from app.storage.models import Tool

__all__ = ["CHECK_CORRECTION", "activate_version", "rollback", "rollback_stack"]


def activate_version(
    session: Session,
    *,
    tool_id: str,
    version: int,
    body: ActivationRequest,
    if_match: str | None,
    actor: Principal,
) -> Tool:
    """Make a stored version the active TCP, honouring If-Match (409 /out-of-tolerance for a
    version stored so, without force)."""
    return activation.activate_version(
        session,
        TOOL,
        subject_id=tool_id,
        version=version,
        body=body,
        if_match=if_match,
        actor=actor,
    )


def rollback(
    session: Session,
    *,
    tool_id: str,
    body: RollbackRequest,
    if_match: str | None,
    actor: Principal,
) -> Tool:
    """Return to the version that was active before the current one (If-Match honoured)."""
    return activation.rollback(
        session, TOOL, subject_id=tool_id, body=body, if_match=if_match, actor=actor
    )
