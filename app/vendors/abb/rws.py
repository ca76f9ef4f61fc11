"""ABB tool data (a PERS ``tooldata``) over Robot Web Services 1.0 and 2.0.

Followed: ABB *Application manual - Robot Web Services* (3HAC050973-001, the rwsApi pages
of developercenter.robotstudio.com), "Operations on RAPID symbol data": get symbol data,
"Update RAPID variable current value" (``action=set``, form field ``value``), the common
``json=1`` parameter, HTTP status codes and the error body (``_embedded.status`` {code,
msg} in 1.0, ``status`` at the top in 2.0, as captured RobotWare 7 replies show); checked
against the clients abb-robot-client (PyPI, RWS 1.0), Schindler-EPFL-Lab/rws2 and rwswrap
(PyPI) (RWS 2.0).

RWS 1.0 (RobotWare 6, ``abb_rws1``): HTTP, Digest authentication, a session cookie
(``-http-session-``, ``ABBCX``) kept for the session's requests;
``GET /rw/rapid/symbol/data/RAPID/{task}/{module}/{symbol}?json=1`` -> ``_embedded._state[0]
.value``; ``POST ...?action=set&json=1`` with ``value=<RAPID text>``.

RWS 2.0 (RobotWare 7 / OmniCore, ``abb_rws2``): HTTPS with the controller's certificate,
Basic authentication, media types carrying ``;v=2.0`` (``Accept:
application/hal+json;v=2.0``, ``Content-Type: application/x-www-form-urlencoded;v=2.0``);
``GET /rw/rapid/symbol/RAPID/{task}/{module}/{symbol}/data`` -> ``state[0].value``;
``POST`` the same path with ``value=...`` while holding edit mastership:
``POST /rw/mastership/edit/request`` before, ``POST /rw/mastership/edit/release`` after,
whatever the write's outcome.

Where the robot stands (issue 39, ``read_pose``): "Get Robtarget" (rwsApi
``ms_mechunit_robtarget_page``), ``GET /rw/motionsystem/mechunits/ROB_1/robtarget?tool=tool0
&wobj=wobj0&coordinate=Base``, is the TCP of tool0 (the flange) in the robot's base frame,
so the flange needs no composition; "Get Joint target" (``ms_mechunit_jointtarget_page``),
``.../jointtarget``, gives rax_1..rax_6 in degrees. Each answer's one state item
(``ms-robtargets``, ``ms-jointtarget``; RWS 1.0 ``_embedded._state``, 2.0 ``state``) holds
every value as a string, and those strings are the reading's ``readings``. RWS names no tool
a program moves by (a move instruction names its own tooldata), so the live tool is unknown.

One deadline covers the whole session (``timeout_s`` from `connect`: login, mastership,
every read and write). Whatever the session leaves is then given back within `CLEANUP_S`
more: edit mastership (requested, so perhaps granted even when the answer never came) is
released and the session logged out on every path. RobotWare keeps mastership with the
session that took it until that session releases it or ends, so when the controller does not
answer even that, the session's cookies are kept (`_ORPHANS`, in this process) and the next
session with the same controller releases and logs it out before anything else; otherwise
the next write would meet "Mastership is held by another client" from tcpcal's own session.

Frames (contract v1.4 "Frames at the controller"): a base is a PERS ``wobjdata`` (RAPID
manual 3HAC050917-001, "wobjdata": ``[robhold, ufprog, ufmec, uframe, oframe]``), a fixed
tool a PERS ``tooldata`` with robhold FALSE (the same manual, "tooldata": a stationary tool,
tframe the TCP in the world frame), each by its symbol, read and set as a tool's tooldata is
(edit mastership around the set on RWS 2.0). A work object's frame is its uframe: the write
sets uframe and keeps robhold, ufprog, ufmec and the oframe as read; a fixed tool's write
sets tframe and keeps tload. Both are in the world frame, which tcpcal takes as the robot's
base frame (the base frame's default; RWS's ``.../baseframe`` is not read). The work object
the robot moves in: the mechanical unit's resource (``GET /rw/motionsystem/mechunits/ROB_1``,
its ``ms-mechunit`` item's ``wobj-name``, as ros-industrial/abb_librws
``RWSInterface::getMechanicalUnitDynamicInfo`` reads it beside ``tool-name``), a name only:
RWS gives neither its module nor its value there, so the live frame is that name.

A write keeps the controller's ``robhold`` and, when tcpcal has no load for the tool, its
whole ``tload``; with a load it writes mass and centre of gravity and keeps the axes of
moment and the inertia. Both sessions end with ``GET /logout`` (RobotWare keeps a small
number of sessions). The password goes only into the Authorization header, never into a
message.
"""

