"""guided sessions: a calibration made touch by touch, stored so any worker can continue it

Revision ID: 2026_11_23_guided_sessions
Revises: 2026_11_22_initial
Create Date: 2026-11-23 08:00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "2026_11_23_guided_sessions"
down_revision: str | None = "2026_11_22_initial"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "guided_sessions",
        sa.Column("id", sa.String(length=36), nullable=False),
        sa.Column("tool_id", sa.String(length=36), nullable=False),
        sa.Column("method", sa.String(length=40), nullable=False),
        sa.Column("format", sa.String(length=40), nullable=False),
        sa.Column("units", sa.JSON(), nullable=True),
        sa.Column("target_sigma_mm", sa.Float(), nullable=True),
        sa.Column("max_tilt_deg", sa.Float(), nullable=False),
        sa.Column("max_spin_deg", sa.Float(), nullable=False),
        sa.Column("options", sa.JSON(), nullable=False),
        sa.Column("poses", sa.JSON(), nullable=False),
        sa.Column("status", sa.String(length=20), nullable=False),
        sa.Column("calibration_id", sa.String(length=36), nullable=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("updated_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("created_by", sa.String(length=200), nullable=False),
        sa.ForeignKeyConstraint(
            ["calibration_id"],
            ["calibrations.id"],
            name=op.f("fk_guided_sessions_calibration_id_calibrations"),
        ),
        sa.ForeignKeyConstraint(
            ["tool_id"], ["tools.id"], name=op.f("fk_guided_sessions_tool_id_tools")
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_guided_sessions")),
    )
    with op.batch_alter_table("guided_sessions", schema=None) as batch_op:
        batch_op.create_index(
            "ix_guided_sessions_tool_created", ["tool_id", "created_at", "id"], unique=False
        )


def downgrade() -> None:
    with op.batch_alter_table("guided_sessions", schema=None) as batch_op:
        batch_op.drop_index("ix_guided_sessions_tool_created")
    op.drop_table("guided_sessions")
