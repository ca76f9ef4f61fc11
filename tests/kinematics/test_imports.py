"""app.kinematics and app.exports are pure libraries: no web, database or pydantic."""

from __future__ import annotations

import subprocess
import sys


def test_kinematics_and_exports_import_no_framework() -> None:
    code = (
        "import sys; import app.kinematics.poses, app.kinematics.presets, app.exports; "
        "bad = [m for m in ('fastapi', 'sqlalchemy', 'pydantic') if m in sys.modules]; "
        "print(bad); sys.exit(1 if bad else 0)"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
