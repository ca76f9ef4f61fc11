"""Each list is written once: the schemas name the libraries' Literals, and every
method-derived list equals the registry's."""

from __future__ import annotations

from typing import get_args

from pydantic import BaseModel

from app.api.methods import describe
from app.exports import CONTROLLER_FORMATS, ControllerFormat
from app.kinematics.poses import POSE_FORMATS, PoseFormat
from app.methods import METHOD_NAMES, METHODS
from app.methods.npoint import NPointOptions
from app.methods.requests import SOLVE_MODELS, CalibrationRequest
from app.models import Deployment, GuidedSession, ToolControllerState
from app.schemas.controllers import Deployment as DeploymentOut
from app.schemas.controllers import ReconciledTool, Reconciliation
from app.schemas.fleet import FleetController
from app.schemas.formats import FormatList
from app.schemas.references import TouchIn
from app.schemas.sessions import PlanRequest
from app.schemas.sessions import Session as SessionOut
from app.services.controller_states import EVENT_STATES, SEVERITY
from app.solvers.npoint import ALGORITHMS, Algorithm
from app.statuses import ROBOT_STATES, DeploymentStatus, RobotState, SessionStatus, ToolState


def _annotation(model: type[BaseModel], field: str) -> object:
    return model.model_fields[field].annotation


def test_the_schemas_take_the_libraries_literals() -> None:
    """Pose formats, controller formats and algorithms are each one Literal, in the library
    that parses or solves them; the request and response models name that very object, and the
    tuples the libraries check against are read off it."""
    assert _annotation(PlanRequest, "format") is PoseFormat
    assert _annotation(TouchIn, "format") is PoseFormat
    assert get_args(PoseFormat) == POSE_FORMATS
    assert _annotation(FormatList, "controllers") == list[ControllerFormat]
    assert get_args(ControllerFormat) == CONTROLLER_FORMATS
    assert _annotation(NPointOptions, "algorithm") is Algorithm
    assert get_args(Algorithm) == ALGORITHMS


def test_the_request_unions_are_the_registry() -> None:
    union, _discriminator = get_args(CalibrationRequest)
    assert get_args(union) == tuple(m.request for m in METHODS)
    assert [m.__mro__[1] for m in SOLVE_MODELS] == [m.request for m in METHODS]
    assert [describe(m).name for m in METHODS] == list(METHOD_NAMES)
    assert len(set(METHOD_NAMES)) == len(METHODS) == 8


def test_the_status_documents_and_rows_share_one_literal() -> None:
    documents = [
        (SessionOut.model_fields["status"].annotation, SessionStatus),
        (DeploymentOut.model_fields["status"].annotation, DeploymentStatus),
        (ReconciledTool.model_fields["state"].annotation, ToolState),
        (FleetController.model_fields["state"].annotation, ToolState),
        (Reconciliation.model_fields["state"].annotation, RobotState),
    ]
    for annotation, literal in documents:
        assert get_args(annotation) == get_args(literal)
    # the rows name the same Literal (their annotations are strings: __future__ annotations)
    assert GuidedSession.__annotations__["status"] == "Mapped[SessionStatus]"
    assert Deployment.__annotations__["status"] == "Mapped[DeploymentStatus]"
    assert ToolControllerState.__annotations__["state"] == "Mapped[ToolState]"


def test_every_controller_state_has_a_severity_naming_a_robot_state() -> None:
    assert set(SEVERITY) == set(get_args(ToolState))
    assert all(ROBOT_STATES[SEVERITY[state]] == state for state in ROBOT_STATES)
    assert set(EVENT_STATES) <= set(get_args(ToolState))
