"""robot controllers, deployments, per-tool controller state, tools.controller_symbol

Revision ID: 2026_11_24_controllers
Revises: 2026_11_24_activation_reason
Create Date: 2026-11-24 05:30:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op


revision: str = "2026_11_24_controllers"
down_revision: str | None = "2026_11_24_activation_reason"  # chained after i24-activation (merged)
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

AutoId = sa.BigInteger().with_variant(sa.Integer(), "sqlite")


def upgrade() -> None:
    with op.batch_alter_table("tools", schema=None) as batch_op:
        batch_op.add_column(sa.Column("controller_symbol", sa.String(length=100), nullable=True))
    op.create_table(
        "robot_controllers",
        sa.Column("robot_id", sa.String(length=36), nullable=False),
        sa.Column("protocol", sa.String(length=20), nullable=False),
        sa.Column("host", sa.String(length=253), nullable=False),
        sa.Column("port", sa.Integer(), nullable=False),
        sa.Column("username", sa.String(length=200), nullable=True),
        sa.Column("password_encrypted", sa.Text(), nullable=True),
        sa.Column("timeout_s", sa.Float(), nullable=False),
        sa.Column("tls_verify", sa.Boolean(), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("updated_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ["robot_id"], ["robots.id"], name=op.f("fk_robot_controllers_robot_id_robots")
        ),
        sa.PrimaryKeyConstraint("robot_id", name=op.f("pk_robot_controllers")),
    )
    op.create_table(
        "deployments",
        sa.Column("id", AutoId, autoincrement=True, nullable=False),
        sa.Column("tool_id", sa.String(length=36), nullable=False),
        sa.Column("robot_id", sa.String(length=36), nullable=False),
        sa.Column("version", sa.Integer(), nullable=False),
        sa.Column("protocol", sa.String(length=20), nullable=False),
        sa.Column("target", sa.String(length=300), nullable=False),
        sa.Column("status", sa.String(length=20), nullable=False),
        sa.Column("previous", sa.JSON(), nullable=True),
        sa.Column("read_back", sa.JSON(), nullable=True),
        sa.Column("deviation_mm", sa.Float(), nullable=True),
        sa.Column("deviation_deg", sa.Float(), nullable=True),
        sa.Column("error", sa.JSON(), nullable=True),
        sa.Column("actor", sa.String(length=200), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ["tool_id"], ["tools.id"], name=op.f("fk_deployments_tool_id_tools")
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_deployments")),
    )
    op.create_index("ix_deployments_tool_seq", "deployments", ["tool_id", "id"], unique=False)
    op.create_table(
        "tool_controller_states",
        sa.Column("tool_id", sa.String(length=36), nullable=False),
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
            ["tool_id"], ["tools.id"], name=op.f("fk_tool_controller_states_tool_id_tools")
        ),
        sa.PrimaryKeyConstraint("tool_id", name=op.f("pk_tool_controller_states")),
    )
    op.create_index(
        op.f("ix_tool_controller_states_robot_id"),
        "tool_controller_states",
        ["robot_id"],
        unique=False,
    )


def downgrade() -> None:
    op.drop_index(
        op.f("ix_tool_controller_states_robot_id"), table_name="tool_controller_states"
    )
    op.drop_table("tool_controller_states")
    op.drop_index("ix_deployments_tool_seq", table_name="deployments")
    op.drop_table("deployments")
    op.drop_table("robot_controllers")
    with op.batch_alter_table("tools", schema=None) as batch_op:
        batch_op.drop_column("controller_symbol")
