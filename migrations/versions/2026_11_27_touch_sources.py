"""touches straight from the controller: each touch of a guided session records where it
came from (typed, or read from the controller with what it printed), and the calibration a
session finishes keeps them (issue 39)

Revision ID: 2026_11_27_touch_sources
Revises: 2026_11_27_deployment_truth
Create Date: 2026-11-27 08:30:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "2026_11_27_touch_sources"
down_revision: str | None = "2026_11_27_deployment_truth"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_SESSIONS = sa.table(
    "guided_sessions",
    sa.column("id", sa.String(36)),
    sa.column("poses", sa.JSON()),
    sa.column("touches", sa.JSON()),
)


def upgrade() -> None:
    with op.batch_alter_table("guided_sessions", schema=None) as batch_op:
        batch_op.add_column(sa.Column("touches", sa.JSON(), nullable=True))
    # Every touch stored before this revision was typed: that is all a session could take.
    bind = op.get_bind()
    for row in bind.execute(sa.select(_SESSIONS.c.id, _SESSIONS.c.poses)).all():
        typed = [{"source": "typed", "read_at": None} for _ in row.poses or []]
        bind.execute(_SESSIONS.update().where(_SESSIONS.c.id == row.id).values(touches=typed))
    with op.batch_alter_table("guided_sessions", schema=None) as batch_op:
        batch_op.alter_column("touches", existing_type=sa.JSON(), nullable=False)
    with op.batch_alter_table("calibrations", schema=None) as batch_op:
        batch_op.add_column(sa.Column("touches", sa.JSON(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("calibrations", schema=None) as batch_op:
        batch_op.drop_column("touches")
    with op.batch_alter_table("guided_sessions", schema=None) as batch_op:
        batch_op.drop_column("touches")
