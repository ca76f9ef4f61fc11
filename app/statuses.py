"""The stored status words: what a calibration (and the TCP version it writes), a guided
session and a deployment is, and what state a tool's controller was found in.

Pure Python, so that the stored rows (app.models), the documents (app.schemas) and the
services share the one list of each without importing each other.
"""

from __future__ import annotations

from typing import Literal, get_args

#: A calibration and its version: within the tool's tolerance or not (app.helpers.tolerance).
Status = Literal["accepted", "out_of_tolerance"]

#: A guided session: touches may still be added, or it ended in a calibration.
SessionStatus = Literal["open", "finished"]

#: A deployment: read back as written, not written (or not read), or read back otherwise.
DeploymentStatus = Literal["verified", "failed", "mismatch"]

#: What the controller holds for a tool, against the tool's active version.
ToolState = Literal["in_sync", "drifted", "no_active_version", "unreachable"]

#: A robot's state: the worst of its tools' states, least bad first.
RobotState = Literal["in_sync", "drifted", "unreachable"]

#: The robot states by how bad they are (the index is the severity).
ROBOT_STATES: tuple[RobotState, ...] = get_args(RobotState)
