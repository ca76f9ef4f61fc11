"""deployments tell where they stopped: the old status 'failed' split honestly, and a
deployment's `reason` and `settled`

Until contract v1.3 every failed deployment was stored as 'failed' and said "...; nothing
was written", whether it stopped before the write was sent or after. The old rows are mapped
by what they can show:

- a refusal (error type "controller-refused") -> 'not_written': the controller answered and
  said no, and every refusal the old connectors met came before the write or was the
  write's own refusal (the controller kept what it held);
- anything else (unreachable, not its protocol) -> 'unverified': the old code did not note
  whether the write had been sent, so the controller may hold either frame. The detail's
  claim "; nothing was written" is replaced by a sentence saying the record cannot tell.

None of them is settled here: the next reconcile round settles one that is still its
tool's newest deployment, as it does any `unverified` one (what a controller holds now says
nothing about an attempt a later one followed, so older ones stay unsettled).
Downgrade maps 'not_written' and 'unverified' back to 'failed'.

Revision ID: 2026_11_27_deployment_truth
Revises: 2026_11_24_audit_scoped_keys
Create Date: 2026-11-27 08:00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "2026_11_27_deployment_truth"
down_revision: str | None = "2026_11_24_audit_scoped_keys"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_OLD_CLAIM = "; nothing was written"
_HONEST = (
    "; recorded before tcpcal told apart a failure before the write from one after it: "
    "the controller may have held this version or what it held before"
)

_deployments = sa.table(
    "deployments",
    sa.column("id", sa.Integer()),
    sa.column("status", sa.String(20)),
    sa.column("error", sa.JSON()),
)


def upgrade() -> None:
    with op.batch_alter_table("deployments", schema=None) as batch_op:
        batch_op.add_column(sa.Column("reason", sa.String(length=500), nullable=True))
        batch_op.add_column(sa.Column("settled", sa.JSON(), nullable=True))
    conn = op.get_bind()
    failed = conn.execute(
        sa.select(_deployments.c.id, _deployments.c.error).where(
            _deployments.c.status == "failed"
        )
    ).all()
    for row_id, error in failed:
        kind = error.get("type") if isinstance(error, dict) else None
        if kind == "controller-refused":
            values: dict[str, object] = {"status": "not_written"}
        else:
            values = {"status": "unverified"}
            detail = error.get("detail") if isinstance(error, dict) else None
            if isinstance(detail, str) and detail.endswith(_OLD_CLAIM):
                values["error"] = {**error, "detail": detail[: -len(_OLD_CLAIM)] + _HONEST}
        conn.execute(
            sa.update(_deployments).where(_deployments.c.id == row_id).values(**values)
        )


def downgrade() -> None:
    op.execute(
        sa.update(_deployments)
        .where(_deployments.c.status.in_(["not_written", "unverified"]))
        .values(status="failed")
    )
    with op.batch_alter_table("deployments", schema=None) as batch_op:
        batch_op.drop_column("settled")
        batch_op.drop_column("reason")
