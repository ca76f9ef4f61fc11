"""Which tool numbers (slots) a robot's controller has, by the robot's vendor.

The ranges are the controllers' own, and the exports' (one definition each: the `Maker` of
app/vendors/<maker>/, its `tool_numbers`, citing the vendor documents). A maker whose tools
are not numbered (a named variable, or one TCP at a time) declares none: a slot on its tools
is not checked and is kept as the tool's number in file names and tables, as before. The
vendor is matched without regard to case, on its first word, against each maker's
`vendor_words` (its name, its company's, a brand it sells under).
"""

from __future__ import annotations

import re
from collections.abc import Iterable

from app.errors import InvalidInput
from app.vendors.registry import MAKERS

#: The tool numbers of each vendor whose controller numbers its tools, by its controller format:
#: (name, first, last) (app.vendors.registry.SLOT_RANGES holds them by protocol).
SLOTS_BY_FORMAT: dict[str, tuple[str, int, int]] = {
    m.format: (m.name, *m.tool_numbers) for m in MAKERS if m.tool_numbers is not None
}
_ALIASES = {
    word: m.format for m in MAKERS if m.format in SLOTS_BY_FORMAT for word in m.vendor_words
}


def numbered_vendor(vendor: str | None) -> str | None:
    """The key in SLOTS_BY_FORMAT of a robot's vendor, or None when its tools are not numbered
    (its maker declares no tool numbers) or the vendor is unknown or not given."""
    if not vendor:
        return None
    first = re.split(r"[^a-z0-9]+", vendor.strip().lower(), maxsplit=1)[0]
    return _ALIASES.get(first)


def slot_range(vendor: str | None) -> tuple[str, int, int] | None:
    """(vendor name, first, last) tool number of the robot's controller, None if unchecked."""
    key = numbered_vendor(vendor)
    return None if key is None else SLOTS_BY_FORMAT[key]


def check_slot(vendor: str | None, slot: int | None, *, loc: tuple[str, ...]) -> None:
    """422 at `loc` when `slot` is outside the tool numbers of the vendor's controller."""
    allowed = slot_range(vendor)
    if slot is None or allowed is None:
        return
    name, first, last = allowed
    if not first <= slot <= last:
        raise InvalidInput(
            "out-of-range",
            f"slot {slot} is not a {name} tool number: a {name} controller numbers its tools "
            f"{first}-{last}; give a slot from {first} to {last}",
            loc=loc,
        )


def check_vendor_change(
    vendor: str | None, tools: Iterable[tuple[str, int | None]], *, loc: tuple[str, ...]
) -> None:
    """422 at `loc` when a robot's new vendor numbers tools in a range that some of its live
    tools (name, slot) fall outside."""
    allowed = slot_range(vendor)
    if allowed is None:
        return
    name, first, last = allowed
    outside = sorted(
        f"{tool} (slot {slot})"
        for tool, slot in tools
        if slot is not None and not first <= slot <= last
    )
    if outside:
        raise InvalidInput(
            "out-of-range",
            f"a {name} controller numbers its tools {first}-{last}, and this robot's "
            f"{', '.join(outside)} would fall outside; change those slots first "
            "(PATCH /v1/tools/{tool_id}), then the vendor",
            loc=loc,
        )
