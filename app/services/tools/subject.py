"""The tool as a calibrated subject (app.services.lifecycle.subject): its TCP versions and
activations, named by `tool_id` in every lifecycle table, served under /v1/tools; at the
controller, its deployments and controller states, its place a tool number or a RAPID
symbol (`ToolTarget`), read and written by the connector's read_tool and write_tool."""

from __future__ import annotations

from typing import Final

from app.schemas.controllers import Deployment as DeploymentOut
from app.schemas.controllers import ReconciledTool
from app.services.lifecycle.subject import ControllerSide, Subject, Valued
from app.storage.models import (
    Activation,
    Calibration,
    Deployment,
    TcpVersion,
    Tool,
    ToolControllerState,
)
from app.vendors.connector import Connector, ToolTarget
from app.vendors.registry import TARGET_FIELD, describe_target, scope_of, target_problem
from app.vendors.tool import ToolData, ToolLoad
from app.words import CHECK_ACTION


def _target(tool: Tool) -> ToolTarget:
    return ToolTarget(slot=tool.slot, symbol=tool.controller_symbol)


def _field(protocol: str) -> str:
    return "slot" if TARGET_FIELD.get(protocol) == "slot" else "controller_symbol"


def _read(conn: Connector, target: ToolTarget) -> ToolData:
    return conn.read_tool(target)


def _write(conn: Connector, target: ToolTarget, data: ToolData) -> None:
    conn.write_tool(target, data)


def _vec3(values: object) -> tuple[float, float, float]:
    x, y, z = (float(v) for v in values)  # type: ignore[attr-defined]
    return x, y, z


def _vec4(values: object) -> tuple[float, float, float, float]:
    w, x, y, z = (float(v) for v in values)  # type: ignore[attr-defined]
    return w, x, y, z


def tool_data(tool: Tool, version: Valued) -> ToolData:
    """What deploying the tool writes: its version's frame and the tool's load (a missing
    centre of gravity at the flange)."""
    load = None
    if tool.load is not None:
        cog = tool.load.get("cog_mm") or [0.0, 0.0, 0.0]
        load = ToolLoad(mass_kg=float(tool.load["mass_kg"]), cog_mm=_vec3(cog))
    return ToolData(
        position_mm=_vec3(version.position_mm),
        quaternion=_vec4(version.quaternion),
        load=load,
    )


TOOL_CONTROLLER: Final = ControllerSide(
    target=_target,
    problem=target_problem,
    field=_field,
    describe=describe_target,
    read=_read,
    write=_write,
    held=tool_data,
    scope=scope_of,
    deploy_action="tool.deploy",
    deployment_schema=DeploymentOut,
    reconciled_schema=ReconciledTool,
    moved_by=True,
)

TOOL: Final = Subject(
    kind="tool",
    model=Tool,
    version_model=TcpVersion,
    activation_model=Activation,
    calibration_model=Calibration,
    key="tool_id",
    value="TCP",
    plural="tools",
    leaf="tcp",
    folder="Tools",
    check_action=CHECK_ACTION,
    served_detail="load",
    deployment_model=Deployment,
    state_model=ToolControllerState,
    controller=TOOL_CONTROLLER,
)
