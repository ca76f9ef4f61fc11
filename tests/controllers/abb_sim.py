"""An ABB controller's Robot Web Services, in memory: PERS tooldata and wobjdata symbols in
RAPID tasks.

Follows ABB *Application manual - Robot Web Services* (3HAC050973-001, the rwsApi pages):
"Operations on RAPID symbol data" (get, and ``action=set`` with form field ``value``),
``json=1``, the HTTP status codes, the error body (RWS 1.0 ``_embedded.status`` {code, msg}, RWS 2.0
``status`` {code, msg} at the top), and
``/logout``. Version 1 is RWS 1.0 as RobotWare 6 serves it (HTTP, Digest authentication,
RFC 7616 MD5 with qop=auth, realm ``validusers@robapi.abb``, then the session cookies
``-http-session-`` and ``ABBCX``; the shape abb-robot-client reads). Version 2 is RWS 2.0
as RobotWare 7 serves it (HTTPS with a self-signed certificate made at start, Basic
authentication, media types that must carry ``;v=2.0`` (406 for an Accept naming another
type, 415 for a POST body without it), the path
``/rw/rapid/symbol/RAPID/{task}/{module}/{symbol}/data``, the answer's ``state`` list, and
edit mastership: ``POST /rw/mastership/edit/request`` / ``release``, or every domain's with
``/rw/mastership/request`` / ``release``; a write without it is refused with 403). Answers
are JSON only (hal+json), not the xhtml+xml RWS also serves. The error codes are this
simulator's own; the messages say what failed.

A written value is read here, not with the connector's parser (this module imports nothing
from app/): RAPID text as ABB *Technical reference manual - RAPID Instructions, Functions and
Data types* (3HAC050917-001) gives it. ``tooldata`` is ``[robhold, tframe, tload]``: robhold
a ``bool`` (TRUE/FALSE), tframe a ``pose`` ``[trans, rot]`` (``pos`` [x, y, z] mm, ``orient``
[q1, q2, q3, q4], q1 the scalar part, normalized), tload a ``loaddata`` ``[mass, cog, aom,
ix, iy, iz]`` (kg, ``pos`` mm, ``orient``, kg m2); the manual's own example is
``[TRUE, [[97.4, 0, 223.1], [0.924, 0, 0.383, 0]], [5, [23, 0, 75], [1, 0, 0, 0], 0, 0,
0]]``. Aggregates are bracketed and comma separated, spaces anywhere between tokens; a num
literal (*Technical reference manual - RAPID kernel*, "Numeric literals") is digits with an
optional decimal point and exponent (``7990``, ``23.67``, ``2E6``, ``2.5E-3``), a unary
minus allowed: nothing Python's ``float`` takes beyond that (``nan``, ``inf``, ``1_000``).
The answer to a read (``rap-data`` with its ``value``) is the RWS manual's "Get symbol
data" (rwsApi ``rapid_symbol_data_page``).

Work objects (the same RAPID manual, "wobjdata"): ``[robhold, ufprog, ufmec, uframe,
oframe]``, robhold a bool (TRUE: the robot holds the work object), ufprog a bool (TRUE: a
fixed user frame), ufmec a string (the mechanical unit moving the user frame, ``""`` when
fixed), uframe and oframe poses (the user frame, and the object frame in it); the manual's
example ``[FALSE, TRUE, "", [[300, 600, 200], [1, 0, 0, 0]], [[0, 200, 30], [1, 0, 0, 0]]]``.
A string literal is ``"..."`` (RAPID kernel, "String literals"; no quote inside here).
`wobjdata` (symbol -> `WobjSymbol`) is the frame table, apart from the tool table
(`symbols`): a write of a wobjdata symbol sets that symbol, every member as written (a client
that means to change the uframe alone writes the oframe and robhold it read), and nothing
else; a tooldata written to a wobjdata symbol, or a wobjdata to a tooldata symbol, is a type
mismatch (400), as is a non-normalized quaternion. A write needs edit mastership on RWS 2.0,
as for tools. A stationary tool is a tooldata with robhold FALSE (the manual's tooldata:
tframe is then the TCP in the world frame), held and written as any tooldata.

Where the robot stands (issue 39): "Get Robtarget" (rwsApi ``ms_mechunit_robtarget_page``),
``GET /rw/motionsystem/mechunits/{mechunit}/robtarget`` with ``tool``, ``wobj`` (each the
mechunit's active one when left out) and ``coordinate`` (``Base | World | Tool | Wobj``,
required), answering one ``ms-robtargets`` item titled by the mechunit with x, y, z (mm),
q1..q4 (q1 the scalar part), cf1, cf4, cf6, cfx and eax_a..eax_f (unused: 8.999999e+009);
The mechanical unit itself (``GET /rw/motionsystem/mechunits/{mechunit}``) answers one
``ms-mechunit`` item naming the tool and work object it moves by (``tool-name``,
``wobj-name``: `active_tool`, `active_wobj`), as ros-industrial/abb_librws reads it.
"Get Joint target" (``ms_mechunit_jointtarget_page``), ``.../jointtarget``, one
``ms-jointtarget`` item with rax_1..rax_6 (degrees) and eax_a..eax_f. The manual's examples
are the XHTML form; JSON carries the same names and every value as a string: RWS 1.0
(``json=1``) the item in ``_embedded._state`` (where abb-robot-client reads it), RWS 2.0
(hal+json;v=2.0) in ``state``, as replies captured from a RobotWare 7.21 virtual controller
in public RWS 2.0 clients' tests show. The simulator holds the flange (tool0) in the robot's
base frame and the six joint angles, which a test sets (`set_pose`); it computes no
kinematics: a robtarget of another tool is the flange composed with that tool's tframe, of
coordinate Wobj the same seen from the work object's frame (``wobjs``, wobj0 the base; a
wobjdata symbol of the task with robhold FALSE and a fixed uframe (ufprog TRUE) is
uframe * oframe in the world, seen from the base through ``base_frame``), of
World from ``base_frame`` (the base in the world; the identity by default); Tool is refused
(400) as nothing here needs it.

Tool data, the pose and the joints are held as RobotWare holds ``num`` (32-bit float) unless
`single_precision` is False. `set_tool` / `tool` are the operator at the FlexPendant (Jogging
> Tool, or the Program Data window); `mastership_holder` set to "FlexPendant" is an operator
holding write access there.

Edit mastership belongs to the session that requested it (its cookie) until that session
releases it or logs out; another session's request is refused with "Mastership is held by
another client". A session that stops talking keeps it: that is why a client must release it
and log out whatever failed.

`stalled` makes the controller accept requests and answer none (until it is cleared or the
simulator stops; the requests it did not answer are dropped). The fault hook (`Faults`) names
a request "login" while it has no live session cookie (the Digest challenge and answer, or
Basic credentials), else "METHOD /path"; `reply_delay_s` delays every answer.
"""

