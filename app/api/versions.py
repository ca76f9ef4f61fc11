"""HTTP for versions, activation and the served TCP (JSON or controller text)."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Header, Query, Response
from fastapi.responses import JSONResponse

from app.api.params import PathId, VersionNumber
from app.api.tools import IfMatch
from app.deps import CalibrateKey, ReadKey, SessionDep
from app.models import TcpVersion
from app.models import Tool as ToolRow
from app.schemas.common import ControllerFormat
from app.schemas.tools import ActiveTcp, Tool, ToolTable, Version, VersionList
from app.services import registry, versions
from app.services.exports import controller_text

router = APIRouter(tags=["versions"])

FormatQuery = Annotated[ControllerFormat | None, Query(description="controller text format")]


def _version_out(row: TcpVersion, tool: ToolRow) -> dict[str, Any]:
    return {
        "version": row.version,
        "tcp": {"position_mm": row.position_mm, "quaternion": row.quaternion},
        "source": row.source,
        "status": row.status,
        "calibration_id": row.calibration_id,
        "note": row.note,
        "created_at": row.created_at,
        "created_by": row.created_by,
        "active": tool.active_version == row.version,
    }


def _active_out(tool: ToolRow, row: TcpVersion, fmt: str | None) -> dict[str, Any]:
    out: dict[str, Any] = {
        "tool_id": tool.id,
        "robot_id": tool.robot_id,
        "tool_name": tool.name,
        "slot": tool.slot,
        "version": row.version,
        "tcp": {"position_mm": row.position_mm, "quaternion": row.quaternion},
        "calibrated_at": row.created_at,
        "method": row.source,
    }
    if fmt is not None:
        out["controller"] = controller_text(fmt, tool=tool, version=row)
    return out


@router.get("/v1/tools/{tool_id}/versions", response_model=VersionList)
def list_versions(tool_id: PathId, session: SessionDep, key: ReadKey) -> object:
    tool, rows, history = versions.list_versions(session, tool_id=tool_id)
    return {
        "items": [_version_out(r, tool) for r in rows],
        "activations": history,
    }


@router.get("/v1/tools/{tool_id}/versions/{version}", response_model=Version)
def get_version(
    tool_id: PathId, version: VersionNumber, session: SessionDep, key: ReadKey
) -> object:
    row = versions.get_version(session, tool_id=tool_id, version=version)
    return _version_out(row, registry.get_tool(session, tool_id))


@router.post("/v1/tools/{tool_id}/versions/{version}/activate", response_model=Tool)
def activate_version(
    tool_id: PathId,
    version: VersionNumber,
    response: Response,
    session: SessionDep,
    key: CalibrateKey,
    if_match: IfMatch = None,
) -> object:
    tool = versions.activate_version(
        session, tool_id=tool_id, version=version, if_match=if_match, actor=key
    )
    response.headers["ETag"] = registry.tool_etag(tool)
    return tool


@router.get(
    "/v1/tools/{tool_id}/tcp",
    response_model=ActiveTcp,
    responses={304: {"description": "not modified (If-None-Match)"}},
)
def get_active_tcp(
    tool_id: PathId,
    session: SessionDep,
    key: ReadKey,
    format: FormatQuery = None,
    if_none_match: Annotated[str | None, Header()] = None,
) -> Any:
    tool, row = versions.active_tcp(session, tool_id=tool_id)
    etag = versions.tcp_etag(tool, row)
    if if_none_match is not None:
        candidates = {c.strip() for c in if_none_match.split(",")}
        if etag in candidates or "*" in candidates:
            return Response(status_code=304, headers={"ETag": etag})
    body = ActiveTcp.model_validate(_active_out(tool, row, format))
    return JSONResponse(body.model_dump(mode="json"), headers={"ETag": etag})


@router.get("/v1/robots/{robot_id}/tool-table", response_model=ToolTable)
def tool_table(
    robot_id: PathId, session: SessionDep, key: ReadKey, format: FormatQuery = None
) -> object:
    served, missing = versions.tool_table(session, robot_id=robot_id)
    return {
        "robot_id": robot_id,
        "items": [_active_out(t, r, format) for t, r in served],
        "without_active_version": missing,
    }
