"""Each list is written once: every Literal under one name with one meaning, the rows and
the documents naming the same stored-word Literal, the schemas naming the libraries'
Literals, and every method-derived list equal to the registry's."""

from __future__ import annotations

import ast
import importlib
import re
from pathlib import Path
from types import UnionType
from typing import Annotated, Literal, Union, get_args, get_origin, get_type_hints

from pydantic import BaseModel
from sqlalchemy.orm import Mapped

from app.api.methods import describe
from app.kinematics.poses import POSE_FORMATS
from app.methods import METHOD_NAMES, METHODS
from app.methods.base import MethodRequest
from app.methods.frame import FRAME_METHOD_NAMES
from app.methods.guided import GUIDED, SessionCreate
from app.methods.npoint import NPointOptions
from app.methods.requests import SOLVE_MODELS, CalibrationRequest
from app.schemas import (
    audit,
    controllers,
    fleet,
    frames,
    keys,
    references,
    results,
    sessions,
    tools,
)
from app.schemas.formats import FormatList
from app.schemas.frame_sessions import FrameSession
from app.scopes import Scope
from app.services.controllers.states import EVENT_ACTIONS, SEVERITY
from app.solvers.npoint import ALGORITHMS
from app.storage import models
from app.vendors import registry
from app.words import (
    CONTROLLER_FORMATS,
    ROBOT_STATES,
    ActivationKind,
    Algorithm,
    AuditAction,
    ControllerFormat,
    DeploymentScope,
    DeploymentStatus,
    FrameKind,
    FrameMethodName,
    FrameSessionMethod,
    LaserDeviceSource,
    MethodName,
    PoseFormat,
    ProtocolName,
    Recheck,
    ResourceType,
    RobotState,
    SessionMethod,
    SessionStatus,
    SettledHolds,
    Status,
    ToolState,
    TouchOrigin,
)

APP = Path(__file__).resolve().parents[1] / "app"


def _annotation(model: type[BaseModel], field: str) -> object:
    return model.model_fields[field].annotation


def test_the_schemas_take_the_libraries_literals() -> None:
    """Pose formats, controller formats and algorithms are each one Literal (pose formats and
    algorithms in app.words, so that the rows name them without importing numpy); the request
    and response models name that very object, and the tuples the libraries check against
    are read off it."""
    assert _annotation(sessions.PlanRequest, "format") is PoseFormat
    assert _annotation(references.TouchIn, "format") is PoseFormat
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
    # The stored method names are the registry's, in its order (each request's own
    # `Literal[name]` is checked by mypy against MethodRequest's MethodName).
    assert get_args(MethodName) == METHOD_NAMES
    # and the frames' theirs (app.methods.frame, FrameMethodRequest's FrameMethodName)
    assert get_args(FrameMethodName) == FRAME_METHOD_NAMES


def _literal_of(annotation: object) -> object:
    """The Literal an annotation names, under Mapped[...], `| None` and Annotated[...] (the
    documents' StoredWord)."""
    if get_origin(annotation) is Mapped:
        (annotation,) = get_args(annotation)
    if get_origin(annotation) in (Union, UnionType):
        (annotation,) = [a for a in get_args(annotation) if a is not type(None)]
    if get_origin(annotation) is Annotated:
        annotation = get_args(annotation)[0]
    return annotation


