"""Frames and fixed tools (issue 47, contract v1.4 "Frames"): a robot's frames (`frames`),
each a calibrated subject of the one lifecycle with its versions (`frame_versions`) and
activations (`frame_activations`), its calibrations (`frame_calibrations`, with the touched
points and the pointer tool's version) and the fiducials each calibration kept
(`frame_fiducials`). audit_events and outbox name a frame by `frame_id`, as a tool by
`tool_id` (app.storage.models.SUBJECT_KEYS).

Revision ID: 2026_12_02_frames
Revises: 2026_12_02_watch_leases
Create Date: 2026-12-02 04:00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "2026_12_02_frames"
down_revision: str | None = "2026_12_02_watch_leases"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:

    op.create_table(
        "frames",
        sa.Column("id", sa.String(length=36), nullable=False),
        sa.Column("robot_id", sa.String(length=36), nullable=False),
        sa.Column("name", sa.String(length=200), nullable=False),
        sa.Column("kind", sa.String(length=20), nullable=False),
        sa.Column("slot", sa.Integer(), nullable=True),
        sa.Column("controller_symbol", sa.String(length=100), nullable=True),
        sa.Column("description", sa.Text(), nullable=True),
        sa.Column("tolerance", sa.JSON(), nullable=False),
        sa.Column("active_version", sa.Integer(), nullable=True),
        sa.Column("last_version", sa.Integer(), nullable=False),
        sa.Column("revision", sa.Integer(), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("updated_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("archived_at", sa.DateTime(timezone=True), nullable=True),
        sa.Column("drift", sa.JSON(), nullable=True),
        sa.Column("drift_crosses_at", sa.DateTime(timezone=True), nullable=True),
        sa.ForeignKeyConstraint(
            ["robot_id"], ["robots.id"], name=op.f("fk_frames_robot_id_robots")
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_frames")),
    )
    with op.batch_alter_table("frames", schema=None) as batch_op:
        batch_op.create_index(
            "ix_frames_live_created",
            ["created_at", "id"],
            unique=False,
            sqlite_where=sa.text("archived_at IS NULL"),
            postgresql_where=sa.text("archived_at IS NULL"),
        )
        batch_op.create_index(
            "ix_frames_robot_created", ["robot_id", "created_at", "id"], unique=False
        )
        batch_op.create_index(
            "uq_frames_live_name",
            ["robot_id", "name"],
            unique=True,
            sqlite_where=sa.text("archived_at IS NULL"),
            postgresql_where=sa.text("archived_at IS NULL"),
        )
        batch_op.create_index(
            "uq_frames_live_slot",
            ["robot_id", "slot"],
            unique=True,
            sqlite_where=sa.text("archived_at IS NULL AND slot IS NOT NULL"),
            postgresql_where=sa.text("archived_at IS NULL AND slot IS NOT NULL"),
        )

    op.create_table(
        "frame_activations",
        sa.Column(
            "id",
            sa.BigInteger().with_variant(sa.Integer(), "sqlite"),
            autoincrement=True,
            nullable=False,
        ),
        sa.Column("frame_id", sa.String(length=36), nullable=False),
        sa.Column("version", sa.Integer(), nullable=False),
        sa.Column("previous_version", sa.Integer(), nullable=True),
        sa.Column("reason", sa.String(length=40), nullable=False),
        sa.Column("reason_text", sa.String(length=500), nullable=True),
        sa.Column("activated_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("activated_by", sa.String(length=200), nullable=False),
        sa.ForeignKeyConstraint(
            ["frame_id"], ["frames.id"], name=op.f("fk_frame_activations_frame_id_frames")
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_frame_activations")),
    )
    with op.batch_alter_table("frame_activations", schema=None) as batch_op:
        batch_op.create_index("ix_frame_activations_frame_seq", ["frame_id", "id"], unique=False)

    op.create_table(
        "frame_calibrations",
        sa.Column("id", sa.String(length=36), nullable=False),
        sa.Column("frame_id", sa.String(length=36), nullable=False),
        sa.Column("method", sa.String(length=40), nullable=False),
        sa.Column("status", sa.String(length=40), nullable=False),
        sa.Column("request", sa.JSON(), nullable=False),
        sa.Column("result", sa.JSON(), nullable=False),
        sa.Column("version", sa.Integer(), nullable=True),
        sa.Column("touches", sa.JSON(), nullable=True),
        sa.Column("points_mm", sa.JSON(), nullable=False),
        sa.Column("pointer_tool_id", sa.String(length=36), nullable=True),
        sa.Column("pointer_version", sa.Integer(), nullable=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("created_by", sa.String(length=200), nullable=False),
        sa.ForeignKeyConstraint(
            ["frame_id"], ["frames.id"], name=op.f("fk_frame_calibrations_frame_id_frames")
        ),
        sa.ForeignKeyConstraint(
            ["pointer_tool_id"],
            ["tools.id"],
            name=op.f("fk_frame_calibrations_pointer_tool_id_tools"),
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_frame_calibrations")),
    )
    with op.batch_alter_table("frame_calibrations", schema=None) as batch_op:
        batch_op.create_index(
            "ix_frame_calibrations_frame_created", ["frame_id", "created_at", "id"], unique=False
        )

    op.create_table(
        "frame_fiducials",
        sa.Column(
            "id",
            sa.BigInteger().with_variant(sa.Integer(), "sqlite"),
            autoincrement=True,
            nullable=False,
        ),
        sa.Column("frame_id", sa.String(length=36), nullable=False),
        sa.Column("calibration_id", sa.String(length=36), nullable=False),
        sa.Column("seq", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(length=100), nullable=False),
        sa.Column("nominal_mm", sa.JSON(), nullable=False),
        sa.Column("point_mm", sa.JSON(), nullable=False),
        sa.ForeignKeyConstraint(
            ["calibration_id"],
            ["frame_calibrations.id"],
            name=op.f("fk_frame_fiducials_calibration_id_frame_calibrations"),
        ),
        sa.ForeignKeyConstraint(
            ["frame_id"], ["frames.id"], name=op.f("fk_frame_fiducials_frame_id_frames")
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_frame_fiducials")),
        sa.UniqueConstraint("calibration_id", "name", name="uq_frame_fiducials_calibration_name"),
    )
    with op.batch_alter_table("frame_fiducials", schema=None) as batch_op:
        batch_op.create_index(
            "ix_frame_fiducials_frame", ["frame_id", "calibration_id", "seq"], unique=False
        )

    op.create_table(
        "frame_versions",
        sa.Column("id", sa.String(length=36), nullable=False),
        sa.Column("frame_id", sa.String(length=36), nullable=False),
        sa.Column("version", sa.Integer(), nullable=False),
        sa.Column("position_mm", sa.JSON(), nullable=False),
        sa.Column("quaternion", sa.JSON(), nullable=False),
        sa.Column("source", sa.String(length=40), nullable=False),
        sa.Column("status", sa.String(length=40), nullable=False),
        sa.Column("calibration_id", sa.String(length=36), nullable=True),
        sa.Column("note", sa.Text(), nullable=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("created_by", sa.String(length=200), nullable=False),
        sa.ForeignKeyConstraint(
            ["calibration_id"],
            ["frame_calibrations.id"],
            name=op.f("fk_frame_versions_calibration_id_frame_calibrations"),
        ),
        sa.ForeignKeyConstraint(
            ["frame_id"], ["frames.id"], name=op.f("fk_frame_versions_frame_id_frames")
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_frame_versions")),
        sa.UniqueConstraint("frame_id", "version", name="uq_frame_versions_frame_version"),
    )
    with op.batch_alter_table("audit_events", schema=None) as batch_op:
        batch_op.add_column(sa.Column("frame_id", sa.String(length=36), nullable=True))
        batch_op.create_index("ix_audit_events_frame", ["frame_id", "id"], unique=False)
        batch_op.create_index(
            "ix_audit_events_frame_action", ["frame_id", "action", "id"], unique=False
        )

    with op.batch_alter_table("outbox", schema=None) as batch_op:
        batch_op.add_column(sa.Column("frame_id", sa.String(length=36), nullable=True))


def downgrade() -> None:

    with op.batch_alter_table("outbox", schema=None) as batch_op:
        batch_op.drop_column("frame_id")

    with op.batch_alter_table("audit_events", schema=None) as batch_op:
        batch_op.drop_index("ix_audit_events_frame_action")
        batch_op.drop_index("ix_audit_events_frame")
        batch_op.drop_column("frame_id")

    op.drop_table("frame_versions")
    with op.batch_alter_table("frame_fiducials", schema=None) as batch_op:
        batch_op.drop_index("ix_frame_fiducials_frame")

    op.drop_table("frame_fiducials")
    with op.batch_alter_table("frame_calibrations", schema=None) as batch_op:
        batch_op.drop_index("ix_frame_calibrations_frame_created")

    op.drop_table("frame_calibrations")
    with op.batch_alter_table("frame_activations", schema=None) as batch_op:
        batch_op.drop_index("ix_frame_activations_frame_seq")

    op.drop_table("frame_activations")
    with op.batch_alter_table("frames", schema=None) as batch_op:
        batch_op.drop_index(
            "uq_frames_live_slot",
            sqlite_where=sa.text("archived_at IS NULL AND slot IS NOT NULL"),
            postgresql_where=sa.text("archived_at IS NULL AND slot IS NOT NULL"),
        )
        batch_op.drop_index(
            "uq_frames_live_name",
            sqlite_where=sa.text("archived_at IS NULL"),
            postgresql_where=sa.text("archived_at IS NULL"),
        )
        batch_op.drop_index("ix_frames_robot_created")
        batch_op.drop_index(
            "ix_frames_live_created",
            sqlite_where=sa.text("archived_at IS NULL"),
            postgresql_where=sa.text("archived_at IS NULL"),
        )

    op.drop_table("frames")
