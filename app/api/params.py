"""Request parameters shared by routes: list paging, path ids, headers read by hand."""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Annotated, Literal

from fastapi import Header, Path, Query, Request
from fastapi.dependencies.models import Dependant

from app.errors import InvalidInput
from app.helpers.etags import IF_MATCH_PATTERN, IF_NONE_MATCH_PATTERN
from app.helpers.pagination import CURSOR_PATTERN, DEFAULT_LIMIT, MAX_LIMIT
from app.schemas.common import ID_PATTERN
from app.words import CONTROLLER_FORMATS, ControllerFormat

Limit = Annotated[int, Query(ge=1, le=MAX_LIMIT, description="page size (max 500)")]
Cursor = Annotated[
    str | None, Query(pattern=CURSOR_PATTERN, description="next_cursor of the last page")
]
DEFAULT_PAGE = DEFAULT_LIMIT
#: Path ids: anything but an id this service could have issued is refused (422) before a
#: database sees it.
PathId = Annotated[str, Path(pattern=ID_PATTERN, description="resource id")]
#: Version numbers start at 1 and fit every database's 32-bit integer.
VersionNumber = Annotated[int, Path(ge=1, le=2**31 - 1, description="version number")]
IdempotencyKey = Annotated[
    str | None,
    Header(
        min_length=1,
        max_length=200,
        description="retry-safe submissions: same key and body -> the first response",
    ),
]
IfMatch = Annotated[
    str | None,
    Header(pattern=IF_MATCH_PATTERN, description="the tool's ETag (or *); 412 when stale"),
]


def _query_names(dependant: Dependant) -> set[str]:
    """The query parameters a route (or dependency) and its dependencies declare."""
    names = {p.alias for p in dependant.query_params}
    for sub in dependant.dependencies:
        names |= _query_names(sub)
    return names


def known_query_only(request: Request) -> None:
    """A dependency that refuses (422, naming them) query parameters the route does not
    take: where a misspelt filter would otherwise be ignored and answer with everything."""
    dependant = getattr(request.scope.get("route"), "dependant", None)
    if not isinstance(dependant, Dependant):
        return
    known = _query_names(dependant)
    unknown = sorted(set(request.query_params) - known)
    if unknown:
        raise InvalidInput(
            "validation",
            f"unknown query parameter{'s' if len(unknown) > 1 else ''} "
            f"{', '.join(unknown)}: this route takes {', '.join(sorted(known))}",
            loc=("query", unknown[0]),
        )


@dataclass(frozen=True)
class RawParam:
    """A request parameter a route reads itself instead of declaring it to FastAPI: on the
    hot read, FastAPI's per-request inspection of declared parameters (path, query and
    headers) cost more than the database statement (profiled under bench/wrk_load.py). It is
    documented in OpenAPI as a declared one would be (`openapi()`, for the route's
    `openapi_extra`) and refused with the same 422 problem, naming it, when it breaks its
    rule."""

    where: Literal["path", "query", "header"]
    name: str  # as in OpenAPI (headers in lower case)
    title: str
    rule: str  # what a valid value is, for the 422
    description: str | None = None
    pattern: str | None = None
    max_length: int | None = None
    choices: tuple[str, ...] | None = None

    def openapi(self) -> dict[str, object]:
        schema: dict[str, object] = {"title": self.title, "type": "string"}
        if self.description is not None:
            schema["description"] = self.description
        if self.pattern is not None:
            schema["pattern"] = self.pattern
        if self.max_length is not None:
            schema["maxLength"] = self.max_length
        if self.choices is not None:
            schema["enum"] = list(self.choices)
        doc: dict[str, object] = {"in": self.where, "name": self.name}
        if self.description is not None:
            doc["description"] = self.description
        return {**doc, "required": self.where == "path", "schema": schema}

    def read(self, request: Request) -> str | None:
        """The parameter's value (None when an optional one is absent), or 422 naming it."""
        if self.where == "path":
            value: str | None = request.path_params[self.name]
        elif self.where == "query":
            value = request.query_params.get(self.name)
        else:
            value = request.headers.get(self.name)
        if value is None:
            return None
        if (
            (self.max_length is not None and len(value) > self.max_length)
            or (self.pattern is not None and re.match(self.pattern, value) is None)
            or (self.choices is not None and value not in self.choices)
        ):
            raise InvalidInput(
                "validation", f"{self.where} {self.title}: {self.rule}", loc=(self.where, self.name)
            )
        return value


#: A hot read's If-None-Match, read by hand (a tool's /tcp, a frame's /frame).
IF_NONE_MATCH = RawParam(
    "header",
    "if-none-match",
    "If-None-Match",
    'the ETag of an earlier answer (a quoted hex string, e.g. "3f2a...") or *; '
    "send back the ETag header you were given",
    pattern=IF_NONE_MATCH_PATTERN,
)


#: A served subject's controller format (?format=) and Accept, read by hand on the hot reads
#: (GET /v1/tools/{id}/tcp, /v1/frames/{id}/frame) and as parameters on the tables.
FORMAT = RawParam(
    "query",
    "format",
    "Format",
    f"one of {', '.join(CONTROLLER_FORMATS)}, or leave it out for JSON alone",
    description="controller text format",
    choices=CONTROLLER_FORMATS,
)
ACCEPT = RawParam(
    "header", "accept", "Accept", "at most 1000 characters (e.g. text/plain)", max_length=1000
)
FormatQuery = Annotated[ControllerFormat | None, Query(description="controller text format")]
AcceptHeader = Annotated[
    str | None,
    Header(max_length=1000, description="text/plain: the controller file (with ?format=)"),
]
