"""A structural check of FANUC ASCII TP programs (.LS), from the layout controllers write.

What it checks is what programs saved by R-30iA/R-30iB controllers show (public robot-cell
backups, e.g. WILDER-SYSTEMS-LLC/git-ftp *.ls, JuniorNatalin/VASC backups; the LS sections as
HandlingTool's ASCII upload reads them):

- printable ASCII lines (tabs allowed in /ATTR), the file ends with ``/END`` and a newline;
- ``/PROG  NAME`` first: two spaces, a name of letters, digits and ``_`` starting with a letter
  (upper case, at most 8 characters as tcpcal writes it);
- the sections ``/PROG``, ``/ATTR``, optional ``/APPL``, ``/MN``, ``/POS``, ``/END``, each
  once and in that order;
- ``/ATTR``: ``KEY = value;`` statements (``TCD:`` spanning lines up to its ``;``), known keys;
  ``COMMENT`` a quoted string of at most 16 characters; ``CREATE``/``MODIFIED`` as ``DATE
  yy-mm-dd  TIME hh:mm:ss``; ``LINE_COUNT`` the number of /MN lines; ``DEFAULT_GROUP`` five
  of ``1``, ``0`` or ``*``; ``PROTECT`` READ or READ_WRITE;
- ``/MN``: lines ``   n:  instruction ;`` numbered 1, 2, ... in order; each instruction one
  the checker knows: a remark ``!text`` (at most 32 characters, no ``;``), ``PR[i]=LPOS``,
  ``PR[i,j]=<constant>`` (a negative constant in parentheses), ``UTOOL[i]=PR[j]``,
  ``UTOOL_NUM=i``, an empty line;
- ``/POS``: nothing, or ``P[n]{ ... };`` blocks.
"""

from __future__ import annotations

import re

ATTR_KEYS = {
    "OWNER", "COMMENT", "PROG_SIZE", "CREATE", "MODIFIED", "FILE_NAME", "VERSION",
    "LINE_COUNT", "MEMORY_SIZE", "PROTECT", "TCD", "DEFAULT_GROUP", "CONTROL_CODE", "STORAGE",
}  # fmt: skip
SECTIONS = ["/PROG", "/ATTR", "/APPL", "/MN", "/POS", "/END"]
_CONSTANT = r"(?:\d+(?:\.\d*)?|\.\d+|\(-(?:\d+(?:\.\d*)?|\.\d+)\))"
INSTRUCTIONS = [
    re.compile(r"![ -:<-~]{0,32}"),  # remark: printable ASCII but ';'
    re.compile(r"PR\[\d+\]=LPOS\s*"),
    re.compile(rf"PR\[\d+,[1-6]\]={_CONSTANT}"),
    re.compile(r"UTOOL\[\d+\]=PR\[\d+(?::[^\]]*)?\]"),
    re.compile(r"UTOOL_NUM=\d+"),
    re.compile(r""),
]


def check_ls(text: str) -> list[str]:
    """Every way `text` departs from the LS structure above (empty: it conforms)."""
    errors: list[str] = []
    if not text.endswith("/END\n"):
        errors.append("the file does not end with /END and a newline")
    lines = text.split("\n")[:-1]
    for n, line in enumerate(lines, start=1):
        if not all(ch == "\t" or " " <= ch <= "~" for ch in line):
            errors.append(f"line {n} is not printable ASCII: {line!r}")
    if not lines or not re.fullmatch(r"/PROG  [A-Z][A-Z0-9_]{0,7}", lines[0]):
        errors.append(f"the first line is not '/PROG  NAME' (<= 8 characters): {lines[:1]}")
    starts = {s: [i for i, line in enumerate(lines) if line.split(" ")[0] == s] for s in SECTIONS}
    for section in SECTIONS:
        if len(starts[section]) > 1 or (section != "/APPL" and not starts[section]):
            errors.append(f"section {section} appears {len(starts[section])} times")
    if errors:
        return errors
    order = [starts[s][0] for s in SECTIONS if starts[s]]
    if order != sorted(order):
        return [*errors, "the sections are not in the order /PROG /ATTR /APPL /MN /POS /END"]
    attr_end = starts["/APPL"][0] if starts["/APPL"] else starts["/MN"][0]
    main = lines[starts["/MN"][0] + 1 : starts["/POS"][0]]
    errors += _check_attr(lines[starts["/ATTR"][0] + 1 : attr_end], len(main))
    errors += _check_main(main)
    pos = "\n".join(lines[starts["/POS"][0] + 1 : starts["/END"][0]])
    if pos.strip() and not re.fullmatch(r"(?:\s*P\[\d+(?::[^\]]*)?\]\{[^}]*\};\s*)+", pos):
        errors.append("/POS holds something other than P[n]{...}; blocks")
    return errors


def _check_attr(lines: list[str], line_count: int) -> list[str]:
    errors: list[str] = []
    statements = re.findall(r"([A-Z_]+)\s*[=:]\s*([^;]*);", "\n".join(lines))
    if "".join(re.sub(r"([A-Z_]+)\s*[=:]\s*([^;]*);", "", "\n".join(lines)).split()):
        errors.append("/ATTR holds text that is not KEY = value; statements")
    values = {key: value.strip() for key, value in statements}
    for key, value in values.items():
        if key not in ATTR_KEYS:
            errors.append(f"/ATTR key {key} is not one controllers write")
        if key == "COMMENT" and not re.fullmatch(r'"[^"]{0,16}"', value):
            errors.append(f"COMMENT {value} is not a quoted string of at most 16 characters")
        if key in ("CREATE", "MODIFIED") and not re.fullmatch(
            r"DATE \d\d-\d\d-\d\d  TIME \d\d:\d\d:\d\d", value
        ):
            errors.append(f"{key} {value!r} is not DATE yy-mm-dd  TIME hh:mm:ss")
        if key == "LINE_COUNT" and value != str(line_count):
            errors.append(f"LINE_COUNT {value} but /MN has {line_count} lines")
        if key == "DEFAULT_GROUP" and not re.fullmatch(r"[01*](?:,[01*]){4}", value):
            errors.append(f"DEFAULT_GROUP {value!r} is not five of 1, 0 or *")
        if key == "PROTECT" and value not in ("READ", "READ_WRITE"):
            errors.append(f"PROTECT {value!r}")
    return errors


def _check_main(lines: list[str]) -> list[str]:
    errors: list[str] = []
    for expected, line in enumerate(lines, start=1):
        match = re.fullmatch(r" {0,3}(\d{1,4}):  (.*?) ?;", line)
        if match is None:
            errors.append(f"/MN line {line!r} is not '   n:  instruction ;'")
            continue
        if int(match.group(1)) != expected:
            errors.append(f"/MN line numbered {match.group(1)}, expected {expected}")
        instruction = match.group(2).rstrip()
        if not any(p.fullmatch(instruction) for p in INSTRUCTIONS):
            errors.append(f"/MN instruction {instruction!r} is not one the checker knows")
    return errors
