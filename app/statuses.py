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

#: A deployment that failed short of a read-back, decided by where it stopped: before the
#: write was sent, so the controller holds what it held (`not_written`); after it, so the
#: controller may hold either frame (`unverified`, settled by the next reconcile round).
FailedDeploymentStatus = Literal["not_written", "unverified"]
#: A deployment: read back as written (`verified`), failed short of a read-back (above), or
#: read back otherwise than written (`mismatch`).
DeploymentStatus = Literal["verified", FailedDeploymentStatus, "mismatch"]

#: Where a deployment holds (contract v1.3): `stored` where the controller keeps it (KUKA,
#: FANUC, ABB, Yaskawa), `live` where it holds only for the running program (UR, Techman:
#: the next program start sets its own TCP).
DeploymentScope = Literal["stored", "live"]

#: What the controller holds for a tool, against the tool's active version; `not_live`: the
#: robot has one live TCP (a `live` scope protocol) and it is another tool's, the one
#: deployed to it last.
ToolState = Literal["in_sync", "drifted", "no_active_version", "unreachable", "not_live"]

#: A robot's state: the worst of its tools' states, least bad first.
RobotState = Literal["in_sync", "drifted", "unreachable"]

#: The robot states by how bad they are (the index is the severity).
ROBOT_STATES: tuple[RobotState, ...] = get_args(RobotState)
