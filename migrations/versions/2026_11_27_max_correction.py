"""re-check after a collision (issue 41): each tool's tolerance gains max_correction_mm,
the largest deviation a re-check corrects from one touch (default 2.0 mm), written into the
tolerance every tool stores, so that what a tool shows is what a re-check applies

Revision ID: 2026_11_27_max_correction
Revises: 2026_11_27_live_tools
Create Date: 2026-11-27 09:00:00
"""

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "2026_11_27_max_correction"
down_revision: str | None = "2026_11_27_live_tools"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

#: The default of app.schemas.tools.Tolerance.max_correction_mm (a migration keeps its own
#: copy: it must do what it did when it was written, whatever the code says later).
MAX_CORRECTION_MM = 2.0

_TOOLS = sa.table("tools", sa.column("id", sa.String(36)), sa.column("tolerance", sa.JSON()))


def upgrade() -> None:
    bind = op.get_bind()
    for row in bind.execute(sa.select(_TOOLS.c.id, _TOOLS.c.tolerance)).all():
        tolerance = dict(row.tolerance or {})
        if "max_correction_mm" in tolerance:
            continue
        tolerance["max_correction_mm"] = MAX_CORRECTION_MM
        bind.execute(_TOOLS.update().where(_TOOLS.c.id == row.id).values(tolerance=tolerance))


def downgrade() -> None:
    bind = op.get_bind()
    for row in bind.execute(sa.select(_TOOLS.c.id, _TOOLS.c.tolerance)).all():
        tolerance = dict(row.tolerance or {})
        if tolerance.pop("max_correction_mm", None) is None:
            continue
        bind.execute(_TOOLS.update().where(_TOOLS.c.id == row.id).values(tolerance=tolerance))
