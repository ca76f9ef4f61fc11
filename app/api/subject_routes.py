"""The routes of every calibrated subject's versions, from one definition: its versions listed
and read, a version activated (reason, force) and a rollback, each as a subject's route under
its path (/v1/tools/{tool_id}/versions, /v1/frames/{frame_id}/versions), its path parameter
named by the subject's key. A subject's router module includes `version_routes(...)` with its
declaration (app.services.lifecycle.subject) and its documents, and adds the hot read of its
active version with `add_active_route` (GET /v1/tools/{tool_id}/tcp, /v1/frames/{frame_id}/frame)
and its robot's table with `add_table_route` (GET /v1/robots/{robot_id}/tool-table, frame-table).

A route's words (its description, its parameters') are the subject's: written here once with
the subject's kind, value and path in them, so that the tool's read as they always did.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated, Generic, Protocol, TypeVar, cast

from fastapi import APIRouter, Header, Request, Response
from fastapi.responses import PlainTextResponse
from pydantic import BaseModel
from sqlalchemy.orm import Session

from app.api.deps import CalibrateKey, ReadKey, SessionDep, label_request
from app.api.params import (
    ACCEPT,
    FORMAT,
    IF_NONE_MATCH,
    AcceptHeader,
    FormatQuery,
    PathId,
    RawParam,
    VersionNumber,
)
from app.helpers.etags import IF_MATCH_PATTERN
from app.schemas.common import ID_PATTERN
from app.schemas.tools import ActivationRequest, RollbackRequest
from app.security.auth import Principal
from app.services.lifecycle import activation
from app.services.lifecycle import versions as lifecycle
from app.services.lifecycle.subject import ActivationT, AnySubject, Row, Subject, VersionT
from app.vendors.files import ControllerFile
from app.words import ControllerFormat

Document = TypeVar("Document", bound=BaseModel)
VersionDocument = TypeVar("VersionDocument", bound=BaseModel)
ListDocument = TypeVar("ListDocument", bound=BaseModel)


@dataclass(frozen=True)
class SubjectRoutes(Generic[Row, VersionT, ActivationT, Document, VersionDocument, ListDocument]):
    """A subject's version routes: its declaration, the document of the subject (a Tool, a
    Frame: what an activation answers), of a version and of the version list, and how a
    stored version becomes its document; `names` prefixes the routes' names (their
    operationIds) after the first word: "" for the tool's (list_versions), "frame_" for the
    frame's (list_frame_versions). The routes take the tags of the router including them."""

    subject: Subject[Row, VersionT, ActivationT]
    document: type[Document]
    version: type[VersionDocument]
    version_list: type[ListDocument]
    version_document: Callable[[VersionT, Row], VersionDocument]
    names: str


def with_etag(response: Response, document: type[Document], row: lifecycle.Revised) -> Document:
    """A subject's row as its document (a Tool, a RobotFrame), its ETag in the answer's
    headers: what a subject's create, read, PATCH, activation and rollback answer."""
    response.headers["ETag"] = lifecycle.etag(row)
    return document.model_validate(row, from_attributes=True)


def version_routes(
    spec: SubjectRoutes[Row, VersionT, ActivationT, Document, VersionDocument, ListDocument],
) -> APIRouter:
    """The subject's routes: GET {path}/{{key}}/versions, GET {path}/{{key}}/versions/{{version}},
    POST {path}/{{key}}/versions/{{version}}/activate, POST {path}/{{key}}/rollback."""
    router = APIRouter()
    _read_routes(router, spec)
    _write_routes(router, spec)
    return router


class Served(Protocol):
    """A hot read's answer (app.services.tools.active_tcp.ServedTcp, a frame's
    ServedFrameAnswer): who asked, its ETag, and the JSON document or the controller's file,
    neither when the client's copy is current (If-None-Match: 304)."""

    @property
    def key(self) -> Principal: ...
    @property
    def etag(self) -> str: ...
    @property
    def document(self) -> BaseModel | None: ...
    @property
    def file(self) -> ControllerFile | None: ...


class ServeActive(Protocol):
    """A subject's hot read: its active version for the caller behind `authorization`, as
    JSON (in controller `fmt`'s text when given) or as the controller's file when
    `file_base_url` (the server's base URL, which the file's header names) is given."""

    def __call__(
        self,
        subject_id: str,
        /,
        *,
        authorization: str | None,
        fmt: ControllerFormat | None,
        if_none_match: str | None,
        file_base_url: str | None,
    ) -> Served: ...


def subject_id_param(subject: AnySubject) -> RawParam:
    """The subject's id as its hot read's path parameter, read by hand (see RawParam)."""
    return RawParam(
        "path",
        subject.key,
        subject.key.replace("_", " ").title(),
        f"an id this service issued (1-64 of A-Za-z0-9_-); take it from GET {subject.path}",
        description="resource id",
        pattern=ID_PATTERN,
    )