from __future__ import annotations

import base64
import datetime
import hashlib
import ipaddress
import json
import re
import secrets
import ssl
import tempfile
import threading
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Self
from urllib.parse import parse_qs, urlsplit

import numpy as np
from scipy.spatial.transform import Rotation

from tests.controllers.simbase import Faults

REALM = "validusers@robapi.abb"
V2 = ";v=2.0"
_V1_PATH = re.compile(r"^/rw/rapid/symbol/data/RAPID/([^/]+)/([^/]+)/([^/?]+)$")
_V2_PATH = re.compile(r"^/rw/rapid/symbol/RAPID/([^/]+)/([^/]+)/([^/]+)/data$")
_MOTION_PATH = re.compile(r"^/rw/motionsystem/mechunits/([^/]+)/(robtarget|jointtarget)/?$")
_MECHUNIT_PATH = re.compile(r"^/rw/motionsystem/mechunits/([^/]+)/?$")
#: what RobotWare prints for an external axis that is not there (the manual's example)
NO_AXIS = "8.999999e+009"
#: a frame: position mm, quaternion q1..q4 (w, x, y, z)
SimFrame = tuple[tuple[float, float, float], tuple[float, float, float, float]]
IDENTITY: SimFrame = ((0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0))
NOT_FOUND_CODE = -1073442816
#: codes RobotWare 7 sends (captured replies in public RWS 2.0 clients' tests)
RESOURCE_NOT_FOUND_CODE = -1073445859
PARAMETER_CODE = -1073445879
TYPE_CODE = -1073442815
MASTERSHIP_CODE = -1073445865


@dataclass
class Symbol:
    """One PERS tooldata as the controller holds it."""

    robhold: bool = True
    trans: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rot: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    mass: float = 1.0
    cog: tuple[float, float, float] = (0.0, 0.0, 1.0)
    aom: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    inertia: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def text(self) -> str:
        num = num_text

        def group(vs: tuple[float, ...]) -> str:
            return "[" + ",".join(num(v) for v in vs) + "]"

        return (
            f"[{'TRUE' if self.robhold else 'FALSE'},[{group(self.trans)},{group(self.rot)}],"
            f"[{num(self.mass)},{group(self.cog)},{group(self.aom)},"
            f"{','.join(num(v) for v in self.inertia)}]]"
        )


def num_text(v: float) -> str:
    """A num as RobotWare prints it: a 32-bit float in its shortest form (a value held in
    double precision, `single_precision` False, in full)."""
    if float(np.float32(v)) == v:
        return np.format_float_positional(np.float32(v), trim="-")
    return np.format_float_positional(v, trim="-")


def _rotation(q: tuple[float, ...]) -> Rotation:
    return Rotation.from_quat([q[1], q[2], q[3], q[0]])


def _compose(a: SimFrame, b: SimFrame) -> SimFrame:
    """a @ b (this simulator's own, with scipy: it imports nothing from app/)."""
    ra, rb = _rotation(a[1]), _rotation(b[1])
    x, y, z = (float(v) for v in ra.apply(b[0]) + np.asarray(a[0]))
    qx, qy, qz, qw = (float(v) for v in (ra * rb).as_quat())
    return (x, y, z), (qw, qx, qy, qz)


def _inverse(a: SimFrame) -> SimFrame:
    r = _rotation(a[1]).inv()
    x, y, z = (float(v) for v in -r.apply(a[0]))
    qx, qy, qz, qw = (float(v) for v in r.as_quat())
    return (x, y, z), (qw, qx, qy, qz)


