"""The method registry: each calibration method is one run() over one solver and one schema."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from app.errors import InvalidInput
from app.methods import laser, manual, npoint, orientation, reference
from app.methods.base import MethodContext, SolvedTcp

Runner = Callable[[Any, MethodContext], SolvedTcp]

RUNNERS: dict[str, Runner] = {
    "manual": manual.run,
    "xyz_npoint": npoint.run,
    "xyz_reference": reference.run,
    "tcp_z_x": orientation.run_tcp_z_x,
    "abc_2point": orientation.run_abc_2point,
    "abc_world": orientation.run_abc_world,
    "laser_beam": laser.run,
}


def run_method(request: Any, ctx: MethodContext) -> SolvedTcp:
    """Solve a submission with the method it names."""
    runner = RUNNERS.get(request.method)
    if runner is None:
        raise InvalidInput(
            "unsupported",
            f"method {request.method!r} is not available on this server yet",
            loc=("body", "method"),
        )
    return runner(request, ctx)
