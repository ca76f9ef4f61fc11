"""MQTT commands (issue 41): a cell PLC or robot program asks for a re-check without a person.

`{prefix}/commands/recheck`, QoS 1, a JSON object `{"request_id", "tool_id",
"reference_point_id", "correct"?, "deploy"?, "reason"?}` and an API key of calibrate scope in
the MQTT 5 user property `authorization` (the key, or `Bearer <key>`), is answered on
`{prefix}/replies/{request_id}`, QoS 1, with what `POST /v1/tools/{tool_id}/checks`
`{"capture": true, ...}` answers: the Check document, or its problem+json document. Both
run the one service function (app.services.checks.recheck.recheck) with the request_id as the
Idempotency-Key, so the record is the same as the HTTP call's and a repeated request_id (a
PLC that lost the reply and sends the command again) gets the first answer again and changes
nothing. The problem documents are the HTTP layer's own (app.api.problems).

`{prefix}/commands/recheck-frame` does the same for a frame's re-check after a move (issue
49): `{"request_id", "frame_id"}` and the body of `POST /v1/frames/{frame_id}/checks`
(app.services.checks.frame_recheck.check_frame), answered with its FrameCheck.

The key is never logged, echoed or kept: the log names the key's name, as the access log
does. Off unless TCPCAL_MQTT_COMMANDS=true (app.publish.mqtt subscribes only then).

A command's JSON is read before its key is checked: without its request_id there is no
topic to answer on. A command with no usable request_id (not JSON, not an object, no
request_id or one that cannot be a topic level) is answered on `{prefix}/replies/_invalid`,
which no request_id can name.
"""

from __future__ import annotations

import json
import logging
import queue
import re
import threading
from collections.abc import Callable
from dataclasses import dataclass, field

from fastapi.exceptions import RequestValidationError
from pydantic import ValidationError
from sqlalchemy.exc import IntegrityError
from starlette.responses import JSONResponse

from app.api.problems import (
    domain_error_response,
    integrity_response,
    internal_error_response,
    validation_response,
)
from app.errors import DomainError, Unauthorized
from app.jsontypes import JsonObject
from app.schemas.frame_checks import FrameCheckCreate
from app.schemas.references import CheckCreate
from app.security.auth import Principal, authenticate_key
from app.services.checks import frame_recheck as frame_checks
from app.services.checks import recheck
from app.storage.db import session_scope

log = logging.getLogger(__name__)

#: The user property that carries the API key (MQTT 5 user properties, 3.3.2.3.7).
AUTHORIZATION = "authorization"
#: A request_id is one topic level (no '/', '+', '#') and an Idempotency-Key (at most 200
#: characters); starting with a letter or digit, so `_invalid` is never one.
REQUEST_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9._:-]{0,199}")
#: Where a command with no usable request_id is answered.
INVALID_REPLY = "_invalid"
#: The command's own fields; the rest are the check's (CheckCreate), except those that would
#: make it something other than a re-check from the controller.
ENVELOPE = ("request_id", "tool_id")
NOT_IN_A_COMMAND = ("capture", "format", "poses", "units")
#: Commands run at once (one slow controller does not hold up another cell's command).
WORKERS = 4


#: The commands, by the last level of their topic: a tool's re-check after a collision, and
#: a frame's after a move (issue 49: `{"request_id", "frame_id", ...}` and the body of POST
#: /v1/frames/{frame_id}/checks, its touches typed: a frame's touches are not captured yet).
RECHECK = "recheck"
RECHECK_FRAME = "recheck-frame"
COMMANDS = (RECHECK, RECHECK_FRAME)


def recheck_topic(prefix: str, command: str = RECHECK) -> str:
    """The topic a command arrives on."""
    return f"{prefix}/commands/{command}"


def command_of(prefix: str, topic: str) -> str:
    """The command a topic carries (RECHECK for any topic not another command's)."""
    for command in COMMANDS:
        if topic == recheck_topic(prefix, command):
            return command
    return RECHECK


