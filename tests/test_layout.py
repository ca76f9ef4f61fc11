"""tests/ mirrors app/: each package of tests/ is the mirror of a package of app/ (tests/api
for app/api, tests/services/<feature> for app/services/<feature>, tests/vendors/<maker> ...),
so the tests of a module are found where the module is; the exceptions are the kinds of test
named here, which test the whole service from outside or hold what tests share."""

from __future__ import annotations

from pathlib import Path

TESTS = Path(__file__).resolve().parent
APP = TESTS.parent / "app"

#: Directories of tests/ that are not a mirror: a kind of test, or what tests share.
NAMED_KINDS = {
    "browser": "the console driven by Chromium",
    "live": "real servers started on loopback ports",
    "contract": "the fuzzed HTTP contract's hooks and settings",
    "controllers": "the controller simulators and the rigs that drive them",
    "data": "real recorded data (tests/data/README.md)",
    "opcua_client": "node-opcua's client, the other implementation",
}


def _test_dirs() -> list[Path]:
    """Every directory of tests/ that is a package or holds a test module."""
    found = {p.parent for p in TESTS.rglob("__init__.py")}
    found |= {p.parent for p in TESTS.rglob("test_*.py")}
    return sorted(d for d in found if d != TESTS and "node_modules" not in d.parts)


def test_each_package_of_tests_mirrors_a_package_of_app_or_is_a_named_kind() -> None:
    strays = []
    for directory in _test_dirs():
        relative = directory.relative_to(TESTS)
        if relative.parts[0] in NAMED_KINDS:
            continue
        if not (APP / relative / "__init__.py").is_file():
            strays.append(f"tests/{relative.as_posix()} (no app/{relative.as_posix()}/)")
    assert not strays, "move these tests under the mirror of what they test:\n" + "\n".join(strays)


def test_every_test_package_is_a_package() -> None:
    """A directory of test modules without __init__.py would import its modules by their bare
    names, and two test_x.py in two such directories would collide."""
    missing = [
        d.relative_to(TESTS).as_posix()
        for d in _test_dirs()
        if not (d / "__init__.py").is_file() and any(d.glob("test_*.py"))
    ]
    assert missing == []
