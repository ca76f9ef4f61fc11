"""audit events carry their request id and version, and are read by filter without a scan;
API keys can be limited to robot cells

Revision ID: 2026_11_24_audit_scoped_keys
Revises: 2026_11_24_outbox
Create Date: 2026-11-24 05:20:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "2026_11_24_audit_scoped_keys"
down_revision: str | None = "2026_11_24_drift"  # chained after the drift migration (merged)
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

#: GET /v1/audit: newest first (by id) under each filter, a seek in an index ending in id.
_INDEXES = {
    "ix_audit_events_tool": ["tool_id", "id"],
    "ix_audit_events_robot": ["robot_id", "id"],
    "ix_audit_events_action": ["action", "id"],
    "ix_audit_events_actor": ["actor", "id"],
    "ix_audit_events_at": ["at", "id"],
}


def upgrade() -> None:
    with op.batch_alter_table("audit_events", schema=None) as batch_op:
        batch_op.add_column(sa.Column("version", sa.Integer(), nullable=True))
        batch_op.add_column(sa.Column("request_id", sa.String(length=128), nullable=True))
        # (tool_id, id) serves everything (tool_id) did, and the trail's order too.
        batch_op.drop_index("ix_audit_events_tool_id")
        for name, columns in _INDEXES.items():
            batch_op.create_index(name, columns, unique=False)
    with op.batch_alter_table("api_keys", schema=None) as batch_op:
        batch_op.add_column(sa.Column("cells", sa.JSON(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("api_keys", schema=None) as batch_op:
        batch_op.drop_column("cells")
    with op.batch_alter_table("audit_events", schema=None) as batch_op:
        for name in reversed(_INDEXES):
            batch_op.drop_index(name)
        batch_op.create_index("ix_audit_events_tool_id", ["tool_id"], unique=False)
        batch_op.drop_column("request_id")
        batch_op.drop_column("version")
