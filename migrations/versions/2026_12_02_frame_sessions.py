"""Guided frame sessions (issue 47, API.md v1.4 "Sessions:"): a guided session is of a tool
or of a frame. guided_sessions.frame_id names the frame a session calibrates (tool_id is then
the pointer it touches with), frame_calibration_id the frame calibration its finish stored;
the reachable cone (max_tilt_deg, max_spin_deg) is a tool session's only, null for a frame's.
Existing rows are tools' sessions and keep their values.

Revision ID: 2026_12_02_frame_sessions
Revises: 2026_12_02_frames
Create Date: 2026-12-02 04:50:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "2026_12_02_frame_sessions"
down_revision: str | None = "2026_12_02_frames"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("guided_sessions", schema=None) as batch_op:
        batch_op.add_column(sa.Column("frame_id", sa.String(length=36), nullable=True))
        batch_op.add_column(
            sa.Column("frame_calibration_id", sa.String(length=36), nullable=True)
        )
        batch_op.create_foreign_key(
            "fk_guided_sessions_frame_id_frames", "frames", ["frame_id"], ["id"]
        )
        batch_op.create_foreign_key(
            "fk_guided_sessions_frame_calibration_id_frame_calibrations",
            "frame_calibrations",
            ["frame_calibration_id"],
            ["id"],
        )
        batch_op.create_index(
            "ix_guided_sessions_frame_created", ["frame_id", "created_at", "id"], unique=False
        )
        batch_op.alter_column("max_tilt_deg", existing_type=sa.Float(), nullable=True)
        batch_op.alter_column("max_spin_deg", existing_type=sa.Float(), nullable=True)


def downgrade() -> None:
    op.execute("DELETE FROM guided_sessions WHERE frame_id IS NOT NULL")
    with op.batch_alter_table("guided_sessions", schema=None) as batch_op:
        batch_op.alter_column("max_spin_deg", existing_type=sa.Float(), nullable=False)
        batch_op.alter_column("max_tilt_deg", existing_type=sa.Float(), nullable=False)
        batch_op.drop_index("ix_guided_sessions_frame_created")
        batch_op.drop_constraint(
            "fk_guided_sessions_frame_calibration_id_frame_calibrations", type_="foreignkey"
        )
        batch_op.drop_constraint("fk_guided_sessions_frame_id_frames", type_="foreignkey")
        batch_op.drop_column("frame_calibration_id")
        batch_op.drop_column("frame_id")