@dataclass
class WobjSymbol:
    """One PERS wobjdata as the controller holds it."""

    robhold: bool = False
    ufprog: bool = True
    ufmec: str = ""
    uframe: SimFrame = IDENTITY
    oframe: SimFrame = IDENTITY

    def text(self) -> str:
        def pose(frame: SimFrame) -> str:
            trans, rot = frame
            return (
                f"[[{','.join(num_text(v) for v in trans)}],[{','.join(num_text(v) for v in rot)}]]"
            )

        return (
            f"[{'TRUE' if self.robhold else 'FALSE'},{'TRUE' if self.ufprog else 'FALSE'},"
            f'"{self.ufmec}",{pose(self.uframe)},{pose(self.oframe)}]'
        )


@dataclass
class _Session:
    user: str
    cookie: str
    abbcx: str = field(default_factory=lambda: secrets.token_hex(4))


class AbbRwsSimulator(Faults):
    """RWS 1.0 (version=1) or 2.0 (version=2) on 127.0.0.1, a free port."""

    def __init__(
        self,
        version: int = 1,
        *,
        username: str = "Default User",
        password: str = "robotics",
        single_precision: bool = True,
    ) -> None:
        if version not in (1, 2):
            raise ValueError("RWS version 1 or 2")
        self.version = version
        self.users = {username: password}
        self.single_precision = single_precision
        self.host = "127.0.0.1"
        self.port = 0
        self.stalled = False
        #: who holds edit mastership: None, a session cookie, or "FlexPendant"
        self.mastership_holder: str | None = None
        self.symbols: dict[str, Symbol] = {
            "T_ROB1/user/tTorch": Symbol(),
            "T_ROB1/user/tGripper": Symbol(robhold=False, mass=2.0, cog=(0.0, 0.0, 50.0)),
            "T_ROB2/user/tTorch": Symbol(),
        }
        #: PERS wobjdata symbols (the frame table)
        self.wobjdata: dict[str, WobjSymbol] = {
            "T_ROB1/user/wobjTable": WobjSymbol(),
            "T_ROB1/user/wobjFixture": WobjSymbol(
                uframe=((800.0, -200.0, 350.0), (1.0, 0.0, 0.0, 0.0)),
                oframe=((10.0, 20.0, 0.0), (0.7071068, 0.0, 0.0, 0.7071068)),
            ),
            "T_ROB2/user/wobjTable": WobjSymbol(),
        }
        for held in self.wobjdata.values():  # held as RobotWare holds num
            held.uframe, held.oframe = self._frame(held.uframe), self._frame(held.oframe)
        #: non-tooldata symbols a client may name by mistake: symbol -> RAPID text
        self.other_symbols = {"T_ROB1/user/reg1": "0"}
        #: the motion task's mechanical unit (T_ROB1 moves ROB_1)
        self.mechunit = "ROB_1"
        #: the flange (tool0) in the robot's base frame, and joints rax_1..rax_6 in degrees
        self.flange: SimFrame = ((515.0, 0.0, 712.0), (0.7071068, 0.0, 0.7071068, 0.0))
        self.joints: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 30.0, 0.0)
        self.robconf: tuple[int, int, int, int] = (0, 0, 0, 0)
        #: the tool and work object active for the mechunit (jogging / the program's last move)
        self.active_tool = "tool0"
        self.active_wobj = "wobj0"
        #: work objects' frames in the robot's base frame (uframe * oframe)
        self.wobjs: dict[str, SimFrame] = {"wobj0": IDENTITY}
        #: the robot's base frame in the world
        self.base_frame: SimFrame = IDENTITY
        #: a moving robot: each robtarget or jointtarget read finds the flange this many mm
        #: further along the base's x axis and rax_1 this many degrees further
        self.moving_per_read = 0.0
        self.requests: list[tuple[str, str, str]] = []  # method, path, authorization scheme
        #: the query of each request, in order (what the client asked for)
        self.queries: list[dict[str, str]] = []
        self.sessions: dict[str, _Session] = {}
        self._nonces: set[str] = set()
        self._lock = threading.Lock()
        self._release = threading.Event()
        self._server: ThreadingHTTPServer | None = None
        self._thread: threading.Thread | None = None
        self._tmp: tempfile.TemporaryDirectory[str] | None = None
        self.certificate_pem: bytes = b""
        #: the PEM file of the certificate (RWS 2.0), for a client that should trust it
        self.certificate_path: Path | None = None

    # --- lifecycle ----------------------------------------------------------------------

    def start(self) -> Self:
        """Serve on a free loopback port (the same one again after a `stop`)."""
        self._release.clear()
        server = ThreadingHTTPServer((self.host, self.port), _handler_for(self))
        server.daemon_threads = True
        if self.version == 2:
            server.socket = self._tls_context().wrap_socket(server.socket, server_side=True)
        self.port = server.server_address[1]
        self._server = server
        self._thread = threading.Thread(
            target=server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True
        )
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop serving and close the port (the controller switched off)."""
        self._release.set()
        server, self._server = self._server, None
        if server is not None:
            server.shutdown()
            server.server_close()
        if self._thread is not None:
            self._thread.join(timeout=2)
        self.sessions.clear()

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None

    @property
    def base_url(self) -> str:
        return f"{'https' if self.version == 2 else 'http'}://{self.host}:{self.port}"

    # --- the pendant --------------------------------------------------------------------

    def set_tool(
        self,
        symbol: str,
        position_mm: tuple[float, float, float],
        quaternion: tuple[float, float, float, float],
        *,
        mass: float | None = None,
        cog: tuple[float, float, float] | None = None,
    ) -> None:
        """What an operator enters for a tooldata's tframe (and tload) on the FlexPendant."""
        with self._lock:
            held = self.symbols.setdefault(symbol, Symbol())
            held.trans = self._reals(position_mm)  # type: ignore[assignment]
            held.rot = self._reals(quaternion)  # type: ignore[assignment]
            if mass is not None:
                held.mass = self._reals((mass,))[0]
            if cog is not None:
                held.cog = self._reals(cog)  # type: ignore[assignment]

    def set_wobj(self, symbol: str, uframe: SimFrame, oframe: SimFrame = IDENTITY) -> None:
        """What an operator enters for a wobjdata's uframe and oframe on the FlexPendant."""
        with self._lock:
            held = self.wobjdata.setdefault(symbol, WobjSymbol())
            held.uframe = self._frame(uframe)
            held.oframe = self._frame(oframe)

    def wobj(self, symbol: str) -> WobjSymbol:
        """A copy of the wobjdata the controller holds in `symbol`."""
        with self._lock:
            return WobjSymbol(**self.wobjdata[symbol].__dict__)

    def _frame(self, frame: SimFrame) -> SimFrame:
        return self._reals(frame[0]), self._reals(frame[1])  # type: ignore[return-value]

    def tool(self, symbol: str) -> Symbol:
        """A copy of the tooldata the controller holds in `symbol`."""
        with self._lock:
            held = self.symbols[symbol]
            return Symbol(**held.__dict__)

    def set_pose(
        self,
        position_mm: tuple[float, float, float],
        quaternion: tuple[float, float, float, float],
        joints_deg: tuple[float, ...] | None = None,
    ) -> None:
        """Where the robot stands: its flange in the base frame (and its joint angles)."""
        with self._lock:
            self.flange = (self._reals(position_mm), self._reals(quaternion))  # type: ignore[assignment]
            if joints_deg is not None:
                self.joints = self._reals(joints_deg)

    def _move(self) -> None:
        # under self._lock
        if self.moving_per_read:
            (x, y, z), rot = self.flange
            self.flange = ((x + self.moving_per_read, y, z), rot)
            self.joints = (self.joints[0] + self.moving_per_read, *self.joints[1:])

    def _reals(self, values: tuple[float, ...]) -> tuple[float, ...]:
        if self.single_precision:
            return tuple(float(np.float32(v)) for v in values)
        return tuple(float(v) for v in values)

    # --- what the controller does -------------------------------------------------------

    def hang(self) -> None:
        """Answer nothing until `stalled` is cleared or the simulator stops."""
        while self.stalled and not self._release.wait(0.02):
            pass

    def _cookie_session(self, headers: dict[str, str]) -> _Session | None:
        cookies = dict(
            part.strip().split("=", 1)
            for part in headers.get("cookie", "").split(";")
            if "=" in part
        )
        with self._lock:
            return self.sessions.get(cookies.get("-http-session-", ""))

    def authenticate(self, method: str, headers: dict[str, str]) -> _Session | None:
        """The session of a valid cookie or Authorization header; None: challenge."""
        session = self._cookie_session(headers)
        if session is not None:
            return session
        authorization = headers.get("authorization", "")
        user = (
            self._check_basic(authorization)
            if self.version == 2
            else self._check_digest(method, authorization)
        )
        if user is None:
            return None
        session = _Session(user=user, cookie=secrets.token_hex(16))
        with self._lock:
            self.sessions[session.cookie] = session
        return session

    def challenge(self) -> str:
        if self.version == 2:
            return f'Basic realm="{REALM}"'
        nonce = secrets.token_hex(16)
        with self._lock:
            self._nonces.add(nonce)
        opaque = secrets.token_hex(8)
        return (
            f'Digest realm="{REALM}", qop="auth", nonce="{nonce}", opaque="{opaque}", algorithm=MD5'
        )

    def _check_basic(self, authorization: str) -> str | None:
        if not authorization.startswith("Basic "):
            return None
        try:
            user, _, password = base64.b64decode(authorization[6:]).decode().partition(":")
        except ValueError:
            return None
        return user if self.users.get(user) == password else None

    def _check_digest(self, method: str, authorization: str) -> str | None:
        if not authorization.startswith("Digest "):
            return None
        fields = {
            k: v.strip('"') for k, v in re.findall(r'(\w+)=("[^"]*"|[^,\s]+)', authorization[7:])
        }
        user = fields.get("username", "")
        password = self.users.get(user)
        with self._lock:
            known_nonce = fields.get("nonce") in self._nonces
        if password is None or not known_nonce:
            return None

        def md5(text: str) -> str:
            return hashlib.md5(text.encode()).hexdigest()

        ha1 = md5(f"{user}:{REALM}:{password}")
        ha2 = md5(f"{method}:{fields.get('uri', '')}")
        expected = md5(
            f"{ha1}:{fields.get('nonce')}:{fields.get('nc')}:{fields.get('cnonce')}:{fields.get('qop')}:{ha2}"
        )
        return user if secrets.compare_digest(expected, fields.get("response", "")) else None

    def read_symbol(self, symbol: str) -> tuple[int, dict[str, object]]:
        with self._lock:
            held: Symbol | WobjSymbol | None = self.symbols.get(symbol) or self.wobjdata.get(symbol)
            text = held.text() if held is not None else self.other_symbols.get(symbol)
        if text is None:
            return 400, _error(NOT_FOUND_CODE, f"Symbol not found: RAPID/{symbol}")
        state = [{"_type": "rap-data", "_title": f"RAPID/{symbol}", "value": text}]
        if self.version == 2:
            return 200, {"_links": {"base": {"href": f"{self.base_url}/rw/rapid/"}}, "state": state}
        return 200, {
            "_links": {"base": {"href": f"{self.base_url}/rw/rapid/"}},
            "_embedded": {"_state": state},
        }

    def _state_body(self, path: str, item: dict[str, str]) -> dict[str, object]:
        links = {"base": {"href": f"{self.base_url}{path}/"}, "self": {"href": ""}}
        if self.version == 2:
            return {"_links": links, "state": [item]}
        return {"_links": links, "_embedded": {"_state": [item]}}

    def _tool_frame(self, name: str) -> SimFrame | None:
        if name == "tool0":
            return IDENTITY
        task = "T_ROB" + self.mechunit.rsplit("_", 1)[-1]
        for symbol, held in self.symbols.items():
            if symbol.startswith(f"{task}/") and symbol.rsplit("/", 1)[1] == name:
                return held.trans, held.rot
        return None

    def _wobj_frame(self, name: str) -> SimFrame | None:
        """A work object's frame in the robot's base frame: a wobjdata symbol of the task
        (robhold FALSE, fixed uframe: uframe * oframe in the world), else `wobjs`."""
        task = "T_ROB" + self.mechunit.rsplit("_", 1)[-1]
        held = self.wobjdata.get(f"{task}/user/{name}")
        if held is None:
            return self.wobjs.get(name)
        if held.robhold or not held.ufprog:
            return None  # a work object the robot holds or a unit moves: not played
        return _compose(_inverse(self.base_frame), _compose(held.uframe, held.oframe))

    def robtarget(self, mechunit: str, query: dict[str, str]) -> tuple[int, dict[str, object]]:
        """Get Robtarget: the TCP of `tool` in `coordinate` (the flange for tool0 in Base)."""
        if mechunit != self.mechunit:
            return 400, _error(NOT_FOUND_CODE, f"Mechanical unit not found: {mechunit}")
        coordinate = query.get("coordinate")
        if coordinate not in ("Base", "World", "Wobj"):
            return 400, _error(PARAMETER_CODE, f"Invalid coordinate: {coordinate}")
        with self._lock:
            tool = self._tool_frame(query.get("tool") or self.active_tool)
            wobj = self._wobj_frame(query.get("wobj") or self.active_wobj)
            if tool is None or wobj is None:
                return 400, _error(NOT_FOUND_CODE, "Tool or work object not found")
            self._move()
            # tool0 is the flange itself, printed as held
            tcp = self.flange if tool == IDENTITY else _compose(self.flange, tool)
            if coordinate == "Wobj":
                tcp = _compose(_inverse(wobj), tcp)
            elif coordinate == "World":
                tcp = _compose(self.base_frame, tcp)
            robconf = self.robconf
        # printed as the controller holds a num (32-bit unless single_precision is False)
        x, y, z = self._reals(tcp[0])
        q1, q2, q3, q4 = self._reals(tcp[1])
        item = {"_type": "ms-robtargets", "_title": mechunit}
        item |= {k: num_text(v) for k, v in zip("xyz", (x, y, z), strict=True)}
        item |= {f"q{i}": num_text(v) for i, v in enumerate((q1, q2, q3, q4), 1)}
        item |= {k: str(v) for k, v in zip(("cf1", "cf4", "cf6", "cfx"), robconf, strict=True)}
        item |= {f"eax_{c}": NO_AXIS for c in "abcdef"}
        path = f"/rw/motionsystem/mechunits/{mechunit}/robtarget"
        return 200, self._state_body(path, item)

    def mechunit_state(self, mechunit: str) -> tuple[int, dict[str, object]]:
        """The mechanical unit's resource: one ``ms-mechunit`` item naming the tool and work
        object it moves by (``tool-name``, ``wobj-name``), its payloads, mode, status, jog
        mode and coordinate system, as ros-industrial/abb_librws
        (``RWSInterface::getMechanicalUnitDynamicInfo``) reads it."""
        if mechunit != self.mechunit:
            return 400, _error(NOT_FOUND_CODE, f"Mechanical unit not found: {mechunit}")
        with self._lock:
            item = {
                "_type": "ms-mechunit",
                "_title": mechunit,
                "type": "TCPRobot",
                "task-name": "T_ROB" + mechunit.rsplit("_", 1)[-1],
                "tool-name": self.active_tool,
                "wobj-name": self.active_wobj,
                "payload-name": "load0",
                "total-payload-name": "load0",
                "mode": "Activated",
                "status": "Stopped",
                "jog-mode": "Linear",
                "coord-system": "Base",
            }
        return 200, self._state_body(f"/rw/motionsystem/mechunits/{mechunit}", item)

    def jointtarget(self, mechunit: str) -> tuple[int, dict[str, object]]:
        """Get Joint target: rax_1..rax_6 in degrees."""
        if mechunit != self.mechunit:
            return 400, _error(NOT_FOUND_CODE, f"Mechanical unit not found: {mechunit}")
        with self._lock:
            self._move()
            joints = self.joints
        item = {"_type": "ms-jointtarget", "_title": mechunit}
        item |= {f"rax_{i}": num_text(v) for i, v in enumerate(joints, 1)}
        item |= {f"eax_{c}": "0" for c in "abcdef"}
        path = f"/rw/motionsystem/mechunits/{mechunit}/jointtarget"
        return 200, self._state_body(path, item)

    def write_symbol(
        self, symbol: str, value: str, session: _Session
    ) -> tuple[int, dict[str, object] | None]:
        if self.version == 2 and self.mastership_holder != session.cookie:
            holder = "the FlexPendant" if self.mastership_holder == "FlexPendant" else "nobody"
            return 403, _error(
                MASTERSHIP_CODE,
                f"Operation not allowed: edit mastership is required (held by {holder})",
            )
        with self._lock:
            is_wobj = symbol in self.wobjdata
            if symbol not in self.symbols and not is_wobj:
                if symbol in self.other_symbols:
                    return 400, _error(
                        TYPE_CODE, f"Type mismatch: RAPID/{symbol} is not a tooldata"
                    )
                return 400, _error(NOT_FOUND_CODE, f"Symbol not found: RAPID/{symbol}")
        if is_wobj:
            return self._write_wobj(symbol, value)
        try:
            tool = read_tooldata(value)
        except RapidValueError as err:
            return 400, _error(
                TYPE_CODE, f"Invalid value for tooldata RAPID/{symbol}: {err}: {value[:80]}"
            )
        norm = float(np.linalg.norm(tool.rot))
        if abs(norm - 1.0) > 1e-5:
            return 400, _error(
                TYPE_CODE, f"Not a normalized quaternion in RAPID/{symbol} (|q| = {norm:.6f})"
            )
        with self._lock:
            held = self.symbols[symbol]
            held.robhold = tool.robhold
            held.trans = self._reals(tool.trans)  # type: ignore[assignment]
            held.rot = self._reals(tool.rot)  # type: ignore[assignment]
            held.mass = self._reals((tool.mass,))[0]
            held.cog = self._reals(tool.cog)  # type: ignore[assignment]
            held.aom = self._reals(tool.aom)  # type: ignore[assignment]
            held.inertia = self._reals(tool.inertia)  # type: ignore[assignment]
        return 204, None

    def _write_wobj(self, symbol: str, value: str) -> tuple[int, dict[str, object] | None]:
        try:
            wobj = read_wobjdata(value)
        except RapidValueError as err:
            return 400, _error(
                TYPE_CODE, f"Invalid value for wobjdata RAPID/{symbol}: {err}: {value[:80]}"
            )
        for member, (_, rot) in (("uframe", wobj.uframe), ("oframe", wobj.oframe)):
            norm = float(np.linalg.norm(rot))
            if abs(norm - 1.0) > 1e-5:
                return 400, _error(
                    TYPE_CODE,
                    f"Not a normalized quaternion in RAPID/{symbol} {member} (|q| = {norm:.6f})",
                )
        with self._lock:
            wobj.uframe, wobj.oframe = self._frame(wobj.uframe), self._frame(wobj.oframe)
            self.wobjdata[symbol] = wobj
        return 204, None

    def mastership(self, action: str, session: _Session) -> tuple[int, dict[str, object] | None]:
        with self._lock:
            if action == "request":
                if self.mastership_holder not in (None, session.cookie):
                    return 403, _error(
                        MASTERSHIP_CODE,
                        "Mastership is held by another client (FlexPendant)"
                        if self.mastership_holder == "FlexPendant"
                        else "Mastership is held by another client",
                    )
                self.mastership_holder = session.cookie
                return 204, None
            if self.mastership_holder == session.cookie:
                self.mastership_holder = None
            return 204, None

    def _tls_context(self) -> ssl.SSLContext:
        from cryptography import x509
        from cryptography.hazmat.primitives import hashes, serialization
        from cryptography.hazmat.primitives.asymmetric import ec
        from cryptography.x509.oid import NameOID

        key = ec.generate_private_key(ec.SECP256R1())
        name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "IRC5-OmniCore-sim")])
        now = datetime.datetime.now(datetime.UTC)
        cert = (
            x509.CertificateBuilder()
            .subject_name(name)
            .issuer_name(name)
            .public_key(key.public_key())
            .serial_number(x509.random_serial_number())
            .not_valid_before(now - datetime.timedelta(minutes=5))
            .not_valid_after(now + datetime.timedelta(days=1))
            .add_extension(
                x509.SubjectAlternativeName([x509.IPAddress(ipaddress.ip_address(self.host))]),
                critical=False,
            )
            .sign(key, hashes.SHA256())
        )
        if self._tmp is None:
            self._tmp = tempfile.TemporaryDirectory(prefix="rws2-sim-")
        cert_path = Path(self._tmp.name) / "cert.pem"
        key_path = Path(self._tmp.name) / "key.pem"
        self.certificate_pem = cert.public_bytes(serialization.Encoding.PEM)
        cert_path.write_bytes(self.certificate_pem)
        self.certificate_path = cert_path
        key_path.write_bytes(
            key.private_bytes(
                serialization.Encoding.PEM,
                serialization.PrivateFormat.PKCS8,
                serialization.NoEncryption(),
            )
        )
        context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
        context.load_cert_chain(cert_path, key_path)
        return context