def reply_topic(prefix: str, request_id: str) -> str:
    """The topic a command's answer is published on."""
    return f"{prefix}/replies/{request_id}"


@dataclass(frozen=True, slots=True)
class Reply:
    """A command's answer: its topic, its JSON, and the HTTP status the same request gets
    (201 for the Check; the problem's status)."""

    topic: str
    payload: bytes
    status: int
    replayed: bool = False

    @property
    def content_type(self) -> str:
        return "application/json" if self.status < 400 else "application/problem+json"


def answer(prefix: str, payload: bytes, authorization: str | None, command: str = RECHECK) -> Reply:
    """Run one command and say what to reply (never raises)."""
    try:
        document = _json_object(payload)
    except _Refused as refused:
        return _problem(prefix, INVALID_REPLY, refused.response)
    request_id = document.get("request_id")
    if not isinstance(request_id, str) or not REQUEST_ID.fullmatch(request_id):
        return _problem(prefix, INVALID_REPLY, _invalid_request_id(request_id))
    try:
        actor = _authenticated(authorization)
        if command == RECHECK_FRAME:
            return _frame_answer(prefix, request_id, document, actor)
        tool_id, data = _command(document)
        done = recheck.recheck(tool_id=tool_id, data=data, actor=actor, idempotency_key=request_id)
    except _Refused as refused:
        return _problem(prefix, request_id, refused.response)
    except DomainError as exc:
        return _problem(prefix, request_id, domain_error_response(exc))
    except IntegrityError as exc:  # a concurrent duplicate lost the idempotency race
        return _problem(prefix, request_id, integrity_response(exc))
    except Exception:  # a bug: logged (never with the key), answered as HTTP answers it
        log.exception("recheck command %s failed", request_id)
        return _problem(prefix, request_id, internal_error_response())
    body = done.check.model_dump(mode="json", by_alias=True)
    log.info(
        "recheck command %s on tool %s by key %r: %s%s",
        request_id,
        tool_id,
        actor.name,
        done.check.verdict,
        " (replayed)" if done.replayed else "",
    )
    return Reply(reply_topic(prefix, request_id), _compact(body), 201, done.replayed)


def _frame_answer(prefix: str, request_id: str, document: JsonObject, actor: Principal) -> Reply:
    """A frame's re-check after a move (raises what `answer` turns into a problem)."""
    frame_id = document.get("frame_id")
    fields = {k: v for k, v in document.items() if k not in ("request_id", "frame_id")}
    errors: list[dict[str, object]] = []
    if not isinstance(frame_id, str) or not frame_id:
        errors.append({"type": "missing", "loc": ("body", "frame_id"), "msg": "Field required"})
    data = None
    try:
        data = FrameCheckCreate.model_validate(fields)
    except ValidationError as exc:
        errors += [{**e, "loc": ("body", *e["loc"])} for e in exc.errors(include_input=False)]
    if errors or data is None or not isinstance(frame_id, str):
        raise _Refused(validation_response(RequestValidationError(errors), "application/json"))
    done = frame_checks.check_frame(
        frame_id=frame_id, data=data, actor=actor, idempotency_key=request_id
    )
    log.info(
        "recheck-frame command %s on frame %s by key %r: %s%s",
        request_id,
        frame_id,
        actor.name,
        done.check.verdict,
        " (replayed)" if done.replayed else "",
    )
    body = done.check.model_dump(mode="json")
    return Reply(reply_topic(prefix, request_id), _compact(body), 201, done.replayed)


class _Refused(Exception):
    """A command refused before the service ran, with its problem response."""

    def __init__(self, response: JSONResponse) -> None:
        super().__init__(response.status_code)
        self.response = response


def _json_object(payload: bytes) -> JsonObject:
    try:
        document = json.loads(payload)
    except (UnicodeDecodeError, ValueError) as exc:
        raise _Refused(
            _invalid("json_invalid", (), f"not JSON ({exc}); send a JSON object")
        ) from None
    if not isinstance(document, dict):
        raise _Refused(_invalid("model_type", (), "send a JSON object, not a JSON array or value"))
    return document