#: Every column that holds a closed list of words: its Literal, and the request and
#: response fields that carry the same words.
WORD_COLUMNS: dict[
    tuple[type[models.Base], str], tuple[object, list[tuple[type[BaseModel], str]]]
] = {
    (models.Calibration, "method"): (
        MethodName,
        [(results.CalibrationResult, "method"), (MethodRequest, "method")],
    ),
    (models.Calibration, "algorithm"): (
        Algorithm,
        [(results.CalibrationResult, "algorithm"), (NPointOptions, "algorithm")],
    ),
    (models.Calibration, "status"): (
        Status,
        [(results.CalibrationResult, "status"), (fleet.LastCalibration, "status")],
    ),
    (models.TcpVersion, "source"): (
        MethodName,
        [(tools.Version, "source"), (tools.ActiveTcp, "method")],
    ),
    (models.TcpVersion, "status"): (Status, [(tools.Version, "status")]),
    (models.Activation, "reason"): (ActivationKind, [(tools.ActivationOut, "reason")]),
    (models.LaserDevice, "source"): (LaserDeviceSource, [(references.LaserDevice, "source")]),
    (models.ApiKey, "scope"): (
        Scope,
        [(keys.KeyCreate, "scope"), (keys.KeyOut, "scope"), (keys.KeyMe, "scope")],
    ),
    (models.AuditEvent, "action"): (AuditAction, [(audit.AuditEvent, "action")]),
    (models.AuditEvent, "resource_type"): (ResourceType, [(audit.AuditEvent, "resource_type")]),
    (models.OutboxMessage, "action"): (AuditAction, []),
    # a tool session's (Session) or a frame session's (FrameSession): the two below
    (models.GuidedSession, "method"): (SessionMethod, []),
    (models.GuidedSession, "format"): (
        PoseFormat,
        [(sessions.Session, "format"), (SessionCreate, "format")],
    ),
    (models.GuidedSession, "status"): (SessionStatus, [(sessions.Session, "status")]),
    (models.RobotController, "protocol"): (
        ProtocolName,
        [(controllers.Controller, "protocol"), (controllers.ControllerIn, "protocol")],
    ),
    (models.Deployment, "protocol"): (ProtocolName, [(controllers.Deployment, "protocol")]),
    (models.Deployment, "status"): (DeploymentStatus, [(controllers.Deployment, "status")]),
    (models.Deployment, "scope"): (
        DeploymentScope,
        [(controllers.Deployment, "scope"), (controllers.Controller, "scope")],
    ),
    (models.Frame, "kind"): (
        FrameKind,
        [(frames.RobotFrame, "kind"), (frames.FrameCreate, "kind")],
    ),
    (models.FrameVersion, "source"): (
        FrameMethodName,
        [(frames.FrameVersion, "source"), (frames.ActiveRobotFrame, "method")],
    ),
    (models.FrameVersion, "status"): (Status, [(frames.FrameVersion, "status")]),
    (models.FrameActivation, "reason"): (ActivationKind, [(tools.ActivationOut, "reason")]),
    (models.FrameCalibration, "method"): (FrameMethodName, []),
    (models.FrameCalibration, "status"): (Status, []),
    (models.ToolControllerState, "state"): (
        ToolState,
        [(controllers.ReconciledTool, "state"), (fleet.FleetController, "state")],
    ),
    (models.FrameControllerState, "state"): (ToolState, [(controllers.ReconciledFrame, "state")]),
    (models.FrameDeployment, "protocol"): (
        ProtocolName,
        [(controllers.FrameDeployment, "protocol")],
    ),
    (models.FrameDeployment, "status"): (
        DeploymentStatus,
        [(controllers.FrameDeployment, "status")],
    ),
    (models.FrameDeployment, "scope"): (DeploymentScope, [(controllers.FrameDeployment, "scope")]),
}

#: Words stored inside a JSON column, and the document field that serves them.
WORDS_IN_JSON: list[tuple[str, object, tuple[type[BaseModel], str]]] = [
    ("deployments.settled holds", SettledHolds, (controllers.DeploymentSettled, "holds")),
    ("guided_sessions.touches source", TouchOrigin, (results.TouchSource, "source")),
]


def test_a_sessions_method_is_a_tools_or_a_frames() -> None:
    """guided_sessions.method holds a tool session's method (Session.method) or a frame
    session's (FrameSession.method: a frame method or "recheck"), the registries' Literals
    and no other word."""
    assert _literal_of(_annotation(sessions.Session, "method")) is MethodName
    assert _literal_of(_annotation(FrameSession, "method")) is FrameSessionMethod
    assert set(get_args(SessionMethod)) == set(get_args(MethodName)) | set(
        get_args(FrameMethodName)
    ) | set(get_args(Recheck))


