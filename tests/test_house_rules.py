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


def _called_names(tree: ast.AST) -> list[tuple[int, str]]:
    """(line, name) of every call of a bare or dotted name."""
    calls = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            func = node.func
            name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
            calls.append((node.lineno, name))
    return calls


def _imported_names(tree: ast.AST) -> set[str]:
    return {
        alias.name
        for node in ast.walk(tree)
        if isinstance(node, ast.ImportFrom | ast.Import)
        for alias in node.names
    } | {
        node.module
        for node in ast.walk(tree)
        if isinstance(node, ast.ImportFrom) and node.module is not None
    }


def test_every_router_reaches_its_use_case_through_one_runner() -> None:
    """One way into a transaction (issue 46): a route takes the request's session
    (SessionDep) or, when its use case blocks on a controller, hands the use case to
    app.api.deps.run_blocking, the one call of the thread pool; it never opens a transaction,
    limits one to the caller's cells, or reaches the thread pool by itself, and never wraps
    its use case in a lambda (whose arguments mypy cannot check against the use case's)."""
    own = {"session_scope", "act_for", "transaction_for", "run_in_threadpool", "run_sync"}
    strays = []
    blocking = 0
    for path in sorted((APP / "api").glob("*.py")):
        if path.name == "deps.py":
            continue
        tree = ast.parse(path.read_text())
        where = path.relative_to(APP.parent)
        strays += [f"{where}: imports {name}" for name in sorted(_imported_names(tree) & own)]
        strays += [
            f"{where}: imports {name}"
            for name in sorted(_imported_names(tree))
            if name in {"starlette.concurrency", "anyio.to_thread"}
        ]
        strays += [
            f"{where}:{line} calls {name}" for line, name in _called_names(tree) if name in own
        ]
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and getattr(node.func, "id", "") == "run_blocking":
                blocking += 1
                if any(isinstance(arg, ast.Lambda) for arg in node.args):
                    strays.append(f"{where}:{node.lineno} hands run_blocking a lambda")
    assert not strays, "\n".join(strays)
    assert blocking >= 5  # the capture, reconcile, deployment, touch and check routes


def test_a_use_case_acts_for_its_caller_through_one_transaction() -> None:
    """Every transaction a use case opens for a caller is app.security.auth.transaction_for
    (the session, limited to the caller's cells), and a request's session is limited by
    `authenticate`: act_for is called nowhere else, so no transaction is opened for a caller
    and left to find every cell's robots."""
    calls = [
        f"{path.relative_to(APP.parent)}:{line}"
        for path in _sources()
        if path != APP / "security" / "auth.py"
        for line, name in _called_names(ast.parse(path.read_text()))
        if name == "act_for"
    ]
    assert calls == []
    auth = ast.parse((APP / "security" / "auth.py").read_text())
    assert sorted(name for _, name in _called_names(auth) if name == "act_for") == ["act_for"] * 2
