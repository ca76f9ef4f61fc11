"""Frames at the controller (issue 48, contract v1.4 "Frames at the controller"): each
attempt to write a frame's active version into its robot's controller (`frame_deployments`)
and what the last reconcile found there (`frame_controller_states`), of the shape of a
tool's `deployments` and `tool_controller_states` (app.services.lifecycle.subject).

Revision ID: 2026_12_02_frame_deployments
Revises: 2026_12_02_frame_sessions
Create Date: 2026-12-02 05:00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "2026_12_02_frame_deployments"
down_revision: str | None = "2026_12_02_frame_sessions"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_ID = sa.BigInteger().with_variant(sa.Integer(), "sqlite")


def upgrade() -> None:
    op.create_table(
        "frame_deployments",
        sa.Column("id", _ID, autoincrement=True, nullable=False),
        sa.Column("frame_id", sa.String(length=36), nullable=False),
        sa.Column("robot_id", sa.String(length=36), nullable=False),
        sa.Column("version", sa.Integer(), nullable=False),
        sa.Column("protocol", sa.String(length=20), nullable=False),
        sa.Column("target", sa.String(length=300), nullable=False),
        sa.Column("status", sa.String(length=20), nullable=False),
        sa.Column("scope", sa.String(length=10), nullable=False),
        sa.Column("previous", sa.JSON(), nullable=True),
        sa.Column("read_back", sa.JSON(), nullable=True),
        sa.Column("deviation_mm", sa.Float(), nullable=True),
        sa.Column("deviation_deg", sa.Float(), nullable=True),
        sa.Column("error", sa.JSON(), nullable=True),
        sa.Column("reason", sa.String(length=500), nullable=True),
        sa.Column("settled", sa.JSON(), nullable=True),
        sa.Column("actor", sa.String(length=200), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ["frame_id"], ["frames.id"], name=op.f("fk_frame_deployments_frame_id_frames")
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_frame_deployments")),
    )
    with op.batch_alter_table("frame_deployments", schema=None) as batch_op:
        batch_op.create_index("ix_frame_deployments_frame_seq", ["frame_id", "id"], unique=False)
        batch_op.create_index("ix_frame_deployments_robot_seq", ["robot_id", "id"], unique=False)
    op.create_table(
        "frame_controller_states",
        sa.Column("frame_id", sa.String(length=36), nullable=False),
        sa.Column("robot_id", sa.String(length=36), nullable=False),
        sa.Column("state", sa.String(length=20), nullable=False),
        sa.Column("since", sa.DateTime(timezone=True), nullable=False),
        sa.Column("checked_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("target", sa.String(length=300), nullable=True),
        sa.Column("deviation_mm", sa.Float(), nullable=True),
        sa.Column("deviation_deg", sa.Float(), nullable=True),
        sa.Column("controller", sa.JSON(), nullable=True),
        sa.Column("active_version", sa.Integer(), nullable=True),
        sa.Column("error", sa.Text(), nullable=True),
        sa.ForeignKeyConstraint(
            ["frame_id"], ["frames.id"], name=op.f("fk_frame_controller_states_frame_id_frames")
        ),
        sa.PrimaryKeyConstraint("frame_id", name=op.f("pk_frame_controller_states")),
    )
    with op.batch_alter_table("frame_controller_states", schema=None) as batch_op:
        batch_op.create_index(
            batch_op.f("ix_frame_controller_states_robot_id"), ["robot_id"], unique=False
        )


def downgrade() -> None:
    with op.batch_alter_table("frame_controller_states", schema=None) as batch_op:
        batch_op.drop_index(batch_op.f("ix_frame_controller_states_robot_id"))
    op.drop_table("frame_controller_states")
    with op.batch_alter_table("frame_deployments", schema=None) as batch_op:
        batch_op.drop_index("ix_frame_deployments_robot_seq")
        batch_op.drop_index("ix_frame_deployments_frame_seq")
    op.drop_table("frame_deployments")
