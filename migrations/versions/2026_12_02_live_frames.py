"""robot_live_frames (issue 48): the frame each robot moved in at the last reconcile round
(its number, name and value as the controller says) and the version of one of its frames
equal to it, beside robot_live_tools. Empty until the next round reads each robot.

Revision ID: 2026_12_02_live_frames
Revises: 2026_12_02_frame_deployments
Create Date: 2026-12-02 05:15:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "2026_12_02_live_frames"
down_revision: str | None = "2026_12_02_frame_deployments"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "robot_live_frames",
        sa.Column("robot_id", sa.String(length=36), nullable=False),
        sa.Column("read", sa.Boolean(), nullable=False),
        sa.Column("number", sa.Integer(), nullable=True),
        sa.Column("name", sa.Text(), nullable=True),
        sa.Column("frame", sa.JSON(), nullable=True),
        sa.Column("frame_id", sa.String(length=36), nullable=True),
        sa.Column("version", sa.Integer(), nullable=True),
        sa.Column("since", sa.DateTime(timezone=True), nullable=False),
        sa.Column("checked_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ["robot_id"], ["robots.id"], name=op.f("fk_robot_live_frames_robot_id_robots")
        ),
        sa.PrimaryKeyConstraint("robot_id", name=op.f("pk_robot_live_frames")),
    )


def downgrade() -> None:
    op.drop_table("robot_live_frames")
