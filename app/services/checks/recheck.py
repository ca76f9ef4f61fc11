"""A re-check after a collision (issue 41): one touch at a reference point, read from the
controller, checks the active TCP and, when asked (`correct`: "within_limits") and the
deviation lies beyond check_mm but within the tool's max_correction_mm, corrects it: the one
path every check takes, over HTTP, MQTT and the CLI.

The steps, and why each is where it is:
1. a read transaction refuses what can be refused before the robot is read (no active
   version, no such point, no controller, a tool the controller cannot address), and
   replays the first answer to an Idempotency-Key;
2. the controller's read, no transaction open (app.services.checks.checks.capture_touch);
3. one write transaction, under the tool's lock (so a repeated key waits for the first and
   replays it): the check recorded and, for a correction, a calibration by xyz_reference
   from that touch (orientation kept from the active version, the reference point's
   covariance and the touch noise propagated into the version's), its activation (kind
   `check_correction`, the reason) and the answer kept for the key;
4. the deployment (app.services.controllers.deployments, no transaction open during its I/O), then
one
   write transaction: a failed deployment flags the controller (the tool's controller state:
   unreachable, or drifted since it does not hold the active version) and the kept answer
   becomes the final one.
Beyond max_correction_mm nothing changes but the check's record (attention `check_failed`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from sqlalchemy.orm import Session

from app.errors import InvalidInput
from app.helpers.tolerance import effective_tolerance
from app.methods.reference import XYZ_REFERENCE, XyzReferenceCalibration
from app.schemas.controllers import Deployment
from app.schemas.references import CheckCreate, CheckResult, Correction
from app.security.auth import Principal, transaction_for
from app.services import idempotency
from app.services.calibrations import grading, writes
from app.services.calibrations.contexts import DbContext
from app.services.calibrations.grading import Outcome
from app.services.calibrations.presolve import Presolved, Snapshot
from app.services.calibrations.verdict import recheck_summary
from app.services.checks import checks
from app.services.controllers import deployments
from app.services.lifecycle.versions import activate
from app.services.robots.connection import get_controller
from app.services.robots.robots import get_robot
from app.services.tools.activation import CHECK_CORRECTION
from app.services.tools.subject import TOOL
from app.services.tools.tools import get_tool
from app.services.tools.versions import lock_tool


@dataclass(frozen=True)
class Rechecked:
    """The answer (the Check document), and whether it is the first answer replayed."""

    check: CheckResult
    replayed: bool


def recheck(
    *, tool_id: str, data: CheckCreate, actor: Principal, idempotency_key: str | None
) -> Rechecked:
    """POST /v1/tools/{tool_id}/checks (and the MQTT command, and the CLI): check, and
    correct and deploy when asked; the first answer again for a repeated Idempotency-Key."""
    _check_options(data)
    fingerprint = idempotency.request_fingerprint(
        f"check:{tool_id}", data.model_dump(mode="json", exclude_unset=True)
    )
    keyed = None if idempotency_key is None else (idempotency_key, fingerprint)
    with transaction_for(actor, write=False) as session:
        first = _replay(session, actor, keyed, purge=False)
        if first is None and data.correct == "within_limits" and _deploys(data):
            _refuse_undeployable(session, tool_id)
    if first is not None:
        return Rechecked(_as_it_ends(first, data, actor, keyed), replayed=True)
    captured = checks.capture_touch(tool_id, data, actor) if data.capture else None
    typed = data if captured is None else checks.as_typed(data, captured)
    with transaction_for(actor, write=True) as session:
        lock_tool(session, tool_id)  # a repeated key waits here for the first, then replays
        first = _replay(session, actor, keyed, purge=True)
        if first is None:
            result = _check_and_correct(
                session, tool_id=tool_id, data=typed, actor=actor, captured=captured
            )
            idempotency.remember_keyed(
                session, actor=actor, keyed=keyed, response=result.model_dump(mode="json")
            )
    if first is not None:  # (its deployment may still be under way: waited for unlocked)
        return Rechecked(_as_it_ends(first, data, actor, keyed), replayed=True)
    if result.correction is not None and _deploys(data):
        result = _deploy(result, actor=actor, reason=data.reason, keyed=keyed)
    return Rechecked(result, replayed=False)


def _check_options(data: CheckCreate) -> None:
    """422 /invalid-options for `correct` without a captured touch, or `deploy` without a
    correction. Checked here, not by the request model: the OpenAPI schema states which of
    typed and captured a check is (oneOf), not these pairings, and a schema-valid request is
    refused for its meaning, by a domain problem, not as a malformed one (/validation)."""
    if data.capture is None and data.correct != "never":
        raise InvalidInput(
            "invalid-options",
            '"correct": "within_limits" corrects from one touch read from the controller: '
            'send "capture": true in place of format and poses',
            loc=("body", "correct"),
        )
    if data.deploy is not None and data.correct == "never":
        raise InvalidInput(
            "invalid-options",
            '"deploy" applies to a correction: send "correct": "within_limits" with it, '
            "or leave deploy out",
            loc=("body", "deploy"),
        )


def _as_it_ends(
    first: CheckResult, data: CheckCreate, actor: Principal, keyed: tuple[str, str] | None
) -> CheckResult:
    """The first answer as the first request ends it. Its answer is kept before its
    deployment (so that a repeat waiting at the tool's lock replays it, not corrects again)
    and replaced after; a repeat arriving in between waits for the final one, so a PLC
    repeating its command gets what the first got, deployment included."""
    deadline = time.monotonic() + deployments.DEPLOYMENT_WAIT_S
    while _deploying(first, data) and time.monotonic() < deadline:
        time.sleep(0.1)
        with transaction_for(actor, write=False) as session:
            first = _replay(session, actor, keyed, purge=False) or first
    return first


def _deploying(answer: CheckResult, data: CheckCreate) -> bool:
    """A correction the first request is still deploying (its deployment not yet kept)."""
    return answer.correction is not None and answer.correction.deployment is None and _deploys(data)


def _deploys(data: CheckCreate) -> bool:
    """Deploy a correction unless told not to (a re-check captures, so the robot has a
    controller)."""
    return data.deploy is not False


def _refuse_undeployable(session: Session, tool_id: str) -> None:
    """A correction that could not be deployed is refused before anything is read or
    written: 409 without a controller, 422 naming the tool field its controller needs."""
    tool = get_tool(session, tool_id)
    controller = get_controller(session, tool.robot_id)
    deployments.subject_target(TOOL, controller.protocol, tool)


def _replay(
    session: Session, actor: Principal, keyed: tuple[str, str] | None, *, purge: bool
) -> CheckResult | None:
    first = idempotency.replay_keyed(session, actor=actor, keyed=keyed, purge=purge)
    return None if first is None else CheckResult.model_validate(first)


def _check_and_correct(
    session: Session,
    *,
    tool_id: str,
    data: CheckCreate,
    actor: Principal,
    captured: checks.Captured | None,
) -> CheckResult:
    """The check recorded and, when due, the correction stored and activated."""
    measured = checks.measure(session, tool_id=tool_id, data=data, actor=actor)
    result = measured.result
    limits = effective_tolerance(measured.tool.tolerance)
    due = data.correct == "within_limits" and captured is not None and not result.within_tolerance
    if due and result.distance_mm > limits.max_correction_mm:
        result.verdict = "recalibrate"
        due = False  # beyond the limit: nothing is solved, nothing changes
    solved = _solve_correction(session, measured, captured) if due else None
    if solved is not None:
        new_tcp = np.asarray(solved.result.tcp.position_mm, dtype=float)
        result.verdict = "corrected"
        result.correction = Correction(
            version=lock_tool(session, tool_id).next_version,
            previous_version=result.version,
            delta_mm=[float(v) for v in new_tcp - measured.frame.position_mm],
            deployment=None,
        )
    result.summary = recheck_summary(
        result, max_correction_mm=limits.max_correction_mm, deploying=_deploys(data)
    )
    checks.record(session, measured, actor, None if captured is None else captured.capture)
    if result.correction is not None and solved is not None and captured is not None:
        _store_correction(session, measured, solved, captured, data, actor)
    return result


def _correction_request(
    measured: checks.Measured, captured: checks.Captured
) -> XyzReferenceCalibration:
    """The correction as the calibration it is: xyz_reference from the one touch."""
    return XyzReferenceCalibration.model_validate(
        {
            "method": XYZ_REFERENCE.name,
            "format": checks.CAPTURE_FORMAT,
            "poses": [captured.pose],
            "options": {"reference_point_id": measured.point.id},
            "activate": "never",  # activated below, with its own kind
            "note": f"re-check correction of version {measured.result.version}",
        }
    )


def _solve_correction(
    session: Session, measured: checks.Measured, captured: checks.Captured | None
) -> Outcome | None:
    """The correction solved (nothing written); None when it is not accepted by the tool's
    tolerance (then the tool needs recalibrating)."""
    if captured is None:
        return None
    tool = measured.tool
    ctx = DbContext(session, tool, get_robot(session, tool.robot_id))
    outcome = grading.solve(_correction_request(measured, captured), ctx)
    if outcome.result.status != "accepted":
        measured.result.verdict = "recalibrate"
        return None
    return outcome


def _store_correction(
    session: Session,
    measured: checks.Measured,
    solved: Outcome,
    captured: checks.Captured,
    data: CheckCreate,
    actor: Principal,
) -> None:
    """The calibration and its version (stored as any calibration is), then its activation
    with kind check_correction and the person's reason; in the check's transaction."""
    request = _correction_request(measured, captured)
    tool = lock_tool(session, measured.tool.id)
    snapshot = Snapshot(tool.tolerance, tool.active_version, tool.kinematics)
    stored, _ = writes.submit(
        session,
        tool_id=tool.id,
        request=request,
        raw_body=request.model_dump(mode="json", exclude_none=True),
        idempotency_key=None,
        actor=actor,
        solved=Presolved(snapshot, solved),
    )
    correction = measured.result.correction
    assert correction is not None
    assert stored.version == correction.version
    activate(
        session,
        TOOL,
        locked=lock_tool(session, tool.id),
        version=stored.version,
        reason=CHECK_CORRECTION,
        reason_text=data.reason,
        actor=actor,
        details={
            "status": stored.status,
            "checked_version": correction.previous_version,
            "delta_mm": correction.delta_mm,
            "reference_point_id": measured.point.id,
        },
    )


def _deploy(
    result: CheckResult, *, actor: Principal, reason: str | None, keyed: tuple[str, str] | None
) -> CheckResult:
    """Deploy the corrected version; a failure flags the controller and is said, the new
    version staying active. The answer kept for the key becomes this one."""
    correction = result.correction
    assert correction is not None
    attempt = deployments.attempt(TOOL, subject_id=result.tool_id, actor=actor, reason=reason)
    correction.deployment = _deployment(attempt)
    if attempt.error is not None:
        result.verdict = "deployment_failed"
    tolerance = None
    with transaction_for(actor, write=True) as session:
        tool = get_tool(session, result.tool_id)
        tolerance = effective_tolerance(tool.tolerance)
        if attempt.error is not None:
            deployments.flag_failed(session, attempt, actor)
        result.summary = recheck_summary(
            result, max_correction_mm=tolerance.max_correction_mm, failure=attempt.error
        )
        if keyed is not None:
            idempotency.replace(
                session, actor=actor, key=keyed[0], response=result.model_dump(mode="json")
            )
    return result


def _deployment(attempt: deployments.Attempt) -> Deployment:
    """A tool's deployment as served (the tool's deployment schema)."""
    document = attempt.document
    assert isinstance(document, Deployment)
    return document
