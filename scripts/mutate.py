"""Mutation testing: plant one mistake at a time in a module and see whether its tests notice.

    nice -n 10 .venv/bin/python scripts/mutate.py \\
        --target 'app/solvers/npoint/=tests/solvers/test_npoint.py' \\
        --target 'app/kinematics/poses.py=tests/kinematics/test_poses.py' \\
        --n 35 --seed 51 --json mutants.json

A target is MODULE=TESTS: MODULE a .py file, a directory or several joined by commas (its
mutants are pooled),
TESTS what pytest is given (files, node ids, `-k` expressions: split on spaces). For each target
the script lists every mutant it can make (below), ranks them by a hash of the seed and the
mutant's key and tries the first N. The key names the file, the enclosing function, the kind
of mutation and the source text mutated (not the line number), so the same seed tries the same
mutants after unrelated lines moved, and a "before" and an "after" run compare.

Mutations: an operator swapped (+ -, * /, // *, ** *, < <=, > >=, == !=, is / is not,
in / not in, and / or, a `not` or a unary minus removed, in expressions and `x op= y`),
a constant nudged (0 -> 1, n -> n + 1, 1 -> 0, a float x -> 0.0 and 2x (0.0 -> 1.0), True <->
False), `return x` -> `return None`, a `raise` deleted, the first two positional arguments of a
call swapped, a statement deleted (a call's statement, an assignment to an attribute or an item,
`x op= y`). Annotations, docstrings and `if TYPE_CHECKING:` blocks are left alone. Each mutant is
checked to parse and to differ from the original's syntax tree.

It works on a copy of the tree (in a temporary directory, `.venv` linked; tracked and untracked
files, not .git): the worktree is never written, so a Ctrl-C or a kill leaves it as it was, and
other tests may run in it meanwhile. The copy's file is restored after each mutant (in a
`finally`) all the same. Each mutant runs `python -m pytest -x -q -p no:cacheprovider -n 0
TESTS` in the copy (PYTHONPATH the copy, so child processes import the mutant
too; PYTHONDONTWRITEBYTECODE set, so no stale .pyc of a same-sized mutant is read) under a
timeout; a mutant is killed when pytest fails (exit 1), errs (collection, import: exit 2-4) or
times out (the test process group is killed: `killed by timeout`, counted killed and shown apart:
a mutant that makes a loop run forever is caught only by the clock). The unmutated tests run
first and must pass (and set the default timeout: 3x their time + 30 s).

The table gives killed/tried per target, then each survivor's id, file:line and diff. A survivor
whose id is in scripts/mutants_equivalent.md (a line "- `ID` file:line: the reason it is
equivalent") is shown as equivalent with that reason, and the score is given with and without
them. --json writes every mutant tried (id, target, file, line, kind, outcome, seconds, diff).
--list prints the sampled mutants without running anything; --only ID runs those mutants alone.
"""

from __future__ import annotations

import argparse
import ast
import difflib
import hashlib
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
EQUIVALENT_FILE = REPO / "scripts" / "mutants_equivalent.md"
SKIP_COPY = {".git", ".venv", "__pycache__", "node_modules", ".mypy_cache", ".ruff_cache"}

BINOP = {
    ast.Add: (ast.Sub, "+", "-"),
    ast.Sub: (ast.Add, "-", "+"),
    ast.Mult: (ast.Div, "*", "/"),
    ast.Div: (ast.Mult, "/", "*"),
    ast.FloorDiv: (ast.Mult, "//", "*"),
    ast.Pow: (ast.Mult, "**", "*"),
    ast.Mod: (ast.FloorDiv, "%", "//"),
}
CMPOP = {
    ast.Lt: ("<", "<="),
    ast.LtE: ("<=", "<"),
    ast.Gt: (">", ">="),
    ast.GtE: (">=", ">"),
    ast.Eq: ("==", "!="),
    ast.NotEq: ("!=", "=="),
    ast.Is: ("is", "is not"),
    ast.IsNot: ("is not", "is"),
    ast.In: ("in", "not in"),
    ast.NotIn: ("not in", "in"),
}
# The token of each operator, alone: `*` not part of `**`, `<` not of `<=`, `in` a word.
TOKEN_RE = {
    "+": r"(?<![+=])\+(?!=)",
    "-": r"(?<![-=])-(?![=>])",
    "*": r"(?<!\*)\*(?![*=])",
    "/": r"(?<!/)/(?![/=])",
    "//": r"//(?!=)",
    "**": r"\*\*(?!=)",
    "%": r"%(?!=)",
    "<": r"<(?![=<])",
    "<=": r"<=",
    ">": r">(?![=>])",
    ">=": r">=",
    "==": r"==",
    "!=": r"!=",
    "is": r"\bis\b(?!\s+not\b)",
    "is not": r"\bis\s+not\b",
    "in": r"(?<!not )\bin\b",
    "not in": r"\bnot\s+in\b",
    "and": r"\band\b",
    "or": r"\bor\b",
}