def test_each_word_column_and_its_documents_name_one_literal() -> None:
    """The row's `Mapped[...]` and every request and response field carrying the column's
    words name the same Literal object (not an equal list written again)."""
    for (model, column), (literal, documents) in WORD_COLUMNS.items():
        row = _literal_of(get_type_hints(model)[column])
        assert row is literal, (model.__name__, column, row)
        for document, field in documents:
            served = _literal_of(_annotation(document, field))
            assert served is literal, (model.__name__, column, document.__name__, field)
    for where, literal, (document, field) in WORDS_IN_JSON:
        assert _literal_of(_annotation(document, field)) is literal, where
    assert _literal_of(_annotation(controllers.Reconciliation, "state")) is RobotState


#: The text columns that hold no closed list of words (ids, `*_id`, aside): names, people's
#: words, addresses, secrets, errors. A new text column is either here or a Literal's.
FREE_TEXT: dict[tuple[str, str], str] = {
    **{
        (table, "name"): "a name a person gives"
        for table in (
            "robots",
            "tools",
            "frames",
            "reference_points",
            "laser_devices",
            "api_keys",
            "frame_fiducials",
        )
    },
    **dict.fromkeys(
        (
            ("calibrations", "created_by"),
            ("tcp_versions", "created_by"),
            ("frame_calibrations", "created_by"),
            ("frame_versions", "created_by"),
            ("frame_activations", "activated_by"),
            ("reference_points", "created_by"),
            ("laser_devices", "created_by"),
            ("api_keys", "created_by"),
            ("guided_sessions", "created_by"),
            ("activations", "activated_by"),
            ("audit_events", "actor"),
            ("deployments", "actor"),
            ("frame_deployments", "actor"),
        ),
        "the name of the API key (or cli:<user>) that acted",
    ),
    **dict.fromkeys(
        (
            ("robots", "vendor"),
            ("robots", "model"),
            ("robots", "serial"),
            ("robots", "cell"),
            ("tools", "serial"),
            ("tools", "description"),
            ("frames", "description"),
            ("frame_versions", "note"),
            ("frame_activations", "reason_text"),
            ("tcp_versions", "note"),
            ("activations", "reason_text"),
            ("deployments", "reason"),
            ("frame_deployments", "reason"),
        ),
        "a person's own words",
    ),
    ("reference_points", "source"): '"numeric", a method, or "touch:<tool id>:v<version>"',
    ("tools", "controller_symbol"): "an ABB PERS tooldata, TASK/MODULE/SYMBOL",
    ("frames", "controller_symbol"): "an ABB wobjdata or fixed tooldata, TASK/MODULE/SYMBOL",
    ("robot_controllers", "host"): "a host name or address",
    ("robot_controllers", "username"): "a controller's user",
    ("robot_controllers", "password_encrypted"): "a secret, encrypted",
    ("api_keys", "key_hash"): "a digest",
    ("api_keys", "prefix"): "the start of a key",
    ("idempotency_records", "key"): "a client's Idempotency-Key",
    ("idempotency_records", "request_hash"): "a digest",
    ("deployments", "target"): "where in the controller: $TOOL_DATA[3], UTOOL[3], a symbol",
    ("tool_controller_states", "target"): "where in the controller",
    ("tool_controller_states", "error"): "what went wrong, in a sentence",
    ("frame_deployments", "target"): "where in the controller: BASE_DATA[3], UFRAME[3], a symbol",
    ("frame_controller_states", "target"): "where in the controller",
    ("frame_controller_states", "error"): "what went wrong, in a sentence",
    ("robot_live_tools", "error"): "what went wrong, in a sentence",
    ("robot_live_frames", "name"): "a frame's name as its controller keeps it",
    ("watch_leases", "holder"): "an instance's name: host:pid:random",
    ("watchers", "holder"): "an instance's name: host:pid:random",
}


def test_every_text_column_is_a_literal_or_free_text() -> None:
    """A `Mapped[str]` column that is not an id is in FREE_TEXT; any other text column holds
    words and is typed as their Literal (so WORD_COLUMNS can name it)."""
    untyped, words = [], []
    for mapper in models.Base.registry.mappers:
        model = mapper.class_
        hints = get_type_hints(model)
        for column in model.__table__.columns:
            if column.key == "id" or column.key.endswith("_id"):
                continue
            key = (model.__tablename__, column.key)
            annotation = _literal_of(hints[column.key])
            if annotation is str and key not in FREE_TEXT:
                untyped.append(key)
            if get_origin(annotation) is Literal and (model, column.key) not in WORD_COLUMNS:
                words.append(key)
    assert untyped == [], f"text columns typed str: a Literal's words, or FREE_TEXT? {untyped}"
    assert words == [], f"word columns missing from WORD_COLUMNS: {words}"
    stale = [k for k in FREE_TEXT if k[1] not in models.Base.metadata.tables[k[0]].columns]
    assert stale == [], stale