# --- RAPID text as the controller reads a write (this simulator's own reader) --------------

RapidItem = float | bool | str | list["RapidItem"]


class RapidValueError(ValueError):
    """Not the RAPID value the symbol's type takes."""


#: the largest num (a 32-bit float) RobotWare holds
NUM_MAX = float(np.finfo(np.float32).max)
_RAPID_TOKEN = re.compile(r'"[^"]*"|[\[\],]|[^\s\[\],"]+')
#: a num literal (RAPID kernel, "Numeric literals"), with a unary minus
_RAPID_NUM = re.compile(r"-?(?:\d+\.?\d*|\.\d+)(?:[Ee][+-]?\d+)?")


def read_value(text: str) -> RapidItem:
    """``[TRUE,[1,2.5E-3]]`` -> [True, [1.0, 0.0025]]; RapidValueError for anything else."""
    tokens = _RAPID_TOKEN.findall(text)
    value, end = _item(tokens, 0)
    if end != len(tokens):
        raise RapidValueError(f"text after the value: {tokens[end : end + 3]}")
    return value


def _item(tokens: list[str], pos: int) -> tuple[RapidItem, int]:
    if pos >= len(tokens):
        raise RapidValueError("a value is missing")
    token = tokens[pos]
    if token == "[":
        items: list[RapidItem] = []
        pos += 1
        while True:
            item, pos = _item(tokens, pos)
            items.append(item)
            if pos < len(tokens) and tokens[pos] == ",":
                pos += 1
                continue
            if pos < len(tokens) and tokens[pos] == "]":
                return items, pos + 1
            raise RapidValueError("an aggregate not closed by ]")
    if token.startswith('"'):
        return token[1:-1], pos + 1
    if token.upper() in ("TRUE", "FALSE"):
        return token.upper() == "TRUE", pos + 1
    if _RAPID_NUM.fullmatch(token):
        return float(token), pos + 1
    raise RapidValueError(f"{token!r} is not a bool, a num or an aggregate")