@dataclass
class Mutant:
    """One planted mistake: a byte range of one file replaced."""

    id: str
    target: str
    file: str
    line: int
    kind: str
    start: int
    end: int
    replacement: bytes = field(repr=False)
    key: str = field(repr=False, default="")

    def apply(self, source: bytes) -> bytes:
        return source[: self.start] + self.replacement + source[self.end :]


@dataclass
class Outcome:
    id: str
    target: str
    file: str
    line: int
    kind: str
    outcome: str  # killed | error | timeout | survived
    seconds: float
    diff: str
    equivalent: str | None = None


class _Source:
    """A file's bytes with line starts, to turn ast positions (UTF-8 byte columns) into offsets."""

    def __init__(self, data: bytes) -> None:
        self.data = data
        self.starts = [0]
        for i, b in enumerate(data):
            if b == 0x0A:
                self.starts.append(i + 1)

    def offset(self, line: int, col: int) -> int:
        return self.starts[line - 1] + col

    def span(self, node: ast.AST) -> tuple[int, int]:
        return (
            self.offset(node.lineno, node.col_offset),  # type: ignore[attr-defined]
            self.offset(node.end_lineno, node.end_col_offset),  # type: ignore[attr-defined]
        )

    def text(self, node: ast.AST) -> bytes:
        a, b = self.span(node)
        return self.data[a:b]


def _is_docstring(node: ast.AST, parent: ast.AST | None) -> bool:
    body = getattr(parent, "body", None)
    return (
        isinstance(node, ast.Expr)
        and isinstance(node.value, ast.Constant)
        and isinstance(node.value.value, str)
        and isinstance(body, list)
        and bool(body)
        and body[0] is node
    )


