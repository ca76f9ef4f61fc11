"""The stored words: every closed list of words a column (or a stored JSON record) holds, one
Literal each, written here once.

What a calibration (and the TCP version it writes), a guided session and a deployment is,
what state a tool's controller was found in, what an audit event says was done and to what,
which method made a version, what kind an activation was, where a touch came from.

Pure Python, so that the stored rows (app.storage.models), the documents (app.schemas) and the
services share the one list of each without importing each other. The controller makers'
words are here too (`ControllerFormat`, `ProtocolName`): app.vendors.registry lists the makers
that serve them, and tests/vendors/test_registry.py holds that both say the same words. Key
scopes are app.scopes.Scope. tests/test_one_definition.py holds that no Literal is written twice.
"""

from __future__ import annotations

from typing import Final, Literal, get_args

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

#: What the reconcile round after an `unverified` deployment found the controller holding:
#: the deployed version, the frame it held before the deployment, or neither.
SettledHolds = Literal["written", "previous", "other"]

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

#: The pose formats the API takes (the `format` of touches, references and guided sessions);
#: app.kinematics.poses parses them and reads POSE_FORMATS off this Literal. Written here, not
#: there, so that the rows (app.storage.models) name it without importing numpy and scipy.
PoseFormat = Literal[
    "matrix",
    "xyz_wxyz",
    "xyz_xyzw",
    "kuka_abc",
    "fanuc_wpr",
    "yaskawa_rxyz",
    "techman_rxyz",
    "ur_rotvec",
    "joints",
]

#: The units a pose's numbers are in (a format's defaults, a request's and a session's
#: `units`); with the formats, so that app.schemas.common names them without the numeric
#: core.
Length = Literal["mm", "m"]
Angle = Literal["deg", "rad"]

#: The controllers' text and file formats (``?format=``, ``controller.format``), one a maker
#: (app/vendors/<maker>/), in the order the API lists them.
ControllerFormat = Literal["kuka", "abb", "fanuc", "ur", "yaskawa", "techman"]
CONTROLLER_FORMATS: tuple[ControllerFormat, ...] = get_args(ControllerFormat)
#: "kuka, abb, fanuc, ur, yaskawa or techman": the formats as a sentence names them.
FORMATS_IN_WORDS = f"{', '.join(CONTROLLER_FORMATS[:-1])} or {CONTROLLER_FORMATS[-1]}"

#: The wire protocols a connector speaks (a robot's ``controller.protocol``), each its
#: maker's (app/vendors/<maker>/__init__.py); those of one port first, as the API lists them.
ProtocolName = Literal[
    "kuka_kvp",
    "fanuc_rmi",
    "abb_rws1",
    "abb_rws2",
    "techman",
    "yaskawa_hses",
    "ur_rtde",
]
PROTOCOLS: tuple[ProtocolName, ...] = get_args(ProtocolName)

#: The N-point estimators (`options.algorithm`, a calibration's `algorithm`); app.solvers.npoint
#: runs them and reads ALGORITHMS off this Literal (written here for the same reason).
Algorithm = Literal["robust", "stacked", "pairwise", "sphere", "gls"]

#: Each calibration method's word, written once: its request model's `method` names it
#: (`method: XyzPlane`, app.methods), and MethodName below is their union.
XyzNpoint = Literal["xyz_npoint"]
XyzPlane = Literal["xyz_plane"]
XyzReference = Literal["xyz_reference"]
TcpZX = Literal["tcp_z_x"]
Abc2Point = Literal["abc_2point"]
AbcWorld = Literal["abc_world"]
LaserBeam = Literal["laser_beam"]
Manual = Literal["manual"]


def word(literal: object) -> str:
    """The word a one-word Literal stands for (`word(TcpZX)`): how a declaration outside
    app.methods (a maker's `teaches`) names a method without spelling it again."""
    (value,) = get_args(literal)
    return str(value)


#: A calibration method (a calibration's `method`, a version's `source`, a guided session's
#: `method`): the registry's names, in its order (app.methods.METHOD_NAMES is read off the
#: registry; tests/test_one_definition.py holds the two equal and each word written here
#: only). GET /v1/methods lists them; the CLI and the console read them from there.
MethodName = Literal[
    XyzNpoint,
    XyzPlane,
    XyzReference,
    TcpZX,
    Abc2Point,
    AbcWorld,
    LaserBeam,
    Manual,
]

#: What a frame is (a frame's `kind`): a base the robot works in (KUKA base, ABB work object,
#: FANUC and Yaskawa user frame, UR feature), or a tool standing in the cell that the robot
#: brings the part to (a stationary TCP).
FrameKind = Literal["base", "fixed_tool"]