def _invalid_request_id(value: object) -> JSONResponse:
    reason = "Field required" if value is None else "must be 1-200 letters, digits and . _ : -"
    return _invalid("value_error", ("request_id",), f"{reason}: it names the reply topic")


def _invalid(kind: str, loc: tuple[str, ...], msg: str) -> JSONResponse:
    """422 naming the field, as the HTTP layer words a request validation error."""
    error = {"type": kind, "loc": ("body", *loc), "msg": msg}
    return validation_response(RequestValidationError([error]), "application/json")


def _authenticated(authorization: str | None) -> Principal:
    """The key's caller, of calibrate scope (401 missing or unknown, 403 a read key)."""
    key = (authorization or "").strip()
    if key[:7].lower() == "bearer ":
        key = key[7:].strip()
    if not key:
        raise Unauthorized(
            "no API key: send a key of calibrate scope in the MQTT 5 user property "
            f"'{AUTHORIZATION}' (the key itself, or 'Bearer <key>')"
        )
    with session_scope(write=False) as session:
        return authenticate_key(session, key, required="calibrate")


def _command(document: JsonObject) -> tuple[str, CheckCreate]:
    """The tool and the check a command asks for; 422 naming every offending field."""
    errors: list[dict[str, object]] = []
    tool_id = document.get("tool_id")
    if not isinstance(tool_id, str) or not tool_id:
        errors.append({"type": "missing", "loc": ("body", "tool_id"), "msg": "Field required"})
    for name in NOT_IN_A_COMMAND:
        if name in document:
            msg = "not a command field: a command always captures the touch from the controller"
            errors.append({"type": "extra_forbidden", "loc": ("body", name), "msg": msg})
    fields = {k: v for k, v in document.items() if k not in (*ENVELOPE, *NOT_IN_A_COMMAND)}
    data = None
    try:
        data = CheckCreate.model_validate({**fields, "capture": True})
    except ValidationError as exc:
        errors += [{**e, "loc": ("body", *e["loc"])} for e in exc.errors(include_input=False)]
    if errors or data is None or not isinstance(tool_id, str):
        raise _Refused(validation_response(RequestValidationError(errors), "application/json"))
    return tool_id, data


def _problem(prefix: str, request_id: str, response: JSONResponse) -> Reply:
    log.info("recheck command %s refused: %s", request_id, response.status_code)
    return Reply(reply_topic(prefix, request_id), bytes(response.body), response.status_code)


def _compact(document: JsonObject) -> bytes:
    return json.dumps(document, separators=(",", ":")).encode()


@dataclass
class Workers:
    """Commands run in worker threads, off paho's network thread (which must keep reading
    the socket: a command waits for a controller for up to its timeout_s). Stopping does not
    wait for a command under way, so that SIGTERM still ends the publisher within a second
    (daemon threads; `tcpcal publish` leaves with os._exit): its answer is then not sent, and
    the PLC, having no reply, sends the same request_id again to the next publisher (the
    first answer, if it was kept, or the command run once)."""

    prefix: str
    send: Callable[[Reply], None]
    count: int = WORKERS
    _queue: queue.Queue[tuple[bytes, str | None, str]] = field(default_factory=queue.Queue)
    _stopping: threading.Event = field(default_factory=threading.Event)

    def start(self) -> None:
        for i in range(self.count):
            name = f"mqtt-command-{i + 1}"
            threading.Thread(target=self._work, name=name, daemon=True).start()

    def submit(self, payload: bytes, authorization: str | None, command: str = RECHECK) -> None:
        """Queue a command (called on paho's network thread: returns at once)."""
        self._queue.put((payload, authorization, command))

    def stop(self) -> None:
        """Take no more commands; those under way end with the process."""
        self._stopping.set()

    def _work(self) -> None:
        while not self._stopping.is_set():
            try:
                payload, authorization, command = self._queue.get(timeout=0.2)
            except queue.Empty:
                continue
            reply = answer(self.prefix, payload, authorization, command)
            if not self._stopping.is_set():
                self.send(reply)