from __future__ import annotations

import contextlib
import math
import socket
import ssl
import threading
from dataclasses import replace

import httpx

from app.jsontypes import JsonObject
from app.kinematics.frames import flange_from_tcp
from app.vendors.abb import RWS1, RWS2
from app.vendors.abb.symbol import split_symbol
from app.vendors.abb.text import (
    RapidSyntaxError,
    RapidTool,
    RapidWobj,
    format_tooldata,
    format_wobjdata,
    parse_tooldata,
    parse_wobjdata,
)
from app.vendors.connector import (
    CLEANUP_S,
    ClosingSession,
    ControllerCredentialsRefused,
    ControllerProtocolError,
    ControllerRefused,
    ControllerSettings,
    ControllerSilent,
    ControllerUnreachable,
    Deadline,
    Frame,
    FrameTarget,
    LiveFrame,
    LiveTool,
    PoseReading,
    ToolTarget,
    finite_frame,
    write_sent,
)
from app.vendors.tool import ToolData, ToolLoad, finite_tool_data

#: ABB's factory user, used when the controller settings name none.
DEFAULT_USER = "Default User"
DEFAULT_PASSWORD = "robotics"
V2_JSON = "application/hal+json;v=2.0"
V2_FORM = "application/x-www-form-urlencoded;v=2.0"
_WORDS_LIMIT = 300
#: the mechanical unit of the motion task T_ROB1 (a single robot's controller)
MECHUNIT = "ROB_1"
#: tool0 in wobj0 in Base coordinates: the flange in the robot's base frame, whatever tool
#: and work object the robot moves by
ROBTARGET_QUERY = {"tool": "tool0", "wobj": "wobj0", "coordinate": "Base"}
_ROBTARGET = ("x", "y", "z", "q1", "q2", "q3", "q4")
_JOINTS = ("rax_1", "rax_2", "rax_3", "rax_4", "rax_5", "rax_6")
#: how far from 1 the norm of a printed quaternion may be (RobotWare prints 7 digits)
_UNIT_SLACK = 1e-3
_MASTERSHIP_REQUEST = "/rw/mastership/edit/request"
_MASTERSHIP_RELEASE = "/rw/mastership/edit/release"

#: Sessions a failure left on a controller that did not answer their release and logout:
#: base URL -> the cookies of each. The next session with that controller ends them first.
_ORPHANS: dict[str, list[dict[str, str]]] = {}
_ORPHANS_LOCK = threading.Lock()


