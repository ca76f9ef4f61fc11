"""Every app/, tests/ and testbed/ path README.md and docs/*.md name exists: moving a module
(issue 38 moved most of them) leaves no page pointing at where it was.

A path with a placeholder in angle brackets (`app/vendors/<maker>/`, `tests/<package>/`)
names a pattern: the part before the first `<` must exist. A `*` is a glob that must match
something."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

#: A repository path: app/, tests/ or testbed/ at a word's start (not inside a URL or an
#: absolute path), then path characters.
PATH = re.compile(r"(?<![\w./-])((?:app|tests|testbed)/[A-Za-z0-9_./<>*-]*)")


def _exists(path: str) -> bool:
    if "<" in path:
        return (ROOT / path.split("<", 1)[0]).is_dir()
    if "*" in path:
        return any(ROOT.glob(path.rstrip("/")))
    return (ROOT / path).exists()


def stale_paths(text: str, page: str) -> list[str]:
    """`page:line: path` for each repository path in `text` that names nothing."""
    stale = []
    for number, line in enumerate(text.splitlines(), 1):
        for match in PATH.finditer(line):
            path = match.group(1).rstrip(".,;:")
            if not _exists(path):
                stale.append(f"{page}:{number}: {path}")
    return stale


def test_every_path_the_readme_and_docs_name_exists() -> None:
    stale = []
    for page in PAGES:
        stale += stale_paths(page.read_text(encoding="utf-8"), page.relative_to(ROOT).as_posix())
    assert stale == [], "paths that do not exist (moved? see git log):\n" + "\n".join(stale)


def test_a_moved_module_is_caught_and_patterns_and_urls_are_not() -> None:
    """The check itself: a path of before the relayout is stale; a placeholder whose fixed
    part exists, a glob that matches, and a path inside a URL are not."""
    planted = (
        "read by `app/services/trail.py` (now audit/reads.py), tests/api/test_watcher.py.\n"
        "`app/vendors/<maker>/__init__.py`, tests/vendors/*/test_*.py, "
        "https://github.com/x/y/blob/main/app/nowhere.py, `app/services/audit/reads.py`.\n"
        "`app/no_such_package/<module>.py`"
    )
    assert stale_paths(planted, "planted.md") == [
        "planted.md:1: app/services/trail.py",
        "planted.md:1: tests/api/test_watcher.py",
        "planted.md:3: app/no_such_package/<module>.py",
    ]


#: The README is a newcomer's first page: the two commands, a first session and the map of the
#: code (issue 46); the manual is docs/. At 402 lines it had become the manual.
README_MAX_LINES = 300


def test_the_readme_stays_a_first_page() -> None:
    lines = (ROOT / "README.md").read_text(encoding="utf-8").count("\n")
    assert lines <= README_MAX_LINES, (
        f"README.md has {lines} lines (at most {README_MAX_LINES}): move a section to docs/ "
        "and link it from the README's 'More' table"
    )
