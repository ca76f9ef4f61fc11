"""A frame's re-check after a move (contract v1.4 "After a move: re-register", issue 49), end
to end: the check and its correction (app.services.frames.checks, one write transaction under
the frame's lock, the answer kept for an Idempotency-Key), then each corrected frame's new
version deployed by the deployment code every subject shares
(app.services.controllers.deployments), no transaction open during the controller's I/O, and
the kept answer completed with the deployments, as a tool's re-check is
(app.services.checks.recheck). Deployed when the robot has a controller and `deploy` is not
false; a controller that cannot address the frame is refused before anything is written.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

from sqlalchemy.orm import Session

from app.schemas.frame_checks import FrameCheck, FrameCheckCreate
from app.security.auth import Principal, transaction_for
from app.services import idempotency
from app.services.controllers import deployments
from app.services.controllers.failures import controller_problem
from app.services.frames import checks as frames
from app.services.frames.subject import FRAME
from app.services.lifecycle import versions as lifecycle
from app.services.robots.connection import settings_of
from app.storage.models import RobotController
from app.vendors.registry import frame_writer_missing


@dataclass(frozen=True)
class Checked:
    """The answer (the FrameCheck document), and whether it is the first answer replayed."""

    check: FrameCheck
    replayed: bool


def check_frame(
    *,
    frame_id: str,
    data: FrameCheckCreate,
    actor: Principal,
    idempotency_key: str | None,
    on_stored: Callable[[FrameCheck], None] | None = None,
) -> Checked:
    """POST /v1/frames/{frame_id}/checks (and the MQTT command, and the CLI): check, correct
    when asked and deploy the correction where the robot has a controller (after the check's
    transaction, no transaction open during the controller's I/O); the first answer again
    for a repeated Idempotency-Key, its deployment included. `on_stored` is told the check
    once its transaction has committed, before any deployment (a recheck session's finish:
    from then on the check is made, whatever the deployment does)."""
    frames.check_options(data)
    keyed = None if idempotency_key is None else (idempotency_key, fingerprint(frame_id, data))
    with transaction_for(actor, write=False) as session:
        plan = _deployment_plan(session, frame_id) if frames.deploys(data) else _NO_DEPLOYMENT
    deploying = plan.deploying
    with transaction_for(actor, write=True) as session:
        lifecycle.lock(session, FRAME, frame_id)  # a repeated key waits here for the first
        first = _replay(session, actor, keyed)
        if first is None:
            result = frames.check_and_correct(
                session,
                frame_id=frame_id,
                data=data,
                actor=actor,
                deploying=deploying,
                by_hand=plan.by_hand,
            )
            idempotency.remember_keyed(
                session, actor=actor, keyed=keyed, response=result.model_dump(mode="json")
            )
    if first is None and on_stored is not None:
        on_stored(result)
    if first is not None:  # (its deployment may still be under way: waited for unlocked)
        return Checked(_as_it_ends(first, deploying, actor, keyed), replayed=True)
    if result.correction is not None and deploying:
        result = _deploy(result, data, actor=actor, keyed=keyed)
    return Checked(result, replayed=False)


def fingerprint(frame_id: str, data: FrameCheckCreate) -> str:
    """What a repeated Idempotency-Key's check must equal (a recheck session's finish too)."""
    return idempotency.request_fingerprint(
        f"frame-check:{frame_id}", data.model_dump(mode="json", exclude_unset=True)
    )


@dataclass(frozen=True)
class _Plan:
    """Whether a correction is deployed, and (`by_hand`) why none can be: the words of the
    501 /no-frame-writer a deployment would get, the file to load by hand in them."""

    deploying: bool
    by_hand: str | None = None


_NO_DEPLOYMENT = _Plan(deploying=False)


def _deployment_plan(session: Session, frame_id: str) -> _Plan:
    """Whether a correction is deployed: the robot has a controller (none: nothing to deploy
    to, the summary says how to load the frame); one that cannot address the frame is
    refused before anything is written, 422 naming the frame field it needs, as a tool's
    re-check is; one no remote interface of which writes a frame
    (registry.frame_writer_missing) is not sent anything, and the answer says so and which
    file to load by hand (contract v1.4)."""
    frame = lifecycle.get_live(session, FRAME, frame_id)
    controller = session.get(RobotController, frame.robot_id)
    if controller is None:
        return _NO_DEPLOYMENT
    deployments.subject_target(FRAME, controller.protocol, frame)
    missing = frame_writer_missing(controller.protocol)
    if missing is None:
        return _Plan(deploying=True)
    refused = controller_problem(
        missing,
        settings_of(controller),
        robot_id=frame.robot_id,
        left="the new version is active in tcpcal",
        refusal="remedy",
    )
    return _Plan(deploying=False, by_hand=refused.detail)


def _replay(session: Session, actor: Principal, keyed: tuple[str, str] | None) -> FrameCheck | None:
    first = idempotency.replay_keyed(session, actor=actor, keyed=keyed)
    return None if first is None else FrameCheck.model_validate(first)


def _as_it_ends(
    first: FrameCheck, deploying: bool, actor: Principal, keyed: tuple[str, str] | None
) -> FrameCheck:
    """The first answer as the first request ends it: kept before its deployment and
    replaced after (as a tool's re-check, app.services.checks.recheck), so a repeat arriving
    in between waits for the final one and no second deployment is made."""
    deadline = time.monotonic() + deployments.DEPLOYMENT_WAIT_S
    while _undeployed(first, deploying) and time.monotonic() < deadline:
        time.sleep(0.1)
        with transaction_for(actor, write=False) as session:
            kept = idempotency.replay_keyed(session, actor=actor, keyed=keyed, purge=False)
            first = first if kept is None else FrameCheck.model_validate(kept)
    return first


def _undeployed(answer: FrameCheck, deploying: bool) -> bool:
    return deploying and answer.correction is not None and answer.correction.deployment is None


def _deploy(
    result: FrameCheck,
    data: FrameCheckCreate,
    *,
    actor: Principal,
    keyed: tuple[str, str] | None,
) -> FrameCheck:
    """Each corrected frame deployed (the checked one, and with scope "robot" every other
    one) by the frames' deployment code; a failure is recorded as any attempt is, flags the
    frame's controller state as a tool's re-check does and is said, the new versions
    staying active. The answer kept for the key becomes this one."""
    correction = result.correction
    assert correction is not None
    failures: list[str] = []
    failed: list[deployments.Attempt] = []
    attempted = deployments.attempt(
        FRAME, subject_id=result.frame_id, actor=actor, reason=data.reason
    )
    correction.deployment = attempted.document.model_dump(mode="json")
    if attempted.error is not None:
        failures.append(f"frame {result.frame_id}: {attempted.error.detail}")
        failed.append(attempted)
    for moved in correction.moved:
        if moved.kind != "frame":
            continue
        other = deployments.attempt(FRAME, subject_id=moved.id, actor=actor, reason=data.reason)
        moved.deployment = other.document.model_dump(mode="json")
        if other.error is not None:
            failures.append(f"frame {moved.name!r}: {other.error.detail}")
            failed.append(other)
    result.summary = _with_deployments(result, failures)
    if failed or keyed is not None:
        with transaction_for(actor, write=True) as session:
            for each in failed:  # the controller does not hold the new version (as a tool's)
                deployments.flag_failed(session, each, actor)
            if keyed is not None:
                idempotency.replace(
                    session, actor=actor, key=keyed[0], response=result.model_dump(mode="json")
                )
    return result


def _with_deployments(result: FrameCheck, failures: list[str]) -> str:
    """The check's sentence with what became of the deployments in place of "follows"."""
    correction = result.correction
    assert correction is not None
    assert correction.deployment is not None
    said = result.summary.removesuffix(frames.DEPLOYMENT_FOLLOWS)
    target = correction.deployment.get("target")
    deployed = 1 + sum(1 for m in correction.moved if m.deployment is not None)
    if not failures:
        where = f"to {target}" if deployed == 1 else f"({deployed} frames)"
        return f"{said}; deployed {where} and read back as written (verified)"
    return (
        f"{said}; active in tcpcal, but its deployment failed ({'; '.join(failures)}): "
        f"deploy again (POST /v1/frames/{result.frame_id}/deployments) once the controller answers"
    )