def read_tooldata(text: str) -> Symbol:
    """A tooldata's RAPID text -> the Symbol it sets (RapidValueError naming the member)."""
    value = read_value(text)
    if not isinstance(value, list) or len(value) != 3:
        raise RapidValueError("a tooldata is [robhold, tframe, tload]")
    robhold, tframe, tload = value
    if not isinstance(robhold, bool):
        raise RapidValueError("robhold is not a bool")
    if not isinstance(tframe, list) or len(tframe) != 2:
        raise RapidValueError("tframe is not a pose [trans, rot]")
    if not isinstance(tload, list) or len(tload) != 6:
        raise RapidValueError("tload is not a loaddata [mass, cog, aom, ix, iy, iz]")
    tx, ty, tz = _nums(tframe[0], 3, "tframe.trans")
    q1, q2, q3, q4 = _nums(tframe[1], 4, "tframe.rot")
    cx, cy, cz = _nums(tload[1], 3, "tload.cog")
    a1, a2, a3, a4 = _nums(tload[2], 4, "tload.aom")
    ix, iy, iz = _nums(tload[3:], 3, "tload.ix, iy, iz")
    return Symbol(
        robhold=robhold,
        trans=(tx, ty, tz),
        rot=(q1, q2, q3, q4),
        mass=_nums([tload[0]], 1, "tload.mass")[0],
        cog=(cx, cy, cz),
        aom=(a1, a2, a3, a4),
        inertia=(ix, iy, iz),
    )