def test_every_controller_state_has_a_severity_naming_a_robot_state() -> None:
    assert set(SEVERITY) == set(get_args(ToolState))
    assert all(ROBOT_STATES[SEVERITY[state]] == state for state in ROBOT_STATES)
    assert all(action == f"controller.{state}" for state, action in EVENT_ACTIONS.items())


def _alias_value(node: ast.stmt) -> tuple[list[str], ast.expr | None]:
    """The names a top-level statement assigns and the value it assigns them."""
    if isinstance(node, ast.Assign):
        return [t.id for t in node.targets if isinstance(t, ast.Name)], node.value
    if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
        return [node.target.id], node.value
    return [], None


def _is_literal(node: ast.AST | None) -> bool:
    return isinstance(node, ast.Subscript) and ast.unparse(node.value) == "Literal"


def _literals_in_app() -> tuple[list[tuple[str, str]], list[tuple[str, int, frozenset[str]]]]:
    """Every Literal of app/: (module, name) of each assigned to a name at the top of a
    module, and (file, line, words) of each written in place (in an annotation, a mapping's
    type) with two or more strings."""
    aliases, in_place = [], []
    for path in sorted(APP.rglob("*.py")):
        module = ".".join(path.relative_to(APP.parent).with_suffix("").parts)
        module = module.removesuffix(".__init__")
        tree = ast.parse(path.read_text())
        definitions = set()
        for node in tree.body:
            names, value = _alias_value(node)
            if _is_literal(value):
                aliases += [(module, name) for name in names]
                definitions.add(id(value))
        for found in ast.walk(tree):
            if not isinstance(found, ast.Subscript) or not _is_literal(found):
                continue
            if id(found) in definitions:
                continue
            items = found.slice.elts if isinstance(found.slice, ast.Tuple) else [found.slice]
            words = [i.value for i in items if isinstance(i, ast.Constant)]
            strings = {w for w in words if isinstance(w, str)}
            if len(words) >= 2 and len(strings) == len(words):
                where = str(path.relative_to(APP.parent))
                in_place.append((where, found.lineno, frozenset(strings)))
    return aliases, in_place


def test_no_literal_is_written_twice() -> None:
    """One name, one meaning, one place: no Literal name is defined in two modules (a
    SigmaSource of two words in one and of three in another), no two names list the same
    words (WorkingAxis written in the solver and again in the method), and no list of words
    a name holds is written out again in place (Literal["typed", "controller"] for
    TouchOrigin)."""
    aliases, in_place = _literals_in_app()
    by_name: dict[str, list[str]] = {}
    for module, name in aliases:
        by_name.setdefault(name, []).append(module)
    assert {n: m for n, m in by_name.items() if len(m) > 1} == {}, "one name, two Literals"
    by_words: dict[frozenset[str], list[str]] = {}
    for module, name in aliases:
        words = frozenset(get_args(getattr(importlib.import_module(module), name)))
        by_words.setdefault(words, []).append(f"{module}.{name}")
    assert {w: n for w, n in by_words.items() if len(n) > 1} == {}, "one list, two names"
    again = [(f"{f}:{line}", by_words[w]) for f, line, w in in_place if w in by_words]
    assert again == [], "a named Literal's words written out again: use the name"


def _bound_at_top(path: Path) -> set[str]:
    """The public upper-case names a module binds at its top level (not imports)."""
    names: set[str] = set()
    for node in ast.parse(path.read_text()).body:
        targets, _ = _alias_value(node)
        names |= {t for t in targets if t.isupper() and not t.startswith("_")}
    return names


