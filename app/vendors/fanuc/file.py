"""FANUC: an ASCII TP program (.LS) that sets each tool frame when it is run.

Followed: the LS layout of programs saved by R-30iA/R-30iB controllers in public robot-cell
repositories (e.g. WILDER-SYSTEMS-LLC/git-ftp tool_1_pick_leave.ls, JuniorNatalin/VASC
backups): ``/PROG  NAME``, ``/ATTR`` with ``OWNER = MNEDITOR;``, ``COMMENT = "...";``,
``CREATE``/``MODIFIED = DATE yy-mm-dd  TIME hh:mm:ss;``, ``LINE_COUNT``, ``PROTECT``, the
``TCD:`` block and ``DEFAULT_GROUP``, then ``/MN`` lines ``   n:  instruction ;``, ``/POS``
and ``/END``. The frame is set the way a public TP program does it (a controller backup on
GitHub: ``PR[1]=LPOS ;``, then ``PR[1,1] = ..`` .. ``PR[1,6] = ..`` and ``UTOOL[1]=PR[1] ;``;
HandlingTool manual V9.40 sec. 7.20 "UTOOL[i]=PR[j]" as quoted in public notes; RoboDK's
Fanuc_R30iA post ``setTool``): ``PR[m]=LPOS`` makes the register Cartesian, its six elements
get X Y Z (mm) and W P R (deg, R = Rz(R) Ry(P) Rx(W)), and ``UTOOL[n]=PR[m]`` copies it into
tool frame n. A negative constant is written in parentheses, as the controller stores it.

Names: the program name is at most 8 characters, upper-case letters, digits and underscores,
starting with a letter (the limit of the controllers' file names before V8; later ones allow
more); COMMENT at most 16 characters; remarks (``!...``) at most 32, ASCII, no ``;``. Numbers
have 3 decimals, as the controller shows frames. Position register PR[100] is used as scratch
and overwritten (the program says so in a remark); the tool frames' numbers (UTOOL 1-10) come
from the tools' slots. Load it with the ASCII Upload option (or ROBOGUIDE) and run it once.

What it changes, and how the controller merges it: running it sets the tool frames of the
tools it holds (``UTOOL[n]=PR[100]``, one frame each) and PR[100]; every other tool frame, the
selected tool (UTOOL_NUM) and the payload schedules stay as they are. Its remarks say so.
"""

from __future__ import annotations

import re
from datetime import datetime

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.vendors.fanuc import TOOL_NUMBERS
from app.vendors.fanuc.text import FROM_PR
from app.vendors.files import (
    ControllerFile,
    FileContext,
    FileTool,
    ParsedTool,
    as_utc,
    header_lines,
    left_out_lines,
    split_fitting,
    wrap,
)
from app.vendors.names import ascii_text
from app.vendors.text import NUMBER, parse_error
from app.vendors.tool import ToolData
from app.vendors.wpr import check_slot, tcp_from_numbers, xyz_wpr

FORMAT = "fanuc"
SCRATCH_PR = 100
PROGRAM_CHARS = 8
COMMENT_CHARS = 16
REMARK_CHARS = 32
DECIMALS = 3
TABLE_PROGRAM = "TCPUTALL"

_ATTR_TAIL = (
    "PROTECT\t\t= READ_WRITE;",
    "TCD:  STACK_SIZE\t= 0,",
    "      TASK_PRIORITY\t= 50,",
    "      TIME_SLICE\t= 0,",
    "      BUSY_LAMP_OFF\t= 0,",
    "      ABORT_REQUEST\t= 0,",
    "      PAUSE_REQUEST\t= 0;",
    "DEFAULT_GROUP\t= 1,*,*,*,*;",
    "CONTROL_CODE\t= 00000000 00000000;",
)
_PR_ELEMENT = re.compile(rf"PR\[\s*(\d+)\s*,\s*([1-6])\s*\]\s*=\s*\(?\s*({NUMBER})\s*\)?")
_REMARK_NAME = {
    word: re.compile(rf"!\s*{word}\[(\d+)\]\s+(.*?)\s*;\s*$") for word in ("UTOOL", "UFRAME")
}


def check_tool(tool: ToolData) -> None:
    """A FANUC tool needs its tool frame number (UTOOL 1-10): InvalidInput otherwise."""
    if tool.slot is None:
        raise InvalidInput(
            "invalid-options",
            "a FANUC tool needs its tool frame number (slot 1..10) for UTOOL[n]; it has none: "
            "set the tool's slot",
            loc=("slot",),
        )
    check_slot(FORMAT, tool.slot, TOOL_NUMBERS)
    xyz_wpr(tool)


def program_name(tools: list[FileTool], context: FileContext) -> str:
    """TCPUT03 for tool 3's program, TCPUTALL for a robot's table."""
    if context.table or len(tools) != 1:
        return TABLE_PROGRAM
    return f"TCPUT{tools[0].data.slot:02d}"


def constant(value: float) -> str:
    """A TP constant, 3 decimals; negative in parentheses as the controller stores it."""
    text = f"{round(float(value), DECIMALS) + 0.0:.{DECIMALS}f}"
    return f"({text})" if text.startswith("-") else text