def add_active_route(
    router: APIRouter,
    subject: AnySubject,
    *,
    document: type[BaseModel],
    serve: ServeActive,
    description: str,
) -> None:
    """GET {path}/{{key}}/{leaf}, the route cell controllers poll (add it first: matched before
    the others): the subject's active version with a strong ETag (If-None-Match -> 304),
    `?format=` adding the controller's own text, `Accept: text/plain` (and `?format=`) the file
    the controller loads (Content-Disposition names it). `document` is its JSON answer."""
    subject_id_of = subject_id_param(subject)

    async def get_active(request: Request) -> Response:
        subject_id = subject_id_of.read(request)
        assert subject_id is not None  # a path parameter
        as_text = "text/plain" in (ACCEPT.read(request) or "")
        # On the event loop, no dependency and no threadpool hop: the key check and the read
        # are one indexed statement (app.services.lifecycle.hot_read).
        served = serve(
            subject_id,
            authorization=request.headers.get("authorization"),
            fmt=cast(ControllerFormat | None, FORMAT.read(request)),
            if_none_match=IF_NONE_MATCH.read(request),
            file_base_url=str(request.base_url) if as_text else None,
        )
        label_request(request, served.key)
        headers = {"ETag": served.etag, "Vary": "Accept"}
        if served.document is not None:
            # Serialised by pydantic in one pass (no dict, no json.dumps); validated when built.
            return Response(
                served.document.model_dump_json(), media_type="application/json", headers=headers
            )
        if served.file is not None:
            headers["Content-Disposition"] = f'attachment; filename="{served.file.name}"'
            return PlainTextResponse(served.file.text, headers=headers)
        return Response(status_code=304, headers=headers)

    parameters = (subject_id_of, FORMAT, IF_NONE_MATCH, ACCEPT)
    router.add_api_route(
        f"{_at(subject)}/{subject.leaf}",
        get_active,
        methods=["GET"],
        name=f"get_active_{subject.leaf}",
        response_model=document,
        responses={
            200: {"content": {"text/plain": {"schema": {"type": "string"}}}},
            304: {"description": "not modified (If-None-Match)"},
        },
        openapi_extra={"parameters": [p.openapi() for p in parameters]},
        description=description,
    )


Table = TypeVar("Table", bound=BaseModel)


class RobotFile(Protocol):
    """A subject's robot file: every live one of a robot with an active version, in one file
    of format `fmt` (app.services.tools.controller_files.robot_file)."""

    def __call__(
        self, session: Session, *, robot_id: str, fmt: ControllerFormat | None, base_url: str
    ) -> ControllerFile: ...


def add_table_route(
    router: APIRouter,
    subject: AnySubject,
    *,
    table: Callable[..., Table],
    document: type[Table],
    file: RobotFile,
    description: str,
) -> None:
    """GET /v1/robots/{{robot_id}}/{kind}-table: every live one of a robot's subjects with its
    active version in one answer, `table(session, robot_id=, fmt=)` (its `document`), or with
    `Accept: text/plain` (and `?format=`) the robot's `file` (Content-Disposition names it)."""

    def subject_table(
        robot_id: PathId,
        request: Request,
        session: SessionDep,
        key: ReadKey,
        format: FormatQuery = None,
        accept: AcceptHeader = None,
    ) -> Table | PlainTextResponse:
        if "text/plain" in (accept or ""):
            served = file(session, robot_id=robot_id, fmt=format, base_url=str(request.base_url))
            disposition = f'attachment; filename="{served.name}"'
            headers = {"Content-Disposition": disposition, "Vary": "Accept"}
            return PlainTextResponse(served.text, headers=headers)
        return table(session, robot_id=robot_id, fmt=format)

    router.add_api_route(
        f"/v1/robots/{{robot_id}}/{subject.kind}-table",
        subject_table,
        methods=["GET"],
        name=f"{subject.kind}_table",
        response_model=document,
        responses={200: {"content": {"text/plain": {"schema": {"type": "string"}}}}},
        description=description,
    )


def _at(subject: AnySubject) -> str:
    """Where a subject's own routes start: "/v1/tools/{tool_id}"."""
    return f"{subject.path}/{{{subject.key}}}"


