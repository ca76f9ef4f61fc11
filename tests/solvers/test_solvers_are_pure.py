"""The solver library imports no web, database or validation framework."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
FORBIDDEN = ("fastapi", "sqlalchemy", "pydantic", "starlette")

SCRIPT = f"""
import importlib, pkgutil, sys
import app.solvers
names = sorted(m.name for m in pkgutil.iter_modules(app.solvers.__path__, "app.solvers."))
for name in names:
    importlib.import_module(name)
bad = sorted(m for m in sys.modules if m.split(".")[0] in {FORBIDDEN!r})
print(",".join(names))
print(",".join(bad))
"""


def test_importing_every_solver_module_pulls_in_no_web_or_db_framework() -> None:
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT],
        cwd=REPO,
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
    ).stdout.splitlines()
    modules, bad = out[0].split(","), [m for m in out[1].split(",") if m]
    assert {"app.solvers.npoint", "app.solvers.quality", "app.solvers.reference"} <= set(modules)
    assert bad == []
