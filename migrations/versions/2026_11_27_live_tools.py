"""robot_live_tools and robot_live_matches: which TCP each robot moves by, as the last
reconcile round read it from its controller (contract v1.3 LiveTool and fleet `live`)

One row a robot (the live tool's number and frame, or unread) and one row for each version
of the robot's tools equal to that frame. Nothing to carry over: the next round reads them.

Revision ID: 2026_11_27_live_tools
Revises: 2026_11_27_touch_sources
Create Date: 2026-11-27 08:30:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "2026_11_27_live_tools"
down_revision: str | None = "2026_11_27_touch_sources"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "robot_live_tools",
        sa.Column("robot_id", sa.String(length=36), nullable=False),
        sa.Column("read", sa.Boolean(), nullable=False),
        sa.Column("number", sa.Integer(), nullable=True),
        sa.Column("frame", sa.JSON(), nullable=True),
        sa.Column("since", sa.DateTime(timezone=True), nullable=False),
        sa.Column("checked_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("error", sa.Text(), nullable=True),
        sa.ForeignKeyConstraint(
            ["robot_id"], ["robots.id"], name=op.f("fk_robot_live_tools_robot_id_robots")
        ),
        sa.PrimaryKeyConstraint("robot_id", name=op.f("pk_robot_live_tools")),
    )
    op.create_table(
        "robot_live_matches",
        sa.Column("robot_id", sa.String(length=36), nullable=False),
        sa.Column("tool_id", sa.String(length=36), nullable=False),
        sa.Column("version", sa.Integer(), nullable=False),
        sa.ForeignKeyConstraint(
            ["robot_id"],
            ["robot_live_tools.robot_id"],
            name=op.f("fk_robot_live_matches_robot_id_robot_live_tools"),
        ),
        sa.ForeignKeyConstraint(
            ["tool_id"], ["tools.id"], name=op.f("fk_robot_live_matches_tool_id_tools")
        ),
        sa.PrimaryKeyConstraint(
            "robot_id", "tool_id", "version", name=op.f("pk_robot_live_matches")
        ),
    )


def downgrade() -> None:
    op.drop_table("robot_live_matches")
    op.drop_table("robot_live_tools")