class _Collector(ast.NodeVisitor):
    """Walks one module and yields (node, kind, start, end, replacement) candidates."""

    def __init__(self, src: _Source) -> None:
        self.src = src
        self.scope: list[str] = []
        self.found: list[tuple[str, int, str, int, int, bytes, bytes]] = []
        self.parents: list[ast.AST] = []

    # -- traversal -----------------------------------------------------------------------------
    def generic_visit(self, node: ast.AST) -> None:
        self.parents.append(node)
        for name, value in ast.iter_fields(node):
            if name in {"annotation", "returns"}:
                continue  # annotations do nothing at run time (from __future__ import annotations)
            items = value if isinstance(value, list) else [value]
            for item in items:
                if isinstance(item, ast.AST):
                    self.visit(item)
        self.parents.pop()

    def _scoped(self, node: ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef) -> None:
        self.scope.append(node.name)
        for deco in node.decorator_list:
            self.visit(deco)
        for stmt in node.body:
            self.visit(stmt)
        if not isinstance(node, ast.ClassDef):
            self.parents.append(node)
            for default in [*node.args.defaults, *node.args.kw_defaults]:
                if default is not None:
                    self.visit(default)
            self.parents.pop()
        self.scope.pop()

    def visit_FunctionDef(self, node: ast.FunctionDef) -> None:
        self.parents.append(node)
        self._scoped(node)
        self.parents.pop()

    def visit_AsyncFunctionDef(self, node: ast.AsyncFunctionDef) -> None:
        self.parents.append(node)
        self._scoped(node)
        self.parents.pop()

    def visit_ClassDef(self, node: ast.ClassDef) -> None:
        self.parents.append(node)
        self._scoped(node)
        self.parents.pop()

    def visit_If(self, node: ast.If) -> None:
        test = node.test
        name = test.id if isinstance(test, ast.Name) else getattr(test, "attr", None)
        if name == "TYPE_CHECKING":
            return
        self.generic_visit(node)

    def visit_Expr(self, node: ast.Expr) -> None:
        parent = self.parents[-1] if self.parents else None
        if _is_docstring(node, parent) or (
            isinstance(node.value, ast.Constant) and node.value.value is Ellipsis
        ):
            return
        if isinstance(node.value, ast.Call | ast.Await):
            self._statement(node, "statement deleted")
        self.generic_visit(node)

    def visit_Assign(self, node: ast.Assign) -> None:
        if any(isinstance(t, ast.Attribute | ast.Subscript) for t in node.targets):
            self._statement(node, "statement deleted")
        self.generic_visit(node)

    def visit_AugAssign(self, node: ast.AugAssign) -> None:
        self._statement(node, "statement deleted")
        swap = BINOP.get(type(node.op))
        if swap:
            a = self.src.span(node.target)[1]
            b = self.src.span(node.value)[0]
            self._token(node, a, b, swap[1] + "=", swap[2] + "=", re.escape(swap[1]) + "=")
        self.generic_visit(node)

    def visit_Raise(self, node: ast.Raise) -> None:
        self._statement(node, "raise deleted")
        self.generic_visit(node)

    def visit_Return(self, node: ast.Return) -> None:
        value = node.value
        if value is not None and not (isinstance(value, ast.Constant) and value.value is None):
            a, b = self.src.span(value)
            self._add(node, "return None", a, b, b"None")
        self.generic_visit(node)

    # -- expressions -----------------------------------------------------------------------------
    def visit_BinOp(self, node: ast.BinOp) -> None:
        swap = BINOP.get(type(node.op))
        if swap:
            a = self.src.span(node.left)[1]
            b = self.src.span(node.right)[0]
            self._token(node, a, b, swap[1], swap[2], TOKEN_RE[swap[1]])
        self.generic_visit(node)

    def visit_Compare(self, node: ast.Compare) -> None:
        left = node.left
        for op, right in zip(node.ops, node.comparators, strict=True):
            old, new = CMPOP[type(op)]
            a = self.src.span(left)[1]
            b = self.src.span(right)[0]
            self._token(node, a, b, old, new, TOKEN_RE[old])
            left = right
        self.generic_visit(node)

    def visit_BoolOp(self, node: ast.BoolOp) -> None:
        old, new = ("and", "or") if isinstance(node.op, ast.And) else ("or", "and")
        for left, right in zip(node.values, node.values[1:], strict=False):
            a = self.src.span(left)[1]
            b = self.src.span(right)[0]
            self._token(node, a, b, old, new, TOKEN_RE[old])
        self.generic_visit(node)

    def visit_UnaryOp(self, node: ast.UnaryOp) -> None:
        if isinstance(node.op, ast.Not | ast.USub):
            a, b = self.src.span(node)
            kind = "not removed" if isinstance(node.op, ast.Not) else "unary minus removed"
            operand = self.src.text(node.operand)
            if isinstance(node.operand, ast.BoolOp | ast.BinOp | ast.Compare):
                operand = b"(" + operand + b")"
            self._add(node, kind, a, b, operand)
        self.generic_visit(node)

    def visit_Constant(self, node: ast.Constant) -> None:
        value = node.value
        news: list[object] = []
        if isinstance(value, bool):
            news = [not value]
        elif isinstance(value, int):
            news = [value + 1] if value != 1 else [0, 2]
        elif isinstance(value, float):
            news = [1.0] if value == 0.0 else [0.0, value * 2]
        a, b = self.src.span(node)
        for new in news:
            self._add(node, f"constant {value!r} -> {new!r}", a, b, repr(new).encode())

    def visit_JoinedStr(self, node: ast.JoinedStr) -> None:
        # Positions inside f-strings are unreliable before Python 3.12; mutate what is checkable.
        self.generic_visit(node)

    def visit_Call(self, node: ast.Call) -> None:
        args = node.args
        if len(args) >= 2 and not any(isinstance(x, ast.Starred) for x in args[:2]):
            first, second = self.src.text(args[0]), self.src.text(args[1])
            if first != second:
                a = self.src.span(args[0])[0]
                b = self.src.span(args[1])[1]
                between = self.src.data[self.src.span(args[0])[1] : self.src.span(args[1])[0]]
                self._add(node, "arguments swapped", a, b, second + between + first)
        self.generic_visit(node)

    # -- recording -------------------------------------------------------------------------------
    def _statement(self, node: ast.stmt, kind: str) -> None:
        a, b = self.src.span(node)
        self._add(node, kind, a, b, b"pass")

    def _token(self, node: ast.AST, a: int, b: int, old: str, new: str, pattern: str) -> None:
        gap = self.src.data[a:b].decode()
        code = gap.split("#", 1)[0]
        hits = list(re.finditer(pattern, code))
        if len(hits) != 1:
            return
        hit = hits[0]
        start = a + len(code[: hit.start()].encode())
        end = a + len(code[: hit.end()].encode())
        self._add(node, f"{old} -> {new}", start, end, new.encode())

    def _add(self, node: ast.AST, kind: str, a: int, b: int, replacement: bytes) -> None:
        text = self.src.text(node)
        if isinstance(node, ast.expr) and not _same_expression(text, node):
            return  # the position does not name the node's text (an f-string's inside, < 3.12)
        self.found.append(
            (".".join(self.scope), node.lineno, kind, a, b, replacement, text)  # type: ignore[attr-defined]
        )