def test_the_registrys_tables_have_names_of_their_own() -> None:
    """Each table app.vendors.registry keeps by protocol or by format (SLOT_RANGES, the slots
    each protocol addresses; TOOL_NUMBERS; the deployment scopes ...) has a name no module
    outside app/vendors binds to something else: one name was {protocol: (low, high)} there
    and {format: (vendor, low, high)} in app/services/robots/slots.py, another the
    deployment scope of each protocol there and the API keys' scopes in app/scopes.py. (A
    maker's package binds its own TOOL_NUMBERS: its entry of the registry's table.)"""
    tables = _bound_at_top(APP / "vendors" / "registry.py")
    again = {
        str(path.relative_to(APP.parent)): sorted(tables & _bound_at_top(path))
        for path in APP.rglob("*.py")
        if path.parent.relative_to(APP).parts[:1] != ("vendors",)
    }
    assert {where: names for where, names in again.items() if names} == {}


def test_the_services_take_formats_as_their_literals() -> None:
    """A format reaches the services validated (the request models' PoseFormat, the routes'
    ?format= checked against ControllerFormat): no service takes one as a plain `str`, which
    would let an unchecked word through where mypy could have said so."""
    plain = []
    for path in sorted((APP / "services").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.arg | ast.AnnAssign) and node.annotation is not None:
                name = node.arg if isinstance(node, ast.arg) else ast.unparse(node.target)
                if name in ("fmt", "format") and "str" in ast.unparse(node.annotation):
                    plain.append(f"{path.relative_to(APP.parent)}:{node.lineno}")
    assert plain == []


#: The problems a connector's failure becomes (app.errors): the 502s a client gets.
CONTROLLER_PROBLEMS = {"ControllerRefusedError", "ControllerUnreachableError"}


def test_a_controllers_failure_becomes_its_502_in_one_place() -> None:
    """Capture and deployments once each wrote the mapping from a connector's failure to its
    502 (capture.controller_failure, deployments._failure), each sentence twice: the one
    function in app/services/controllers/failures.py is the only place that raises or builds
    them (others may test for them)."""
    built = set()
    for path in sorted(APP.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and ast.unparse(node.func) in CONTROLLER_PROBLEMS:
                built.add(str(path.relative_to(APP.parent)))
    assert built == {"app/services/controllers/failures.py"}


def test_no_class_is_named_as_a_literal() -> None:
    """A name is a Literal's or a class's, not both: app.publish.sink's dataclass ToolState
    (a tool's published document) once shared its name with app.words.ToolState (a tool's
    controller state), so a reader of either could take one for the other."""
    aliases, _in_place = _literals_in_app()
    literal_names = {name for _module, name in aliases}
    classes = [
        f"{path.relative_to(APP.parent)}:{node.name}"
        for path in sorted(APP.rglob("*.py"))
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.ClassDef) and node.name in literal_names
    ]
    assert classes == [], "a class named as a Literal: rename it to say what it holds"


def test_each_method_name_is_written_once() -> None:
    """A method's name is written in app/words.py only (issue 46: it was spelled in its
    request's Literal, the list in app/words.py, the CLI's and the console's defaults): the
    requests, the registry and GET /v1/methods name it through its Literal, the services
    through its registry entry, the CLI and the console read it from GET /v1/methods."""
    names = set(METHOD_NAMES) | set(FRAME_METHOD_NAMES)
    spelled = [
        f"{path.relative_to(APP.parent)}:{node.lineno} {node.value}"
        for path in sorted(APP.rglob("*.py"))
        if path != APP / "words.py"
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.Constant) and node.value in names
    ]
    alternatives = "|".join(map(re.escape, sorted(names)))
    quoted = re.compile(rf"""["'`]({alternatives})["'`]""")
    spelled += [
        f"{path.relative_to(APP.parent)}:{number} {match.group(1)}"
        for path in sorted((APP / "console").rglob("*"))
        if path.suffix in {".js", ".html"}
        for number, line in enumerate(path.read_text().splitlines(), 1)
        for match in quoted.finditer(line)
    ]
    assert spelled == [], "name the method through app.words or its registry entry"
    words = (APP / "words.py").read_text()
    assert all(words.count(f'"{name}"') == 1 for name in names)