def read_wobjdata(text: str) -> WobjSymbol:
    """A wobjdata's RAPID text -> the WobjSymbol it sets (RapidValueError naming the
    member)."""
    value = read_value(text)
    if not isinstance(value, list) or len(value) != 5:
        raise RapidValueError("a wobjdata is [robhold, ufprog, ufmec, uframe, oframe]")
    robhold, ufprog, ufmec, uframe, oframe = value
    if not isinstance(robhold, bool) or not isinstance(ufprog, bool):
        raise RapidValueError("robhold and ufprog are bools")
    if not isinstance(ufmec, str):
        raise RapidValueError("ufmec is not a string")
    return WobjSymbol(robhold, ufprog, ufmec, _pose(uframe, "uframe"), _pose(oframe, "oframe"))


def _pose(value: RapidItem, member: str) -> SimFrame:
    if not isinstance(value, list) or len(value) != 2:
        raise RapidValueError(f"{member} is not a pose [trans, rot]")
    x, y, z = _nums(value[0], 3, f"{member}.trans")
    q1, q2, q3, q4 = _nums(value[1], 4, f"{member}.rot")
    return (x, y, z), (q1, q2, q3, q4)


def _nums(value: RapidItem, count: int, member: str) -> tuple[float, ...]:
    if (
        not isinstance(value, list)
        or len(value) != count
        or not all(type(v) is float and abs(v) <= NUM_MAX for v in value)
    ):
        raise RapidValueError(f"{member} is not {count} nums")
    return tuple(v for v in value if isinstance(v, float))