class AbbRwsConnector(ClosingSession):
    """One RWS session with an ABB controller: read and write PERS tooldata symbols."""

    def __init__(self, settings: ControllerSettings) -> None:
        if settings.protocol not in ("abb_rws1", "abb_rws2"):
            raise ValueError(
                f"AbbRwsConnector speaks abb_rws1 and abb_rws2, not {settings.protocol}"
            )
        #: the whole session's time budget, from here: TLS set-up, login, mastership, reads,
        #: writes
        self._deadline = Deadline(settings.timeout_s)
        self.protocol: str = settings.protocol
        self._settings = settings
        self._v2 = settings.protocol == "abb_rws2"
        self._wire = RWS2 if self._v2 else RWS1
        host = f"[{settings.host}]" if ":" in settings.host else settings.host
        scheme = "https" if self._v2 else "http"
        self._peer = f"ABB RWS {'2.0' if self._v2 else '1.0'} at {settings.host}:{settings.port}"
        # ABB's factory user only when no user is named at all; a named user without a
        # password sends an empty one (and the controller says whether that will do).
        user = settings.username or DEFAULT_USER
        password = settings.password or (DEFAULT_PASSWORD if not settings.username else "")
        self._user = user
        auth: httpx.Auth = (
            httpx.BasicAuth(user, password) if self._v2 else httpx.DigestAuth(user, password)
        )
        self._client = httpx.Client(
            base_url=f"{scheme}://{host}:{settings.port}",
            auth=auth,
            # The system's trust store (and SSL_CERT_FILE / SSL_CERT_DIR), where a plant puts
            # its controllers' certificates; not a bundle of public CAs.
            # RWS 1.0 is plain HTTP: loading the trust store for it cost 0.08 s a session.
            verify=ssl.create_default_context() if self._v2 and settings.tls_verify else False,
            timeout=settings.timeout_s,
            headers={"Accept": V2_JSON} if self._v2 else {},
            follow_redirects=False,
            trust_env=False,
        )
        self._base_url = f"{scheme}://{host}:{settings.port}"
        self._logged_in = False
        #: edit mastership was asked for and not yet given back (it may have been granted
        #: even when the answer never came)
        self._mastership_asked = False
        self._orphans_ended = False

    # --- the Connector interface -----------------------------------------------------------

    def describe(self, target: ToolTarget) -> str:
        """``T_ROB1/user/tTorch``."""
        return self._wire.describe(target)

    def read_tool(self, target: ToolTarget) -> ToolData:
        """The tooldata the controller holds in the PERS symbol `target.symbol`."""
        self._wire.check(target)
        return _tool_data(self._read(target, self._deadline))

    def write_tool(self, target: ToolTarget, data: ToolData) -> None:
        """Write tframe (and the load when `data.load` is set), keeping robhold and the rest."""
        self._wire.check(target)
        finite_tool_data(data)
        deadline = self._deadline
        held = self._read(target, deadline)
        tool = replace(held, position_mm=data.position_mm, quaternion=data.quaternion)
        if data.load is not None:
            tool = replace(tool, mass_kg=data.load.mass_kg, cog_mm=data.load.cog_or_origin)
        assert target.symbol is not None  # checked above
        self._set(target.symbol, format_tooldata(tool), deadline)

    def _set(self, symbol: str, value: str, deadline: Deadline) -> None:
        """Set the PERS `symbol` to the RAPID text `value` (RWS 2.0: under edit mastership,
        released whatever the set's outcome)."""
        if not self._v2:
            # From the set's POST on the controller may hold the new value.
            with write_sent():
                self._send(
                    "POST",
                    self._data_path(symbol),
                    deadline,
                    params={"action": "set", "json": "1"},
                    data={"value": value},
                    what=f"set {symbol}",
                )
            return
        self._send(
            "POST",
            _MASTERSHIP_REQUEST,
            deadline,
            form=True,
            what="request edit mastership",
        )
        # From the set's POST on the controller may hold the new value, and the release
        # after it changes nothing of that.
        with write_sent():
            try:
                self._send(
                    "POST",
                    self._data_path(symbol),
                    deadline,
                    data={"value": value},
                    form=True,
                    what=f"set {symbol}",
                )
            finally:
                self._release_mastership(deadline)

    def describe_frame(self, target: FrameTarget) -> str:
        """``T_ROB1/user/wobjFixA``."""
        return self._wire.describe_frame(target)

    def read_frame(self, target: FrameTarget) -> Frame:
        """A base: the uframe of the wobjdata `target.symbol`; a fixed tool: the tframe of
        the stationary tooldata `target.symbol`."""
        symbol = self.describe_frame(target)
        if target.kind == "fixed_tool":
            tool = self._fixed_tool(symbol, self._deadline)
            return Frame(tool.position_mm, tool.quaternion)
        position, quaternion = self._wobj(symbol, self._deadline).uframe
        return Frame(position, quaternion)

    def write_frame(self, target: FrameTarget, frame: Frame) -> None:
        """Write the frame into the wobjdata's uframe (robhold, ufprog, ufmec and oframe as
        read) or the stationary tooldata's tframe (robhold FALSE and tload as read)."""
        symbol = self.describe_frame(target)
        finite_frame(frame)
        deadline = self._deadline
        if target.kind == "fixed_tool":
            tool = replace(
                self._fixed_tool(symbol, deadline),
                position_mm=frame.position_mm,
                quaternion=frame.quaternion,
            )
            value = format_tooldata(tool)
        else:
            wobj = replace(
                self._wobj(symbol, deadline), uframe=(frame.position_mm, frame.quaternion)
            )
            value = format_wobjdata(wobj)
        self._set(symbol, value, deadline)

    def _fixed_tool(self, symbol: str, deadline: Deadline) -> RapidTool:
        """The stationary tooldata `symbol`; ControllerRefused when the robot holds it."""
        tool = self._read(ToolTarget(symbol=symbol), deadline)
        if tool.robhold:
            raise ControllerRefused(
                f"{symbol} on the controller is a tooldata the robot holds (robhold TRUE), not "
                "a stationary tool: a fixed tool's tooldata has robhold FALSE (RAPID manual, "
                "tooldata); set the frame's controller_symbol to the stationary tooldata, or "
                "make this frame a base with its wobjdata",
                controller_message=f"{symbol}: robhold TRUE",
            )
        return tool

    def _wobj(self, symbol: str, deadline: Deadline) -> RapidWobj:
        value = self._read_value(symbol, deadline)
        try:
            return parse_wobjdata(value)
        except RapidSyntaxError as err:
            raise ControllerRefused(
                f"{symbol} on the controller is not a wobjdata: {err}; a base's "
                "controller_symbol names its work object (PERS wobjdata), a fixed tool's its "
                "stationary tooldata",
                controller_message=f"{symbol} = {value[:_WORDS_LIMIT]}",
            ) from err

    def read_pose(self) -> PoseReading:
        """The flange in the robot's base frame (the robtarget of tool0 in wobj0, Base
        coordinates), rax_1..rax_6 of the jointtarget, and every value both answers held, as
        printed; the work object the robot moves in by name (the mechunit's ``wobj-name``);
        the three reads within one deadline. The live tool is unknown (RWS does not say)."""
        deadline = self._deadline
        robtarget = self._motion_state("robtarget", "ms-robtargets", deadline)
        jointtarget = self._motion_state("jointtarget", "ms-jointtarget", deadline)
        mechunit = self._motion_state("", "ms-mechunit", deadline)
        x, y, z, q1, q2, q3, q4 = self._numbers(robtarget, _ROBTARGET, "robtarget")
        norm = math.sqrt(q1 * q1 + q2 * q2 + q3 * q3 + q4 * q4)
        if abs(norm - 1.0) > _UNIT_SLACK:
            raise ControllerProtocolError(
                f"{self._peer}: the robtarget's orientation q1..q4 = {q1}, {q2}, {q3}, {q4} is "
                f"not a unit quaternion (norm {norm:.6f})"
            )
        # tool0 in Base coordinates is the flange in the base frame: no tool, no base to
        # compose; flange_from_tcp only normalises the printed quaternion (scipy).
        position, quaternion = flange_from_tcp(((x, y, z), (q1, q2, q3, q4)))
        readings = {f"robtarget.{k}": v for k, v in robtarget.items()}
        readings |= {f"jointtarget.{k}": v for k, v in jointtarget.items()}
        wobj = mechunit.get("wobj-name")
        readings["mechunit.wobj-name"] = wobj or ""
        return PoseReading(
            flange=Frame(position, quaternion),
            joints_deg=self._numbers(jointtarget, _JOINTS, "jointtarget"),
            live_tool=LiveTool(None, None),
            readings=readings,
            live_frame=LiveFrame(number=None, name=wobj or None, frame=None),
        )

    def close(self) -> None:
        """Release edit mastership if it may be held, log out (ends the controller's
        session), close the connection; never raises. Within `CLEANUP_S` past the session's
        deadline; what the controller did not confirm is ended by the next session."""
        if self._mastership_asked:
            self._release_mastership(self._deadline)
        budget = self._deadline.extended(CLEANUP_S).left()
        if self._logged_in and budget > 0:
            with contextlib.suppress(httpx.HTTPError):
                self._client.get("/logout", timeout=budget)
                self._logged_in = False  # answered (a 401 too: the session is gone)
        if self._logged_in or self._mastership_asked:
            cookies = dict(self._client.cookies.items())
            if cookies:
                with _ORPHANS_LOCK:
                    _ORPHANS.setdefault(self._base_url, []).append(cookies)
        self._logged_in = self._mastership_asked = False
        self._client.close()

    # --- requests --------------------------------------------------------------------------

    def _data_path(self, symbol: str) -> str:
        task, module, name = split_symbol(symbol)
        if self._v2:
            return f"/rw/rapid/symbol/RAPID/{task}/{module}/{name}/data"
        return f"/rw/rapid/symbol/data/RAPID/{task}/{module}/{name}"

    def _read_value(self, symbol: str, deadline: Deadline) -> str:
        """The RAPID text the controller holds in the PERS `symbol`."""
        response = self._send(
            "GET",
            self._data_path(symbol),
            deadline,
            params=None if self._v2 else {"json": "1"},
            what=f"read {symbol}",
        )
        value = _state_value(_json(response, self._peer))
        if value is None:
            raise ControllerProtocolError(f"{self._peer}: no value in the answer for {symbol}")
        return value

    def _read(self, target: ToolTarget, deadline: Deadline) -> RapidTool:
        assert target.symbol is not None
        value = self._read_value(target.symbol, deadline)
        try:
            return parse_tooldata(value)
        except RapidSyntaxError as err:
            raise ControllerRefused(
                f"{target.symbol} on the controller is not a tooldata: {err}",
                controller_message=f"{target.symbol} = {value[:_WORDS_LIMIT]}",
            ) from err

    def _motion_state(self, resource: str, kind: str, deadline: Deadline) -> dict[str, str]:
        """The string values of the `kind` state item of mechunit ROB_1's `resource` (""
        for the mechanical unit itself)."""
        params = dict(ROBTARGET_QUERY) if resource == "robtarget" else {}
        if not self._v2:
            params["json"] = "1"
        path = f"/rw/motionsystem/mechunits/{MECHUNIT}"
        response = self._send(
            "GET",
            f"{path}/{resource}" if resource else path,
            deadline,
            params=params,
            what=f"read the {resource or 'state'} of {MECHUNIT}",
        )
        item = _state_item(_json(response, self._peer), kind)
        if item is None:
            raise ControllerProtocolError(f"{self._peer}: no {kind} item in the {resource} answer")
        return {
            key: value
            for key, value in item.items()
            if isinstance(value, str) and key not in ("_type", "_title")
        }

    def _numbers(
        self, values: dict[str, str], names: tuple[str, ...], resource: str
    ) -> tuple[float, ...]:
        """The values `names` as finite numbers; ControllerProtocolError quoting the text."""
        numbers: list[float] = []
        for name in names:
            text = values.get(name)
            try:
                number = float(text) if text is not None else math.nan
            except ValueError:
                number = math.nan
            if not math.isfinite(number):
                raise ControllerProtocolError(
                    f"{self._peer}: the {resource}'s {name} is {text!r}, not a number"
                )
            numbers.append(number)
        return tuple(numbers)

    def _release_mastership(self, deadline: Deadline) -> None:
        # Released even when the write failed, timed out or `deadline` is spent (then within
        # CLEANUP_S more): a held mastership locks the pendant and every other client out,
        # tcpcal's next session included, until the session holding it ends.
        budget = deadline.extended(CLEANUP_S).left()
        if budget <= 0:
            return
        with contextlib.suppress(httpx.HTTPError):
            response = self._client.post(
                _MASTERSHIP_RELEASE, headers={"Content-Type": V2_FORM}, timeout=budget
            )
            if response.status_code < 500:
                self._mastership_asked = False

    def _end_orphans(self) -> None:
        """Release and log out the sessions an earlier failure left on this controller,
        before this session needs the mastership they may hold (within this session's
        deadline; those the controller still does not answer are kept for the next one)."""
        self._orphans_ended = True
        with _ORPHANS_LOCK:
            orphans = _ORPHANS.pop(self._base_url, [])
        for index, cookies in enumerate(orphans):
            # Their own cookies and no credentials: a 401 says that session has ended.
            headers = {
                "Cookie": "; ".join(f"{k}={v}" for k, v in cookies.items()),
                "Content-Type": V2_FORM,
            }
            try:
                if self._v2:
                    self._client.request(
                        "POST",
                        _MASTERSHIP_RELEASE,
                        headers=headers,
                        auth=None,
                        timeout=self._deadline.remaining(),
                    )
                self._client.get(
                    "/logout", headers=headers, auth=None, timeout=self._deadline.remaining()
                )
            except (httpx.HTTPError, ControllerUnreachable):
                with _ORPHANS_LOCK:
                    _ORPHANS.setdefault(self._base_url, []).extend(orphans[index:])
                break
        self._client.cookies.clear()  # their answers set their cookies; this session has its own

    def _send(
        self,
        method: str,
        path: str,
        deadline: Deadline,
        *,
        what: str,
        params: dict[str, str] | None = None,
        data: dict[str, str] | None = None,
        form: bool = False,
    ) -> httpx.Response:
        headers = {"Content-Type": V2_FORM} if form else None
        if not self._orphans_ended:
            self._end_orphans()
        if path == _MASTERSHIP_REQUEST:
            self._mastership_asked = True  # granted perhaps, even if no answer comes
        try:
            response = self._client.request(
                method,
                path,
                params=params,
                data=data,
                headers=headers,
                timeout=httpx.Timeout(deadline.remaining()),
            )
        except (httpx.ReadTimeout, httpx.WriteTimeout) as err:
            if self._logged_in or deadline.answered:  # it answered: it stopped answering
                raise ControllerUnreachable(
                    f"{self._peer} did not answer within {deadline.timeout_s:g} s ({what})"
                ) from err
            raise ControllerSilent(
                f"{self._peer} accepted the TCP connection and sent nothing within "
                f"{deadline.timeout_s:g} s ({what})"
            ) from err
        except httpx.TimeoutException as err:
            raise ControllerUnreachable(
                f"{self._peer} did not answer within {deadline.timeout_s:g} s ({what})"
            ) from err
        except httpx.ConnectError as err:
            raise ControllerUnreachable(self._connect_failure(err)) from err
        except httpx.TransportError as err:
            raise ControllerUnreachable(
                f"{self._peer}: the connection failed ({what}): {err}"
            ) from err
        self._logged_in = deadline.answered = True
        if response.status_code >= 400:
            raise self._refusal(response, what)
        return response

    def _refusal(self, response: httpx.Response, what: str) -> ControllerRefused:
        words = _controller_words(response)
        if response.status_code == 401:
            return ControllerCredentialsRefused(
                f"the controller refused the credentials of user {self._user!r} "
                f"(check the RWS user name and password): {words}",
                controller_message=words,
                user=self._user,
            )
        return ControllerRefused(
            f"the controller refused to {what}: {words}", controller_message=words
        )

    def _connect_failure(self, err: httpx.ConnectError) -> str:
        peer = self._peer
        reason = str(err) or type(err).__name__
        if "CERTIFICATE" in reason.upper():
            return (
                f"{peer}: the TLS handshake failed ({reason}); the controller's certificate is "
                "not trusted here: install it in the system's trust store (or point "
                "SSL_CERT_FILE at it; its name must match the host), or set tls_verify false"
            )
        if "SSL" in reason.upper() or "TLS" in reason.upper():
            settings = self._settings
            if self._v2 and _speaks_plain_http(settings.host, settings.port, self._deadline):
                return (
                    f"{peer}: the port answers plain HTTP, not TLS ({reason}): RWS 2.0 "
                    "(RobotWare 7) is served over HTTPS; a controller answering plain HTTP is "
                    "RobotWare 6: set the controller's protocol to abb_rws1 (port 80)"
                )
            return f"{peer}: the TLS handshake failed ({reason})"
        return f"cannot connect to {peer}: {reason}"


