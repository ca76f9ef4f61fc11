"""The controller simulators are written from the vendors' documents, not from the code they
judge: no module under tests/controllers whose name contains ``sim`` imports ``app``, nor
does any module of tests/controllers such a simulator imports (its helpers), however it
imports it (``import app.x``, ``from app import x``, ``from .helper import y``, a call of
``importlib.import_module("app.x")`` or ``__import__("app")``, inside a function too).

A simulator reading what the connector writes with the connector's own parser passes a
mistake the two share (issue 42): this holds each simulator to its own reader."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
CONTROLLERS = ROOT / "tests" / "controllers"
PACKAGE = "tests.controllers"


def simulator_modules() -> list[Path]:
    """Every module under tests/controllers whose name contains ``sim``."""
    return sorted(p for p in CONTROLLERS.rglob("*.py") if "sim" in p.stem)


def imported_names(tree: ast.AST, package: str) -> list[str]:
    """The absolute names of every module `tree` imports (relative imports resolved against
    `package`, the importing module's package); a ``from a import b`` gives ``a`` and
    ``a.b`` (b may be a module)."""
    names: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.extend(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = _resolve(node.module, node.level, package)
            names.append(base)
            names.extend(f"{base}.{alias.name}" for alias in node.names)
        elif isinstance(node, ast.Call) and _is_import_call(node.func) and node.args:
            first = node.args[0]
            if isinstance(first, ast.Constant) and isinstance(first.value, str):
                names.append(first.value)
    return names


def _resolve(module: str | None, level: int, package: str) -> str:
    if level == 0:
        return module or ""
    parts = package.split(".")
    base = parts[: len(parts) - level + 1]
    return ".".join([*base, module] if module else base)


def _is_import_call(func: ast.expr) -> bool:
    if isinstance(func, ast.Name):
        return func.id in ("__import__", "import_module")
    return isinstance(func, ast.Attribute) and func.attr == "import_module"


def _sibling(name: str, root: Path) -> Path | None:
    """The file of a tests.controllers module `name` under `root`, None for any other."""
    if not name.startswith(PACKAGE + "."):
        return None
    path = root.joinpath(*name.split("."))
    if path.with_suffix(".py").is_file():
        return path.with_suffix(".py")
    if (path / "__init__.py").is_file():
        return path / "__init__.py"
    return None


def app_imports(start: Path, root: Path = ROOT) -> list[str]:
    """``module imports app.x`` for every import of app in `start` (a module under `root`)
    and in the tests.controllers modules it reaches by imports, transitively."""
    found: list[str] = []
    seen: set[Path] = set()
    queue = [start]
    while queue:
        path = queue.pop()
        if path in seen:
            continue
        seen.add(path)
        relative = path.relative_to(root).with_suffix("")
        package = ".".join(relative.parts[:-1])
        for name in imported_names(ast.parse(path.read_text(), str(path)), package):
            if name == "app" or name.startswith("app."):
                found.append(f"{relative.as_posix()}.py imports {name}")
            sibling = _sibling(name, root)
            if sibling is not None:
                queue.append(sibling)
    return sorted(set(found))


def test_the_simulators_are_found() -> None:
    names = {p.name for p in simulator_modules()}
    expected = {"kuka_sim.py", "abb_sim.py", "fanuc_sim.py", "yaskawa_sim.py", "techman_sim.py"}
    assert expected | {"simbase.py"} <= names, names


@pytest.mark.parametrize("module", simulator_modules(), ids=lambda p: p.stem)
def test_no_simulator_imports_app(module: Path) -> None:
    assert app_imports(module) == []


def test_the_check_sees_every_way_of_importing_app(tmp_path: Path) -> None:
    """The walker itself: each spelling of an app import, and one reached through a
    sibling helper, is found (a check that finds nothing would pass every simulator)."""
    tree = ast.parse(
        "import app.vendors\n"
        "from app.vendors.kuka.text import parse_struct\n"
        "from app import kinematics\n"
        "def f():\n"
        "    import importlib\n"
        "    importlib.import_module('app.vendors.abb.text')\n"
        "    __import__('app')\n"
        "from . import helpers\n"
        "from .simbase import TcpSimulator\n"
    )
    names = imported_names(tree, PACKAGE)
    assert {
        "app.vendors",
        "app.vendors.kuka.text",
        "app",
        "app.kinematics",
        "app.vendors.abb.text",
        "tests.controllers.helpers",
        "tests.controllers.simbase",
    } <= set(names)
    # A simulator importing a helper that imports app, relatively, is reported through
    # the helper (a copy of the package in tmp_path, planted there).
    package = tmp_path / "tests" / "controllers"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "planted_sim.py").write_text("from .simbase import X\nfrom . import helpers\n")
    (package / "simbase.py").write_text("import socket\n")
    (package / "helpers.py").write_text("import numpy\nfrom app.vendors.tool import ToolData\n")
    assert app_imports(package / "planted_sim.py", tmp_path) == [
        "tests/controllers/helpers.py imports app.vendors.tool",
        "tests/controllers/helpers.py imports app.vendors.tool.ToolData",
    ]
    (package / "helpers.py").write_text("import numpy\n")
    assert app_imports(package / "planted_sim.py", tmp_path) == []
