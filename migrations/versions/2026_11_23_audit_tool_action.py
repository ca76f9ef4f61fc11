"""audit events by (tool_id, action, id): a tool's newest check without scanning its history

Revision ID: 2026_11_23_audit_tool_action
Revises: 2026_11_23_guided_sessions
Create Date: 2026-11-23 09:10:00
"""

from __future__ import annotations

from collections.abc import Sequence

from alembic import op

revision: str = "2026_11_23_audit_tool_action"
down_revision: str | None = "2026_11_23_guided_sessions"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("audit_events", schema=None) as batch_op:
        batch_op.create_index(
            "ix_audit_events_tool_action", ["tool_id", "action", "id"], unique=False
        )


def downgrade() -> None:
    with op.batch_alter_table("audit_events", schema=None) as batch_op:
        batch_op.drop_index("ix_audit_events_tool_action")
