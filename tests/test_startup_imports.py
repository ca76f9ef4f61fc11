"""What a tcpcal process imports as it starts: the test suite starts about a hundred of them
(server workers, their solver forkservers, publishers), each paying its imports in CPU.

These modules are imported where they are used, not at start: scipy.stats (the solvers take
their quantiles from scipy.special, app.solvers.distributions), scipy.optimize (the fits; the
solver processes preload it), alembic and Mako (app.storage.migrate), httpx (the client commands).
"""

from __future__ import annotations

import json
import subprocess
import sys

#: Top-level packages and subpackages reported by the child process.
_WATCHED = ("scipy", "numpy", "alembic", "mako", "httpx", "httpcore")


def _imported_by(code: str) -> set[str]:
    """The watched modules in sys.modules after a fresh interpreter runs `code`."""
    report = (
        "import json, sys\n"
        f"print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in {_WATCHED!r})))"
    )
    done = subprocess.run(
        [sys.executable, "-c", f"{code}\n{report}"],
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
    )
    modules: list[str] = json.loads(done.stdout.splitlines()[-1])
    return set(modules)


def test_a_server_worker_does_not_import_what_it_does_not_serve_with() -> None:
    modules = _imported_by("import app.cli, app.main")
    assert "scipy.spatial" in modules  # the check watches what it should
    unwanted = {"scipy.stats", "scipy.optimize", "alembic", "mako", "httpx", "httpcore"}
    assert not modules & unwanted


def test_the_solver_preload_imports_what_the_fits_use() -> None:
    modules = _imported_by(
        "import importlib\n"
        "from app.main import SOLVER_PRELOAD\n"
        "for name in SOLVER_PRELOAD:\n"
        "    importlib.import_module(name)"
    )
    assert "scipy.optimize" in modules
    assert "scipy.stats" not in modules


def test_the_controller_schemas_and_connectors_import_no_numeric_core() -> None:
    """The makers' registry declares them and loads their modules on first use: importing
    it (for the ports, the tool numbers, the stored words) ran no exporter and no scipy.spatial
    in whatever touched a controller's schema or connector interface, and no protocol client."""
    modules = _imported_by(
        "import app.vendors.connector, app.schemas.controllers, app.vendors.registry"
    )
    assert "scipy" not in modules
    assert "httpx" not in modules


def test_the_rows_import_no_numeric_core() -> None:
    """The words the rows are typed with are plain data (app.words: pose formats and
    algorithms too), so `tcpcal db upgrade`, a backup and the key check read and write rows
    without importing numpy and scipy."""
    modules = _imported_by(
        "import app.storage.models, app.storage.migrate, app.storage.backup, app.security.auth"
    )
    assert {m.split(".")[0] for m in modules} & {"numpy", "scipy"} == set()
