"""watch_leases and watchers (issue 50): several instances on PostgreSQL share the watcher's
rounds, each robot read by exactly one of them a round (a lease claimed with FOR UPDATE SKIP
LOCKED, not one fleet lock), and an instance that dies loses its robots to the others when
its leases lapse. Empty at first: the first claim adds a row for each robot with a
controller. SQLite keeps one watcher (its flock) and leaves both empty.

Revision ID: 2026_12_02_watch_leases
Revises: 2026_12_02_live_flange
Create Date: 2026-12-02 02:00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "2026_12_02_watch_leases"
down_revision: str | None = "2026_12_02_live_flange"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "watch_leases",
        sa.Column("robot_id", sa.String(length=36), nullable=False),
        sa.Column("holder", sa.String(length=100), nullable=True),
        sa.Column("due_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("leased_until", sa.DateTime(timezone=True), nullable=True),
        sa.ForeignKeyConstraint(["robot_id"], ["robots.id"], ondelete="CASCADE"),
        sa.PrimaryKeyConstraint("robot_id"),
    )
    with op.batch_alter_table("watch_leases", schema=None) as batch_op:
        batch_op.create_index(batch_op.f("ix_watch_leases_due_at"), ["due_at"], unique=False)
    op.create_table(
        "watchers",
        sa.Column("holder", sa.String(length=100), nullable=False),
        sa.Column("seen_at", sa.DateTime(timezone=True), nullable=False),
        sa.PrimaryKeyConstraint("holder"),
    )


def downgrade() -> None:
    op.drop_table("watchers")
    with op.batch_alter_table("watch_leases", schema=None) as batch_op:
        batch_op.drop_index(batch_op.f("ix_watch_leases_due_at"))
    op.drop_table("watch_leases")
