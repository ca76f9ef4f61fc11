"""activations.reason_text: the person's own words for an activation or a rollback

`activations.reason` keeps the kind ("explicit", "rollback", "forced", "calibration:auto");
the text a person gave (at most 500 characters, checked by the API) goes beside it.

Revision ID: 2026_11_24_activation_reason
Revises: 2026_11_24_outbox
Create Date: 2026-11-24 05:20:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "2026_11_24_activation_reason"
down_revision: str | None = "2026_11_24_outbox"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    with op.batch_alter_table("activations", schema=None) as batch_op:
        batch_op.add_column(sa.Column("reason_text", sa.String(length=500), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("activations", schema=None) as batch_op:
        batch_op.drop_column("reason_text")