def _same_expression(text: bytes, node: ast.expr) -> bool:
    try:
        parsed = ast.parse(b"(" + text + b")", mode="eval").body
    except SyntaxError:
        return False
    return ast.dump(parsed) == ast.dump(node)


def _parses_differently(original: ast.Module, data: bytes) -> bool:
    try:
        tree = ast.parse(data)
    except SyntaxError:
        return False
    return ast.dump(tree) != ast.dump(original)


def mutants_of(path: Path, target: str) -> list[Mutant]:
    """Every mutant of one file (checked: each parses and differs from the original)."""
    rel = path.resolve().relative_to(REPO).as_posix()
    data = path.read_bytes()
    tree = ast.parse(data)
    collector = _Collector(_Source(data))
    collector.visit(tree)
    seen: dict[str, int] = {}
    out: list[Mutant] = []
    for scope, line, kind, a, b, replacement, text in collector.found:
        base = f"{rel}|{scope}|{kind}|{text.decode(errors='replace')}|{data[a:b]!r}"
        seen[base] = seen.get(base, 0) + 1
        key = f"{base}|{seen[base]}"
        mutant = Mutant(
            id=hashlib.sha1(key.encode()).hexdigest()[:10],
            target=target,
            file=rel,
            line=data[:a].count(b"\n") + 1 if kind != "statement deleted" else line,
            kind=kind,
            start=a,
            end=b,
            replacement=replacement,
            key=key,
        )
        if _parses_differently(tree, mutant.apply(data)):
            out.append(mutant)
    return out


def _files(module: str) -> list[Path]:
    """A target's files: MODULE is a .py file, a directory, or several joined by commas."""
    found: list[Path] = []
    for part in module.split(","):
        path = (REPO / part.strip()).resolve()
        if path.is_dir():
            found += sorted(p for p in path.rglob("*.py") if "__pycache__" not in p.parts)
        elif path.suffix == ".py" and path.is_file():
            found.append(path)
        else:
            raise SystemExit(f"mutate: {part} is neither a .py file nor a directory of them")
    return found


def sample(module: str, n: int, seed: int) -> list[Mutant]:
    """The first n mutants of a module ranked by sha1(seed, key): stable under moved lines."""
    every = [m for f in _files(module) for m in mutants_of(f, module)]
    ranked = sorted(every, key=lambda m: hashlib.sha1(f"{seed}|{m.key}".encode()).hexdigest())
    chosen = ranked[:n]
    return sorted(chosen, key=lambda m: (m.file, m.start, m.kind))


