"""The shape of app/ that issue 28 set, kept by the suite rather than by memory: no function
above a cyclomatic complexity of 15 (radon) or 80 lines, `Any` only at the DBAPI and JSON
boundaries (at most 20 lines), every route handler typed with what it returns, one array type."""

from __future__ import annotations

import ast
import re
from pathlib import Path

from radon.complexity import cc_visit

APP = Path(__file__).resolve().parents[1] / "app"
MAX_COMPLEXITY = 15
MAX_LINES = 80
MAX_ANY_LINES = 20


def _sources() -> list[Path]:
    return sorted(APP.rglob("*.py"))


def test_no_function_above_complexity_15() -> None:
    over = [
        f"{path.relative_to(APP.parent)}:{block.lineno} {block.fullname} ({block.complexity})"
        for path in _sources()
        for block in cc_visit(path.read_text())
        if block.complexity > MAX_COMPLEXITY
    ]
    assert not over, "split these (radon cc -s app):\n" + "\n".join(over)


def test_no_function_above_80_lines() -> None:
    over = [
        f"{path.relative_to(APP.parent)}:{node.lineno} {node.name} "
        f"({(node.end_lineno or node.lineno) - node.lineno + 1} lines)"
        for path in _sources()
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
        and (node.end_lineno or node.lineno) - node.lineno + 1 > MAX_LINES
    ]
    assert not over, "\n".join(over)


def test_any_only_at_the_boundaries() -> None:
    uses = [
        f"{path.relative_to(APP.parent)}:{number}: {line.strip()}"
        for path in _sources()
        for number, line in enumerate(path.read_text().splitlines(), 1)
        if re.search(r"\bAny\b", line) and "import" not in line
    ]
    assert len(uses) <= MAX_ANY_LINES, "\n".join(uses)


def test_no_route_handler_returns_object() -> None:
    untyped = [
        f"{path.relative_to(APP.parent)}:{node.lineno} {node.name}"
        for path in sorted((APP / "api").glob("*.py"))
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
        and (node.returns is None or ast.unparse(node.returns) == "object")
        and any("router." in ast.unparse(d) for d in node.decorator_list)
    ]
    assert not untyped, "\n".join(untyped)


def test_one_float_array_type() -> None:
    defined = [
        str(path.relative_to(APP.parent))
        for path in _sources()
        if re.search(r"^FloatArray\s*=", path.read_text(), re.M)
    ]
    assert defined == ["app/arrays.py"]


def test_every_router_is_in_the_routers_contract() -> None:
    """The import contract "routers import no router" lists its modules by hand (import-linter
    has no "every module but these"): a new router left off it would be free to import one."""
    import tomllib

    pyproject = tomllib.loads((APP.parent / "pyproject.toml").read_text(encoding="utf-8"))
    contracts = pyproject["tool"]["importlinter"]["contracts"]
    listed = next(c["modules"] for c in contracts if c["type"] == "independence")
    routers = [
        f"app.api.{path.stem}"
        for path in sorted((APP / "api").glob("*.py"))
        if re.search(r"^router = APIRouter\(", path.read_text(encoding="utf-8"), re.MULTILINE)
    ]
    assert len(routers) >= 17
    assert sorted(listed) == routers


def test_bench_imports_nothing_of_tests() -> None:
    """A benchmark's harness and ground truth are testbed/'s, which tests import too: a test's
    helper changed for a test does not change what a benchmark measures."""
    offenders = []
    for path in sorted((APP.parent / "bench").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                names = [node.module or ""]
            else:
                continue
            offenders += [
                f"{path.name}:{node.lineno} {name}"
                for name in names
                if name == "tests" or name.startswith("tests.")
            ]
    assert offenders == []


def test_only_the_session_dependency_of_app_api_reaches_storage() -> None:
    """The contract "routers speak HTTP" lists the modules of app.api by hand, all but
    app.api.deps (which opens the request's session): a module added to app.api and left off
    it would be free to import the database."""
    import tomllib

    pyproject = tomllib.loads((APP.parent / "pyproject.toml").read_text(encoding="utf-8"))
    contracts = pyproject["tool"]["importlinter"]["contracts"]
    listed = next(c["source_modules"] for c in contracts if "speak HTTP" in c["name"])
    modules = [
        f"app.api.{path.stem}"
        for path in sorted((APP / "api").glob("*.py"))
        if path.stem not in ("__init__", "deps")
    ]
    assert sorted(listed) == modules


def test_every_list_route_builds_its_page_with_the_shared_wrapper() -> None:
    """A page is built in one place, app.api.shared.page(): no module of app.api constructs
    `Page[...](...)` itself (a route that answers a Response of its own still builds the page
    it serialises there)."""
    by_hand = []
    for path in sorted((APP / "api").glob("*.py")):
        if path.stem == "shared":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Subscript)
                and ast.unparse(node.func.value) == "Page"
            ):
                by_hand.append(f"{path.name}:{node.lineno}")
    assert by_hand == []