def _tool_data(tool: RapidTool) -> ToolData:
    # RAPID's loaddata has no "no load": a mass of 0 (or -1, "not set") is none to show.
    load = ToolLoad(mass_kg=tool.mass_kg, cog_mm=tool.cog_mm) if tool.mass_kg > 0 else None
    return ToolData(position_mm=tool.position_mm, quaternion=tool.quaternion, load=load)


def _json(response: httpx.Response, peer: str) -> JsonObject:
    try:
        body = response.json()
    except ValueError as err:
        raise ControllerProtocolError(
            f"{peer} answered {response.headers.get('content-type')!r}, not JSON"
        ) from err
    if not isinstance(body, dict):
        raise ControllerProtocolError(f"{peer} answered a JSON {type(body).__name__}")
    return body


def _state_lists(body: JsonObject) -> list[object]:
    """Where an answer's state resources are: RWS 1.0 ``_embedded._state``, RWS 2.0
    ``state`` (or ``_embedded.resources``)."""
    embedded = body.get("_embedded")
    candidates = [body.get("state")]
    if isinstance(embedded, dict):
        candidates += [embedded.get("_state"), embedded.get("resources")]
    return candidates


def _state_value(body: JsonObject) -> str | None:
    """The ``value`` of the first state resource."""
    for states in _state_lists(body):
        if isinstance(states, list) and states and isinstance(states[0], dict):
            value = states[0].get("value")
            if isinstance(value, str):
                return value
    return None