def _error(code: int, msg: str) -> dict[str, object]:
    return {"_links": {}, "_embedded": {"_type": "status", "status": {"code": code, "msg": msg}}}


def _handler_for(sim: AbbRwsSimulator) -> type[BaseHTTPRequestHandler]:
    class Handler(BaseHTTPRequestHandler):
        protocol_version = "HTTP/1.1"
        server_version = "Appweb/4"
        # TCP_NODELAY: the handler writes the headers and the body apart, and with Nagle the
        # body waited for the client's delayed ACK, 42 ms a request (a deployment makes 6-10).
        disable_nagle_algorithm = True

        def log_message(self, format: str, *args: object) -> None:
            return  # quiet: the tests read `sim.requests`

        def do_GET(self) -> None:
            self._handle("GET")

        def do_POST(self) -> None:
            self._handle("POST")

        def _handle(self, method: str) -> None:
            length = int(self.headers.get("Content-Length") or 0)
            body = self.rfile.read(length) if length else b""
            headers = {k.lower(): v for k, v in self.headers.items()}
            url = urlsplit(self.path)
            if sim._cookie_session(headers) is None:
                sim.fault_at("login")  # "before" or "after": no answer either way
            if sim.stalled:
                sim.hang()  # accepts, reads, answers nothing
                self.close_connection = True
                return
            sim.slow()
            scheme = headers.get("authorization", "").split(" ", 1)[0]
            sim.requests.append((method, url.path, scheme))
            sim.queries.append({k: v[0] for k, v in parse_qs(url.query).items()})
            if sim.version == 2 and v2_media_problem(method, headers, self):
                return
            session = sim.authenticate(method, headers)
            if session is None:
                self._reply(401, None, extra={"WWW-Authenticate": sim.challenge()})
                return
            query = {k: v[0] for k, v in parse_qs(url.query).items()}
            form = {k: v[0] for k, v in parse_qs(body.decode("utf-8", "replace")).items()}
            stop = sim.fault_at(f"{method} {url.path}")
            if stop != "before":
                status, payload = route(method, url.path, query, form, session)
            if stop is not None:  # silent from here, as when stalled
                sim.stalled = True
                sim.hang()
                self.close_connection = True
                return
            self._reply(status, payload, cookie=session)

        def _reply(
            self,
            status: int,
            payload: dict[str, object] | None,
            *,
            extra: dict[str, str] | None = None,
            cookie: _Session | None = None,
        ) -> None:
            if sim.version == 2 and payload is not None and "_embedded" in payload:
                # RWS 2.0 puts an error's status at the top: {"_links", "status": {code, msg}}
                embedded = payload["_embedded"]
                assert isinstance(embedded, dict)
                payload = {"_links": payload.get("_links", {}), "status": embedded["status"]}
            data = json.dumps(payload).encode() if payload is not None else b""
            self.send_response(status)
            if data:
                self.send_header(
                    "Content-Type",
                    "application/hal+json;v=2.0" if sim.version == 2 else "application/json",
                )
            self.send_header("Content-Length", str(len(data)))
            for key, value in (extra or {}).items():
                self.send_header(key, value)
            if cookie is not None:
                self.send_header("Set-Cookie", f"-http-session-={cookie.cookie}; path=/; httponly")
                self.send_header("Set-Cookie", f"ABBCX={cookie.abbcx}; path=/")
            self.end_headers()
            self.wfile.write(data)

    def v2_media_problem(method: str, headers: dict[str, str], handler: Handler) -> bool:
        accept = headers.get("accept", "*/*")
        if V2 not in accept and "*/*" not in accept:
            handler._reply(406, _error(-1, "Not Acceptable: the Accept header needs ;v=2.0"))
            return True
        if method == "POST" and V2 not in headers.get("content-type", ""):
            handler._reply(415, _error(-1, "Unsupported Media Type: the Content-Type needs ;v=2.0"))
            return True
        return False

    def route(
        method: str, path: str, query: dict[str, str], form: dict[str, str], session: _Session
    ) -> tuple[int, dict[str, object] | None]:
        if path == "/logout":
            with sim._lock:
                sim.sessions.pop(session.cookie, None)
                if sim.mastership_holder == session.cookie:
                    sim.mastership_holder = None
            return 204, None
        if (
            sim.version == 2
            and method == "POST"
            and path
            in (
                "/rw/mastership/edit/request",
                "/rw/mastership/edit/release",
                "/rw/mastership/request",  # all domains, edit included
                "/rw/mastership/release",
            )
        ):
            return sim.mastership(path.rsplit("/", 1)[1], session)
        unit = _MECHUNIT_PATH.match(path)
        if unit is not None and method == "GET":
            return sim.mechunit_state(unit.group(1))
        motion = _MOTION_PATH.match(path)
        if motion is not None and method == "GET":
            mechunit, resource = motion.groups()
            if resource == "robtarget":
                return sim.robtarget(mechunit, query)
            return sim.jointtarget(mechunit)
        match = (_V2_PATH if sim.version == 2 else _V1_PATH).match(path)
        if match is None:
            return 404, _error(RESOURCE_NOT_FOUND_CODE, "Resource not found")
        symbol = "/".join(match.groups())
        if method == "GET":
            return sim.read_symbol(symbol)
        if sim.version == 1 and query.get("action") != "set":
            return 400, _error(PARAMETER_CODE, "Missing or unknown action")
        if "value" not in form:
            return 400, _error(PARAMETER_CODE, "Data parameter is required")
        return sim.write_symbol(symbol, form["value"], session)

    return Handler
