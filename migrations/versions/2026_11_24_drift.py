"""tools.drift and tools.drift_crosses_at: each tool's drift trend, stored when a version or a
check is written, so that a fleet page reads it instead of every tool's history

Revision ID: 2026_11_24_drift
Revises: 2026_11_24_activation_reason
Create Date: 2026-11-24 06:00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "2026_11_24_drift"
down_revision: str | None = "2026_11_24_controllers"  # chained after i25-deploy (merged)
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("tools", schema=None) as batch_op:
        batch_op.add_column(sa.Column("drift", sa.JSON(), nullable=True))
        batch_op.add_column(
            sa.Column("drift_crosses_at", sa.DateTime(timezone=True), nullable=True)
        )


def downgrade() -> None:
    with op.batch_alter_table("tools", schema=None) as batch_op:
        batch_op.drop_column("drift_crosses_at")
        batch_op.drop_column("drift")