def diff_of(mutant: Mutant, original: bytes) -> str:
    old = original.decode().splitlines(keepends=True)
    new = mutant.apply(original).decode().splitlines(keepends=True)
    lines = difflib.unified_diff(old, new, mutant.file, mutant.file, n=0)
    return "".join(x for x in lines if not x.startswith(("---", "+++")))


def equivalents() -> dict[str, str]:
    """The ids scripts/mutants_equivalent.md explains, with their sentences."""
    if not EQUIVALENT_FILE.exists():
        return {}
    found: dict[str, str] = {}
    for line in EQUIVALENT_FILE.read_text().splitlines():
        match = re.match(r"^- `([0-9a-f]{10})` \S+:\d+[^:]*: (.+)$", line)
        if match:
            found[match.group(1)] = match.group(2).strip()
    return found


# -- running ----------------------------------------------------------------------------------
def _copy_tree(dest: Path) -> None:
    def ignore(_dir: str, names: list[str]) -> set[str]:
        return {n for n in names if n in SKIP_COPY or n.endswith(".pyc")}

    shutil.copytree(REPO, dest, ignore=ignore, symlinks=True)
    venv = REPO / ".venv"
    if venv.exists():
        (dest / ".venv").symlink_to(venv)


def _env(copy: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(copy) + (os.pathsep + env["PYTHONPATH"] if "PYTHONPATH" in env else "")
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    env["PYTHONHASHSEED"] = "0"
    return env


def run_tests(copy: Path, tests: list[str], timeout: float, extra: list[str]) -> tuple[str, float]:
    """pytest in the copy: 'passed', 'killed' (failed), 'error' (exit 2-5) or 'timeout'."""
    cmd = [
        sys.executable,
        "-m",
        "pytest",
        "-x",
        "-q",
        "-p",
        "no:cacheprovider",
        "-n",
        "0",
        *extra,
        *tests,
    ]
    started = time.monotonic()
    proc = subprocess.Popen(
        cmd,
        cwd=copy,
        env=_env(copy),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    try:
        rc = proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        return "timeout", time.monotonic() - started
    except BaseException:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        raise
    seconds = time.monotonic() - started
    if rc == 0:
        return "passed", seconds
    return ("killed" if rc == 1 else "error"), seconds


def _check_import(copy: Path) -> None:
    probe = "import app, sys; sys.stdout.write(app.__file__)"
    where = subprocess.run(
        [sys.executable, "-c", probe], cwd=copy, env=_env(copy), capture_output=True, text=True
    ).stdout
    if not where.startswith(str(copy)):
        raise SystemExit(f"mutate: the copy imports app from {where}, not from {copy}")


def run_target(
    copy: Path, target: str, mutants: list[Mutant], tests: list[str], args: argparse.Namespace
) -> list[Outcome]:
    baseline, took = run_tests(copy, tests, 1800.0, args.pytest_arg)
    if baseline != "passed":
        raise SystemExit(f"mutate: the unmutated tests of {target} did not pass ({baseline})")
    timeout = args.timeout or 3 * took + 30
    print(f"{target}: tests pass unmutated in {took:.1f} s; timeout {timeout:.0f} s", flush=True)
    known = equivalents()
    outcomes: list[Outcome] = []
    for i, mutant in enumerate(mutants, 1):
        path = copy / mutant.file
        original = path.read_bytes()
        try:
            path.write_bytes(mutant.apply(original))
            result, seconds = run_tests(copy, tests, timeout, args.pytest_arg)
        finally:
            path.write_bytes(original)
        result = "survived" if result == "passed" else result
        outcome = Outcome(
            mutant.id,
            target,
            mutant.file,
            mutant.line,
            mutant.kind,
            result,
            round(seconds, 1),
            diff_of(mutant, original),
            known.get(mutant.id) if result == "survived" else None,
        )
        outcomes.append(outcome)
        print(
            f"  [{i}/{len(mutants)}] {mutant.id} {mutant.file}:{mutant.line} {mutant.kind}: "
            f"{result} ({seconds:.1f} s)",
            flush=True,
        )
    return outcomes


def report(outcomes: list[Outcome]) -> str:
    lines = ["", "target | killed/tried | by failure | by error | by timeout | equivalent"]
    lines.append("---|---|---|---|---|---")
    targets = list(dict.fromkeys(o.target for o in outcomes))
    for target in targets:
        mine = [o for o in outcomes if o.target == target]
        killed = [o for o in mine if o.outcome != "survived"]
        equiv = [o for o in mine if o.outcome == "survived" and o.equivalent]
        count = {k: sum(o.outcome == k for o in mine) for k in ("killed", "error", "timeout")}
        share = f"{len(killed)}/{len(mine)} ({100 * len(killed) / max(len(mine), 1):.0f} %)"
        lines.append(
            f"{target} | {share} | {count['killed']} | {count['error']} | {count['timeout']} | "
            f"{len(equiv)} (killed or equivalent: {len(killed) + len(equiv)}/{len(mine)})"
        )
    for o in outcomes:
        if o.outcome == "timeout":
            lines.append(f"killed by timeout: {o.id} {o.file}:{o.line} {o.kind}")
    for o in outcomes:
        if o.outcome != "survived":
            continue
        tag = f"equivalent: {o.equivalent}" if o.equivalent else "SURVIVED"
        lines.append(f"\n{o.id} {o.file}:{o.line} {o.kind} [{tag}]\n{o.diff.rstrip()}")
    return "\n".join(lines)


def _targets(specs: list[str]) -> list[tuple[str, list[str]]]:
    out = []
    for spec in specs:
        module, sep, tests = spec.partition("=")
        if not sep or not tests.split():
            raise SystemExit(f"mutate: --target {spec!r} is not MODULE=TESTS")
        out.append((module.strip(), tests.split()))
    return out


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    p.add_argument("--target", action="append", required=True, help="MODULE=TESTS (repeatable)")
    p.add_argument("--n", type=int, default=35, help="mutants tried per target (default 35)")
    p.add_argument("--seed", type=int, default=51, help="the sampling seed (default 51)")
    p.add_argument("--timeout", type=float, default=0.0, help="seconds per mutant (3x + 30 s)")
    p.add_argument("--json", type=Path, help="write every outcome to this file")
    p.add_argument("--list", action="store_true", help="print the sampled mutants and stop")
    p.add_argument("--only", action="append", default=[], help="run only this mutant id")
    p.add_argument("--pytest-arg", action="append", default=[], help="one more argument to pytest")
    return p


def _iter_sampled(
    targets: list[tuple[str, list[str]]], args: argparse.Namespace
) -> Iterator[tuple[str, list[str], list[Mutant]]]:
    for module, tests in targets:
        mutants = sample(module, args.n, args.seed)
        if args.only:
            every = [m for f in _files(module) for m in mutants_of(f, module)]
            mutants = [m for m in every if m.id in args.only]
        yield module, tests, mutants


def _interrupt(_signum: int, _frame: object) -> None:
    raise KeyboardInterrupt


def main() -> int:
    args = _parser().parse_args()
    signal.signal(signal.SIGTERM, _interrupt)  # a kill ends the pytest group and the copy too
    targets = _targets(args.target)
    if args.list:
        for module, _tests, mutants in _iter_sampled(targets, args):
            for m in mutants:
                original = (REPO / m.file).read_bytes()
                print(f"{m.id} {module} {m.file}:{m.line} {m.kind}\n{diff_of(m, original)}")
        return 0
    outcomes: list[Outcome] = []
    with tempfile.TemporaryDirectory(prefix="tcpcal-mutate-") as tmp:
        copy = Path(tmp) / "tree"
        _copy_tree(copy)
        _check_import(copy)
        try:
            for module, tests, mutants in _iter_sampled(targets, args):
                outcomes += run_target(copy, module, mutants, tests, args)
        except KeyboardInterrupt:
            print("\nmutate: interrupted; the worktree was never written", file=sys.stderr)
        finally:
            print(report(outcomes))
            if args.json:
                data = {"seed": args.seed, "n": args.n, "outcomes": [asdict(o) for o in outcomes]}
                args.json.write_text(json.dumps(data, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