def _state_item(body: JsonObject, kind: str) -> JsonObject | None:
    """The first state resource whose ``_type`` is `kind`."""
    for states in _state_lists(body):
        if isinstance(states, list):
            for item in states:
                if isinstance(item, dict) and item.get("_type") == kind:
                    return item
    return None


def _controller_words(response: httpx.Response) -> str:
    """What the controller said: its status msg and code when it sent them, else the HTTP
    status line and the start of its text."""
    status_line = f"HTTP {response.status_code} {response.reason_phrase}".strip()
    try:
        body = response.json()
    except ValueError:
        body = None
    if isinstance(body, dict):
        embedded = body.get("_embedded")
        status = body.get("status")
        if isinstance(embedded, dict) and isinstance(embedded.get("status"), dict):
            status = embedded["status"]
        if isinstance(status, dict) and status.get("msg"):
            code = status.get("code")
            suffix = f" (code {code})" if code is not None else ""
            return f"{status['msg']}{suffix}; {status_line}"[:_WORDS_LIMIT]
    text = response.text.strip()
    if text and not text.lstrip().startswith("<"):
        return f"{status_line}: {text}"[:_WORDS_LIMIT]
    return status_line


def _speaks_plain_http(host: str, port: int, deadline: Deadline) -> bool:
    """Whether host:port answers a plain HTTP request with an HTTP status line: what makes
    a TLS handshake fail with "wrong version number" (the server answered in clear)."""
    budget = min(deadline.left(), CLEANUP_S)
    if budget <= 0:
        return False
    try:
        with socket.create_connection((host, port), timeout=budget) as sock:
            sock.sendall(b"HEAD / HTTP/1.0\r\n\r\n")
            return sock.recv(5) == b"HTTP/"
    except OSError:
        return False
