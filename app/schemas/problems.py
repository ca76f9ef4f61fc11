"""The RFC 9457 problem document every error is answered with, as the OpenAPI spec shows it."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field


class ProblemError(BaseModel):
    loc: list[str | int] = Field(description="path to the offending value, e.g. body.poses.3")
    msg: str


class Problem(BaseModel):
    """application/problem+json; `type` ends in the kind, e.g. /degenerate-poses."""

    model_config = ConfigDict(extra="allow")

    type: str
    title: str
    status: int
    detail: str
    errors: list[ProblemError] | None = None
