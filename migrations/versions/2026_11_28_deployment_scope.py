"""deployments.scope (contract v1.3): where a deployment holds, `stored` where the
controller keeps it (KUKA, FANUC, ABB, Yaskawa) or `live` where it holds only for the
running program (UR, Techman: the next program start sets its own TCP); every existing row
is set by its protocol. An index on (robot_id, id) finds a live-TCP robot's last
deployment, the tool its reconcile rounds judge.

Revision ID: 2026_11_28_deployment_scope
Revises: 2026_11_28_controller_ports
Create Date: 2026-11-28 09:00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "2026_11_28_deployment_scope"
down_revision: str | None = "2026_11_28_controller_ports"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

#: The protocols whose deployments hold only for the running program (a migration keeps its
#: own copy of app.controllers.base.SCOPES: it must do what it did when written). Every
#: other protocol's deployment is stored.
LIVE_PROTOCOLS = ("techman", "ur_rtde")

_DEPLOYMENTS = sa.table(
    "deployments", sa.column("protocol", sa.String(20)), sa.column("scope", sa.String(10))
)


def upgrade() -> None:
    with op.batch_alter_table("deployments", schema=None) as batch_op:
        batch_op.add_column(sa.Column("scope", sa.String(length=10), nullable=True))
    bind = op.get_bind()
    live = _DEPLOYMENTS.c.protocol.in_(LIVE_PROTOCOLS)
    bind.execute(_DEPLOYMENTS.update().where(live).values(scope="live"))
    bind.execute(_DEPLOYMENTS.update().where(~live).values(scope="stored"))
    with op.batch_alter_table("deployments", schema=None) as batch_op:
        batch_op.alter_column("scope", existing_type=sa.String(length=10), nullable=False)
        batch_op.create_index("ix_deployments_robot_seq", ["robot_id", "id"], unique=False)


def downgrade() -> None:
    with op.batch_alter_table("deployments", schema=None) as batch_op:
        batch_op.drop_index("ix_deployments_robot_seq")
        batch_op.drop_column("scope")