#: Each frame calibration method's word, written once (app.methods.frame; `manual` is the
#: tools' `Manual`, one word for numbers entered by hand): its request's `method` names it.
ThreePoint = Literal["three_point"]
FourPoint = Literal["four_point"]
FitPoints = Literal["fit_points"]
FixedNpoint = Literal["fixed_npoint"]
#: A frame calibration method (a frame calibration's `method`), the frame registry's names
#: in its order (app.methods.frame.FRAME_METHOD_NAMES; tests/test_one_definition.py holds
#: the two equal).
FrameMethodName = Literal[ThreePoint, FourPoint, FitPoints, FixedNpoint, Manual]

#: The roles of frame touches, as app.solvers.frame.construction names them (each
#: construction's `roles`; tests/methods/frame holds the two equal): origin, +X and the XY
#: plane; ABB's user method's X1, X2, Y1; the start of the X axis of the four-point frame.
OriginXXy = Literal["origin", "x", "xy"]
UserMethodRole = Literal["x1", "x2", "y1"]
FrameRole = Literal[OriginXXy, UserMethodRole, "x_start"]

#: How a three_point frame's touches make its axes (app.solvers.frame.construction, one
#: construction each), named as the pendants teach them: the origin, +X and the XY plane (most
#: makers'), ABB's user method (X1, X2 on X, Y1 on Y), PolyScope's Plane feature.
ThreePointConvention = Literal["origin_x_xy", "abb_user", "ur_plane"]

#: The tool axis the 2-point and world orientation methods take as the working axis
#: (app.solvers.orientation; a maker's own, where it declares one: Maker.working_axis).
WorkingAxis = Literal["x", "z"]

#: What a guided frame session's next touch is sent with beside its pose
#: (app.methods.frame.next_role): a role, a nominal_mm, or nothing (a fixed tool's tip).
FrameTouchTakes = Literal["role", "nominal_mm", "tip", "fiducial"]

#: A frame session's method: a frame method that takes touches, or "recheck" (the frame's
#: stored fiducials touched again, finished as its check, POST /v1/frames/{frame_id}/checks).
Recheck = Literal["recheck"]
FrameSessionMethod = Literal[FrameMethodName, Recheck]

#: A guided session's method (guided_sessions.method): a tool session's or a frame session's.
SessionMethod = Literal[MethodName, FrameSessionMethod]

#: What made a version of any calibrated subject (app.services.lifecycle.subject.Valued).
VersionSource = MethodName | FrameMethodName

#: The kind of an activation (activations.reason): a version activated by name
#: (`explicit`), by name out of tolerance with `force` (`forced`), by a rollback, by the
#: calibration that made it (`calibration:<its activate option>`), or by a re-check's
#: correction (`check_correction`).
ActivationKind = Literal[
    "explicit",
    "forced",
    "rollback",
    "calibration:auto",
    "calibration:always",
    "check_correction",
]

#: Where a touch's pose came from: typed by a person, or read from the robot's controller.
TouchOrigin = Literal["typed", "controller"]

#: How a laser device's geometry was given: as numbers, or taught by sweeps.
LaserDeviceSource = Literal["numeric", "taught"]

#: What an audit event (and the outbox message and log line that carry it) says was done,
#: as resource.verb. tests/api/test_audit_every_write.py holds that every write route
#: records only these, and tests/test_one_definition.py that each is recorded somewhere.
AuditAction = Literal[
    "robot.create",
    "robot.update",
    "robot.archive",
    "robot.live_tool",
    "tool.create",
    "tool.update",
    "tool.archive",
    "tool.check",
    "tool.deploy",
    "frame.create",
    "frame.update",
    "frame.archive",
    "frame.fiducials",
    "frame.check",
    "frame.deploy",
    "version.create",
    "version.activate",
    "version.rollback",
    "calibration.create",
    "controller.set",
    "controller.delete",
    "controller.in_sync",
    "controller.drifted",
    "controller.unreachable",
    "deployment.settled",
    "reference_point.create",
    "reference_point.move",
    "laser_device.create",
    "key.create",
    "key.revoke",
    "session.create",
    "session.touch_add",
    "session.touch_delete",
    "session.finish",
]

#: The kind of thing an audit event changed (its `resource_id` names which one).
ResourceType = Literal[
    "robot",
    "tool",
    "frame",
    "calibration",
    "deployment",
    "reference_point",
    "laser_device",
    "api_key",
    "session",
]

#: The action of a TCP check, which the drift trend and the fleet read back.
CHECK_ACTION: Final[AuditAction] = "tool.check"
#: The action of a frame's re-check after a move, which its drift trend and the fleet read back.
FRAME_CHECK_ACTION: Final[AuditAction] = "frame.check"
