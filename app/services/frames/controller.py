"""The frame at the controller (contract v1.4 "Frames at the controller"): its place a frame
number, a RAPID symbol or, where the controller names a frame by its values, none
(`FrameTarget`, with the frame's kind and name), read and written by the connector's
read_frame and write_frame; what a protocol says of that place is its declaration's
(app.vendors.maker.WireProtocol.frames)."""

from __future__ import annotations

from typing import Final

from app.schemas.controllers import FrameDeployment, ReconciledFrame
from app.services.lifecycle.subject import ControllerSide, Valued
from app.storage.models import Frame as FrameRow
from app.vendors.connector import Connector, Frame, FrameTarget
from app.vendors.maker import BySlot
from app.vendors.registry import WIRE_PROTOCOLS
from app.words import PROTOCOLS, DeploymentScope


def _target(frame: FrameRow) -> FrameTarget:
    return FrameTarget(
        kind=frame.kind, slot=frame.slot, symbol=frame.controller_symbol, name=frame.name
    )


def _problem(protocol: str, target: FrameTarget) -> str | None:
    wire = WIRE_PROTOCOLS.get(protocol)
    if wire is None:
        return f"unknown controller protocol {protocol!r}; known: {', '.join(PROTOCOLS)}"
    return wire.frame_problem(target)


def _field(protocol: str) -> str:
    wire = WIRE_PROTOCOLS.get(protocol)
    return "slot" if wire is None or isinstance(wire.frames, BySlot) else "controller_symbol"


def _describe(protocol: str, target: FrameTarget) -> str:
    return WIRE_PROTOCOLS[protocol].describe_frame(target)


def _scope(protocol: str) -> DeploymentScope:
    wire = WIRE_PROTOCOLS.get(protocol)
    return "stored" if wire is None else wire.frame_scope


def _read(conn: Connector, target: FrameTarget) -> Frame:
    return conn.read_frame(target)


def _write(conn: Connector, target: FrameTarget, frame: Frame) -> None:
    conn.write_frame(target, frame)


def frame_pose(frame: FrameRow, version: Valued) -> Frame:
    """What deploying the frame writes: its version's pose in the robot's base frame."""
    x, y, z = (float(v) for v in version.position_mm)
    w, qx, qy, qz = (float(v) for v in version.quaternion)
    return Frame(position_mm=(x, y, z), quaternion=(w, qx, qy, qz))


FRAME_CONTROLLER: Final = ControllerSide(
    target=_target,
    problem=_problem,
    field=_field,
    describe=_describe,
    read=_read,
    write=_write,
    held=frame_pose,
    scope=_scope,
    deploy_action="frame.deploy",
    deployment_schema=FrameDeployment,
    reconciled_schema=ReconciledFrame,
    unaddressed="frames_not_addressable",
)
