"""What every controller file shares: the tools it holds, where their numbers come from (the
header), what a parser reads back, and the file's name and text.

A file holds one tool (GET /v1/tools/{id}/tcp, Accept: text/plain) or all of a robot's tools
(GET /v1/robots/{id}/tool-table): the same writer, one or many tools. A tool the format cannot
hold (no tool number where the controller needs one, no load where the format needs one) is left out
and named, with the reason, in the file's header where the format has comments.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any, Protocol, TypeVar

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.vendors.names import ascii_text
from app.vendors.tool import ToolData

#: Longest tool name shown in a header line.
HEADER_NAME_CHARS = 40


@dataclass(frozen=True)
class Provenance:
    """Where a tool's active TCP comes from: its version, when and by whom it was calibrated
    (the version's creation), the method, and the tool's page on the tcpcal server."""

    version: int
    calibrated_at: datetime
    calibrated_by: str | None
    method: str
    url: str | None = None


@dataclass(frozen=True)
class FileTool:
    """A tool as a file holds it: the controller data, and the header's provenance."""

    data: ToolData
    provenance: Provenance | None = None


@dataclass(frozen=True)
class FileContext:
    """What a file says about itself: the robot (for a robot's table) and the server."""

    robot: str | None = None
    server_url: str | None = None
    table: bool = False
    #: Names of the robot's tools that have no active version (so are not in its table).
    without_version: tuple[str, ...] = ()


@dataclass(frozen=True)
class LeftOut:
    """A tool a file could not hold, and why."""

    name: str
    reason: str


@dataclass(frozen=True)
class ControllerFile:
    """A controller file: the name to save it as, its text (final newline), what it left out."""

    format: str
    name: str
    text: str
    left_out: tuple[LeftOut, ...] = ()


@dataclass(frozen=True)
class ParsedTool:
    """One tool read back from a controller file (None where the file does not say)."""

    slot: int | None
    name: str | None
    position_mm: FloatArray
    quaternion_wxyz: FloatArray
    mass_kg: float | None = None
    cog_mm: FloatArray | None = field(default=None)


class _Named(Protocol):
    """What a header says of a held item's data: its name and number (a ToolData, a
    FrameData)."""

    @property
    def name(self) -> str: ...
    @property
    def slot(self) -> int | None: ...


class Held(Protocol):
    """An item a file holds: its data (named, numbered) and its provenance (a FileTool, a
    FileFrame)."""

    @property
    def data(self) -> _Named: ...
    @property
    def provenance(self) -> Provenance | None: ...


HeldT = TypeVar("HeldT", bound=Held)


def as_utc(moment: datetime) -> datetime:
    """`moment` in UTC (a naive time is taken to be UTC, as the database stores it)."""
    return moment.replace(tzinfo=UTC) if moment.tzinfo is None else moment.astimezone(UTC)


def header_lines(tools: Sequence[Held], context: FileContext, noun: str = "tool") -> list[str]:
    """The header's sentences, plain ASCII (each format adds its comment syntax and wraps);
    `noun` names what the file holds ("tool", "frame")."""
    if context.table:
        subject = f"robot {ascii_text(context.robot or '?', HEADER_NAME_CHARS) or '?'}"
        lines = [f"tcpcal {noun} table of {subject}: {len(tools)} {noun}(s)"]
    else:
        lines = [f"tcpcal {noun} data"]
    for item in tools:
        lines.extend(_held_lines(item, noun))
    if context.without_version:
        names = ", ".join(ascii_text(n, HEADER_NAME_CHARS) or "?" for n in context.without_version)
        lines.append(f"not in this file, no active version yet: {names}")
    if context.server_url:
        lines.append(f"from {context.server_url}")
    return lines


def _held_lines(item: Held, noun: str) -> list[str]:
    tool, origin = item.data, item.provenance
    name = ascii_text(tool.name, HEADER_NAME_CHARS) or "(name not ASCII)"
    slot = f" ({noun} {tool.slot})" if tool.slot is not None else ""
    if origin is None:
        return [f"{noun} {name}{slot}"]
    when = as_utc(origin.calibrated_at).strftime("%Y-%m-%d %H:%M UTC")
    who = ascii_text(origin.calibrated_by or "?", HEADER_NAME_CHARS) or "?"
    lines = [
        f"{noun} {name}{slot} version {origin.version}",
        f"calibrated {when} by {who} ({origin.method})",
    ]
    if origin.url:
        lines.append(origin.url)
    return lines


def left_out_lines(left_out: Sequence[LeftOut]) -> list[str]:
    """Header sentences naming the tools a file could not hold."""
    return [
        f"left out: {ascii_text(item.name, HEADER_NAME_CHARS) or '?'}: {item.reason}"
        for item in left_out
    ]


def header_comments(
    tools: Sequence[Held],
    left_out: Sequence[LeftOut],
    context: FileContext,
    how: Sequence[str],
    mark: str,
    width: int,
    noun: str = "tool",
) -> list[str]:
    """A file's header as comment lines of at most `width` characters, each starting with
    the format's comment `mark` ("; ", "# ", "  ! "): `header_lines`, `left_out_lines`, then
    the format's own sentences on what the file changes (`how`)."""
    sentences = [*header_lines(tools, context, noun), *left_out_lines(left_out), *how]
    return [f"{mark}{piece}" for s in sentences for piece in wrap(s, width - len(mark))]


def wrap(line: str, width: int) -> list[str]:
    """`line` cut into pieces of at most `width` characters, at spaces where it can be."""
    pieces: list[str] = []
    rest = line
    while len(rest) > width:
        cut = rest.rfind(" ", 0, width + 1)
        if cut <= 0:
            cut = width
        pieces.append(rest[:cut].rstrip())
        rest = rest[cut:].lstrip()
    pieces.append(rest)
    return pieces


def split_fitting(
    tools: Sequence[HeldT], check: Callable[[Any], object], context: FileContext
) -> tuple[list[HeldT], list[LeftOut]]:
    """(the items `check` accepts, the others with the reason it gave): `check` takes an
    item's data (a ToolData, a FrameData). A single item the format cannot hold, outside a
    robot's table, is refused with that reason (a 422 naming the field to set)."""
    kept: list[HeldT] = []
    left: list[LeftOut] = []
    left_tools: list[_Named] = []
    for item in tools:
        try:
            check(item.data)
        except InvalidInput as exc:
            left.append(LeftOut(item.data.name, exc.detail))
            left_tools.append(item.data)
            continue
        kept.append(item)
    if left and not context.table:
        check(left_tools[0])  # raises the reason itself
    return kept, left