def test_the_guided_method_is_the_one_a_session_takes() -> None:
    """GET /v1/methods marks one method `guided`, the one a guided session's `method` takes:
    the CLI and the console start sessions, and calibrate by default, with it."""
    assert get_args(_annotation(SessionCreate, "method")) == (GUIDED.name,)
    assert [describe(m).name for m in METHODS if describe(m).guided] == [GUIDED.name]


#: The makers' package names (app/vendors/<maker>/), as the registry lists them.
MAKER_PACKAGES = tuple(sorted(m.text.__module__.rsplit(".", 1)[-1] for m in registry.MAKERS))
#: The files that may name any maker: the registry (its import and MAKERS line) and the words.
MAY_NAME_MAKERS = frozenset({"vendors/registry.py", "words.py"})


def _words_of_words_py() -> frozenset[str]:
    import app.words

    words: set[str] = set()

    def add(annotation: object) -> None:
        for arg in get_args(annotation):
            if isinstance(arg, str):
                words.add(arg)
            else:
                add(arg)

    for value in vars(app.words).values():
        if get_origin(value) is Literal:
            add(value)
    return frozenset(words)


def _names_a_maker(line: str, start: int, end: int, words: frozenset[str]) -> bool:
    """Whether line[start:end], a maker's name standing as a word, names the maker: not when
    it is part of a word of app/words.py (or an identifier built of one, `kuka_abc_from_matrix`),
    a quoted format word (``"kuka"``), or the path of the maker's own package."""
    left, right = start, end
    while left > 0 and (line[left - 1].isalnum() or line[left - 1] == "_"):
        left -= 1
    while right < len(line) and (line[right].isalnum() or line[right] == "_"):
        right += 1
    token, name = line[left:right], line[start:end]
    parts = token.split("_")
    built = {"_".join(parts[i:j]) for i in range(len(parts)) for j in range(i + 2, len(parts) + 1)}
    if any(name.lower() in word.split("_") for word in built & words):
        return False
    quoted = left > 0 and right < len(line) and line[left - 1] == line[right] in "\"'`"
    if token == name and name in words and quoted:
        return False
    return not re.search(r"vendors[./]$", line[:left])


def maker_mentions() -> dict[str, list[str]]:
    """Every line of app/ (py, js, html, css) outside a maker's own package naming a maker,
    by file (relative to app/), as "line: maker"."""
    words = _words_of_words_py()
    found: dict[str, list[str]] = {}
    for path in sorted(APP.rglob("*")):
        if path.suffix not in (".py", ".js", ".html", ".css"):
            continue
        rel = path.relative_to(APP).as_posix()
        if rel in MAY_NAME_MAKERS:
            continue
        for number, line in enumerate(path.read_text().splitlines(), 1):
            for maker in MAKER_PACKAGES:
                if rel.startswith(f"vendors/{maker}/"):
                    continue
                # `ur` as the word ur or UR only (not Ur, not inside "pure" or "ur_rtde").
                flags = 0 if maker == "ur" else re.IGNORECASE
                spelled = "(?:ur|UR)" if maker == "ur" else maker
                pattern = re.compile(rf"(?<![A-Za-z0-9]){spelled}(?![A-Za-z0-9])", flags)
                found.setdefault(rel, []).extend(
                    f"{number}: {maker}"
                    for match in pattern.finditer(line)
                    if _names_a_maker(line, match.start(), match.end(), words)
                )
    return {rel: lines for rel, lines in found.items() if lines}


def test_a_maker_is_named_only_by_its_package_the_registry_and_the_words() -> None:
    """A maker (its package name under app/vendors/) is named outside its own package only
    by the registry (its import and MAKERS line), app/words.py, and the docs (README.md,
    docs/; not scanned here) (issue 46): anything else that knows a maker copies a fact its
    declaration holds. A word app/words.py defines and another file uses as that word
    (`kuka_abc`, `techman_rxyz`, `kuka_kvp`, the format "kuka") is the word, not a copy of
    the maker; nor is the path of the maker's package (app.vendors.kuka.text). A pose
    convention is named by its format's word (`kuka_abc`), and which maker's pendant shows
    it is Maker.pose_format's (said by GET /v1/formats); each pendant's name for a frame
    construction is Maker.teaches."""
    assert maker_mentions() == {}, "a maker named where its declaration or the registry is meant"
