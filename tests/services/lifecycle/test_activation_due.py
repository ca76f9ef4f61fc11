"""The rule that activates a calibration's new version, for any subject: "always" always,
"auto" only accepted and within max_change_mm of the active version, "never" never."""

from __future__ import annotations

import pytest

from app.schemas.tools import Tolerance
from app.services.lifecycle.activation import activation_due

LIMIT = Tolerance(max_change_mm=5.0)


@pytest.mark.parametrize(
    ("activate", "status", "change_mm", "due"),
    [
        ("always", "out_of_tolerance", 50.0, "calibration:always"),
        ("auto", "accepted", None, "calibration:auto"),  # nothing active yet
        ("auto", "accepted", 5.0, "calibration:auto"),  # at the limit: within it
        ("auto", "accepted", 5.01, None),  # held for the change
        ("auto", "out_of_tolerance", 0.1, None),
        ("never", "accepted", 0.0, None),
    ],
)
def test_activation_due(
    activate: str, status: str, change_mm: float | None, due: str | None
) -> None:
    assert activation_due(activate, status, change_mm, LIMIT) == due  # type: ignore[arg-type]
