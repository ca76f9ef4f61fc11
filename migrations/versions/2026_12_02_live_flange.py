"""robot_live_tools.flange (issue 51): whether the frame a robot moved by at the last read is
its bare flange (tool 0, KUKA $NULLFRAME, FANUC UTOOL 0, a zero UR tcp_offset or Techman
TCP): no tool selected, where robots idle between jobs, is not an unknown TCP. Existing rows
are false until the next round reads the robot again.

Revision ID: 2026_12_02_live_flange
Revises: 2026_11_28_deployment_scope
Create Date: 2026-12-02 01:00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "2026_12_02_live_flange"
down_revision: str | None = "2026_11_28_deployment_scope"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("robot_live_tools", schema=None) as batch_op:
        batch_op.add_column(
            sa.Column("flange", sa.Boolean(), nullable=False, server_default=sa.false())
        )


def downgrade() -> None:
    with op.batch_alter_table("robot_live_tools", schema=None) as batch_op:
        batch_op.drop_column("flange")
