"""Simulated touches as API pose lists in any format."""

from __future__ import annotations

from typing import Any

import numpy as np

from app.kinematics.poses import pose_to_format
from testbed.sim.touches import Touches


def as_poses(touches: Touches, fmt: str = "xyz_wxyz") -> list[Any]:
    """The touches' flange poses in `fmt` (default units of that format)."""
    return [pose_to_format(fmt, R, f) for R, f in zip(touches.R, touches.f, strict=True)]


def row_counts(tables: tuple[str, ...]) -> dict[str, int]:
    """Rows in each table, through the app's own engine."""
    from sqlalchemy import text

    from app.storage.db import get_engine

    with get_engine().connect() as conn:
        return {
            t: int(conn.execute(text(f"SELECT count(*) FROM {t}")).scalar_one()) for t in tables
        }


def within(actual: list[float], truth: np.ndarray, sigma: list[float], k: float = 5.0) -> bool:
    """Every axis within k reported sigmas of the truth."""
    return bool(np.all(np.abs(np.asarray(actual) - truth) <= k * np.asarray(sigma)))