def _read_routes(
    router: APIRouter,
    spec: SubjectRoutes[Row, VersionT, ActivationT, Document, VersionDocument, ListDocument],
) -> None:
    subject = spec.subject
    kind, value, at = subject.kind, subject.value, _at(subject)

    def list_versions(subject_id: PathId, session: SessionDep, key: ReadKey) -> ListDocument:
        row, rows, history = lifecycle.list_versions(session, subject, subject_id=subject_id)
        return spec.version_list.model_validate(
            {"items": [spec.version_document(r, row) for r in rows], "activations": history},
            from_attributes=True,
        )

    def get_version(
        subject_id: PathId, version: VersionNumber, session: SessionDep, key: ReadKey
    ) -> VersionDocument:
        row = lifecycle.get_version(session, subject, subject_id=subject_id, version=version)
        return spec.version_document(row, lifecycle.get_live(session, subject, subject_id))

    router.add_api_route(
        f"{at}/versions",
        _keyed(list_versions, subject),
        methods=["GET"],
        name=f"list_{spec.names}versions",
        response_model=spec.version_list,
        description=f"Every version of a {kind}'s {value} with who made it and why, and the "
        "history of activations.",
    )
    router.add_api_route(
        f"{at}/versions/{{version}}",
        _keyed(get_version, subject),
        methods=["GET"],
        name=f"get_{spec.names}version",
        response_model=spec.version,
        description=f"One version of a {kind}'s {value}.",
    )


def _write_routes(
    router: APIRouter,
    spec: SubjectRoutes[Row, VersionT, ActivationT, Document, VersionDocument, ListDocument],
) -> None:
    subject = spec.subject
    kind, value, at = subject.kind, subject.value, _at(subject)

    def activate_version(
        subject_id: PathId,
        version: VersionNumber,
        response: Response,
        session: SessionDep,
        key: CalibrateKey,
        if_match: str | None = None,
        body: ActivationRequest | None = None,
    ) -> Document:
        row = activation.activate_version(
            session,
            subject,
            subject_id=subject_id,
            version=version,
            body=body or ActivationRequest(),
            if_match=if_match,
            actor=key,
        )
        return with_etag(response, spec.document, row)

    def rollback(
        subject_id: PathId,
        response: Response,
        session: SessionDep,
        key: CalibrateKey,
        if_match: str | None = None,
        body: RollbackRequest | None = None,
    ) -> Document:
        row = activation.rollback(
            session,
            subject,
            subject_id=subject_id,
            body=body or RollbackRequest(),
            if_match=if_match,
            actor=key,
        )
        return with_etag(response, spec.document, row)

    stale = {"description": f"If-Match names an older ETag of the {kind}"}
    router.add_api_route(
        f"{at}/versions/{{version}}/activate",
        _keyed(activate_version, subject),
        methods=["POST"],
        name=f"activate_{spec.names}version",
        response_model=spec.document,
        responses={
            409: {"description": "out of tolerance without force (/out-of-tolerance)"},
            412: stale,
        },
        description=f"Make a stored version the active {value}, with an optional `reason` "
        "kept in the activation\nhistory and the audit trail. A version stored as "
        'out_of_tolerance needs `{"force": true,\n"reason": ...}` (409 /out-of-tolerance '
        "otherwise, nothing changed). To go back to the\nversion active before, use POST "
        f"{at}/rollback. Honours If-Match with the\n{kind}'s ETag, 412 when stale.",
    )
    router.add_api_route(
        f"{at}/rollback",
        _keyed(rollback, subject),
        methods=["POST"],
        name=f"{spec.names}rollback",
        response_model=spec.document,
        responses={
            409: {"description": "no earlier activation to return to (/nothing-to-roll-back)"},
            412: stale,
        },
        description="Return to the version that was active before the current one, read "
        "from the activation\nhistory (never by number, never a version that was not "
        "active). Rolling back again walks\nfurther back; 409 /nothing-to-roll-back when no "
        "earlier activation is left. Optional\n`reason`; honours If-Match with the "
        f"{kind}'s ETag, 412 when stale.",
    )


def if_match_of(subject: AnySubject) -> object:
    """The If-Match header of a subject's writes, described with its kind."""
    return Annotated[
        str | None,
        Header(
            pattern=IF_MATCH_PATTERN,
            description=f"the {subject.kind}'s ETag (or *); 412 when stale",
        ),
    ]


Endpoint = TypeVar("Endpoint", bound=BaseModel)


def _keyed(endpoint: Callable[..., Endpoint], subject: AnySubject) -> Callable[..., Endpoint]:
    """The endpoint as FastAPI reads it: its `subject_id` named by the subject's key
    ("tool_id"), its `if_match` header described with the subject's words."""
    key, if_match = subject.key, if_match_of(subject)
    signature = inspect.signature(endpoint, eval_str=True)
    parameters = []
    for parameter in signature.parameters.values():
        if parameter.name == "subject_id":
            parameter = parameter.replace(name=key)
        elif parameter.name == "if_match":
            parameter = parameter.replace(annotation=if_match)
        parameters.append(parameter)

    def call(**values: object) -> Endpoint:
        values["subject_id"] = values.pop(key)
        return endpoint(**values)

    call.__signature__ = signature.replace(parameters=parameters)  # type: ignore[attr-defined]
    call.__name__ = endpoint.__name__
    return call
