"""The tool numbers (slots) of each controller that numbers its tools: the one definition.

KUKA ``$TOOL_DATA[1..16]`` (KSS 8.x, $config.dat; app.exports.kuka), Fanuc ``UTOOL[1..10]``
(R-30iB default, the count is a system setting; app.exports.wpr) and Yaskawa tool files
0..63 (YRC1000 and DX200; NX100 had 0..23). The exports check a slot against these, the
service checks a tool's slot by its robot's vendor (app.services.slots), and the controller
connectors address tools within them (app.controllers.base.SLOT_RANGES).
"""

from __future__ import annotations

#: (first, last) tool number, inclusive, by export format.
TOOL_NUMBERS: dict[str, tuple[int, int]] = {
    "kuka": (1, 16),
    "fanuc": (1, 10),
    "yaskawa": (0, 63),
}