def remark(text: str) -> str:
    """A remark instruction: ASCII, no ';' (it ends a TP line), at most 32 characters."""
    return f"!{ascii_text(text, REMARK_CHARS, drop=';')} ;"


def write(tools: list[FileTool], context: FileContext) -> ControllerFile:
    """/PROG, /ATTR, /MN (remarks, then PR element assignments and UTOOL[n]=PR[m] per tool),
    /POS, /END."""
    kept, left = split_fitting(tools, check_tool, context)
    name = program_name(tools, context)
    body = [remark(piece) for s in header_lines(kept, context) + left_out_lines(left)
            for piece in wrap(s, REMARK_CHARS)]  # fmt: skip
    body += [remark(p) for s in _how(kept) for p in wrap(s, REMARK_CHARS)]
    if kept:
        body.append(f"PR[{SCRATCH_PR}]=LPOS    ;")
    for item in sorted(kept, key=lambda t: t.data.slot or 0):
        body += frame_lines("UTOOL", item.data.slot, item.data.name, xyz_wpr(item.data))
    stamps = [as_utc(t.provenance.calibrated_at) for t in kept if t.provenance is not None]
    comment = "tcpcal tools" if context.table else f"tcpcal UTOOL {kept[0].data.slot}"
    text = ls_program(name, comment, body, max(stamps) if stamps else None)
    return ControllerFile(FORMAT, f"{name}.LS", text, tuple(left))


def ls_program(name: str, comment: str, body: list[str], stamp: datetime | None) -> str:
    """The LS text of a program `name` whose /MN lines are `body`: /PROG, /ATTR (COMMENT,
    CREATE and MODIFIED at `stamp` when given), /MN numbered, /POS, /END."""
    lines = [f"/PROG  {name}", "/ATTR", "OWNER\t\t= MNEDITOR;", f'COMMENT\t\t= "{comment}";']
    if stamp is not None:
        lines += _dates(stamp)
    lines += [f"LINE_COUNT\t= {len(body)};", *_ATTR_TAIL, "/MN"]
    lines += [f"{n:4d}:  {line}" for n, line in enumerate(body, start=1)]
    lines += ["/POS", "/END"]
    return "\n".join(lines) + "\n"


def _how(kept: list[FileTool]) -> list[str]:
    """The remarks on what the program changes when it is run."""
    if not kept:
        return ["changes nothing: it holds no tool"]
    slots = sorted(t.data.slot or 0 for t in kept)
    return [
        f"changes only tool frame(s) {', '.join(str(n) for n in slots)}",
        "every other tool frame is untouched",
        f"PR[{SCRATCH_PR}] carries the numbers: its old value is lost",
        "UTOOL_NUM and payloads stay as they are",
    ]


def _dates(moment: datetime) -> list[str]:
    stamp = moment.strftime("DATE %y-%m-%d  TIME %H:%M:%S")
    return [f"CREATE\t\t= {stamp};", f"MODIFIED\t= {stamp};"]


def frame_lines(word: str, slot: int | None, name: str, numbers: FloatArray) -> list[str]:
    """A remark naming frame `slot` of `word` (UTOOL, UFRAME), PR[100]'s six elements, and
    ``UTOOL[n]=PR[100]``."""
    lines = [remark(f"{word}[{slot}] {ascii_text(name, 40, drop=';')}")]
    lines += [f"PR[{SCRATCH_PR},{i}]={constant(v)} ;" for i, v in enumerate(numbers, start=1)]
    lines.append(f"{word}[{slot}]=PR[{SCRATCH_PR}] ;")
    return lines


def read(text: str) -> list[ParsedTool]:
    """Every ``UTOOL[n]=PR[m]`` of a TP program, with the six PR[m,i] set before it."""
    return [
        ParsedTool(slot, name, position, quaternion)
        for slot, name, position, quaternion in frames_of_program(text, "UTOOL")
    ]


def frames_of_program(text: str, word: str) -> list[tuple[int, str | None, FloatArray, FloatArray]]:
    """(number, name, position, quaternion) of every ``UTOOL[n]=PR[m]`` (`word` UTOOL, or
    UFRAME) of a TP program, with the six PR[m,i] set before it and the name its remark
    gives."""
    if "/MN" not in text:
        raise parse_error(FORMAT, "a TP program (/PROG, /ATTR, /MN ... /POS, /END)", text)
    elements: dict[int, dict[int, float]] = {}
    names: dict[int, str] = {}
    found = []
    for line in text.splitlines():
        named = _REMARK_NAME[word].search(line)
        if named is not None:
            names[int(named.group(1))] = named.group(2)
            continue
        for match in _PR_ELEMENT.finditer(line):
            register = elements.setdefault(int(match.group(1)), {})
            register[int(match.group(2))] = float(match.group(3))
        assign = FROM_PR[word].search(line)
        if assign is None:
            continue
        register = elements.get(int(assign.group(2)), {})
        if len(register) < 6:
            raise parse_error(FORMAT, f"PR[{assign.group(2)},1..6] set before {line.strip()}", text)
        slot = int(assign.group(1))
        position, quaternion = tcp_from_numbers([register[i] for i in range(1, 7)])
        found.append((slot, names.get(slot), position, quaternion))
    return found
