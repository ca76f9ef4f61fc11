"""robot_controllers.ports: a protocol of several services (techman, yaskawa_hses, ur_rtde;
contract v1.3) is reached on one port a service, kept as {service: port} with the defaults
filled in; `port` becomes null for such a protocol (a single-service one keeps its `port`)

Nothing to carry over: every stored controller is of a single-service protocol. Downgrading
puts a several-services controller's main service port back in `port` (the older code then
refuses its protocol, as it would any other it does not know) and drops `ports`.

Revision ID: 2026_11_28_controller_ports
Revises: 2026_11_27_max_correction
Create Date: 2026-11-28 08:00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "2026_11_28_controller_ports"
down_revision: str | None = "2026_11_27_max_correction"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

#: Each several-services protocol's main service and its default port (a migration keeps its
#: own copy of app.controllers.base.SERVICE_PORTS: it must do what it did when written).
MAIN_SERVICES: dict[str, tuple[str, int]] = {
    "techman": ("listen_node", 5890),
    "yaskawa_hses": ("robot", 10040),
    "ur_rtde": ("rtde", 30004),
}

_CONTROLLERS = sa.table(
    "robot_controllers",
    sa.column("robot_id", sa.String(36)),
    sa.column("protocol", sa.String(20)),
    sa.column("port", sa.Integer()),
    sa.column("ports", sa.JSON()),
)


def upgrade() -> None:
    with op.batch_alter_table("robot_controllers", schema=None) as batch_op:
        batch_op.add_column(sa.Column("ports", sa.JSON(), nullable=True))
        batch_op.alter_column("port", existing_type=sa.Integer(), nullable=True)


def downgrade() -> None:
    bind = op.get_bind()
    rows = bind.execute(
        sa.select(_CONTROLLERS.c.robot_id, _CONTROLLERS.c.protocol, _CONTROLLERS.c.ports).where(
            _CONTROLLERS.c.port.is_(None)
        )
    ).all()
    for row in rows:
        service, default = MAIN_SERVICES.get(row.protocol, ("", 0))
        port = int((row.ports or {}).get(service, default)) or 1
        bind.execute(
            _CONTROLLERS.update()
            .where(_CONTROLLERS.c.robot_id == row.robot_id)
            .values(port=port)
        )
    with op.batch_alter_table("robot_controllers", schema=None) as batch_op:
        batch_op.alter_column("port", existing_type=sa.Integer(), nullable=False)
        batch_op.drop_column("ports")
