"""Every registered controller maker provides what the registry asks of it, and the stored
words (app/words.py's Literals) are the registry's: adding a maker is its package, its line in
MAKERS and its words, and this module says what is missing.

`missing(maker)` lists what a maker lacks; each registered maker lacks nothing, and a maker
planted without one of its parts is told what it lacks (so the check can fail).
"""

from __future__ import annotations

import ast
import inspect
import re
import subprocess
import sys
import tomllib
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace
from typing import cast, get_args

import numpy as np
import pytest

from app.vendors import registry
from app.vendors.connector import ToolTarget
from app.vendors.files import FileContext, FileTool
from app.vendors.maker import (
    BySlot,
    BySymbol,
    FileModule,
    Maker,
    OpenSession,
    TextModule,
    WireProtocol,
)
from app.vendors.registry import (
    BY_FORMAT,
    DEFAULT_PORTS,
    MAKERS,
    SERVICE_PORTS,
    SLOT_RANGES,
    TARGET_FIELD,
    TOOL_NUMBERS,
    WIRE_PROTOCOLS,
    vendor_formats,
)
from app.vendors.tool import ToolData, ToolLoad
from app.words import CONTROLLER_FORMATS, PROTOCOLS, ControllerFormat, PoseFormat, ProtocolName

ROOT = Path(__file__).resolve().parents[2]
#: What a connector class offers (app.vendors.connector.Connector).
CONNECTOR_METHODS = ("describe", "read_tool", "write_tool", "read_pose", "close")
#: A tool every maker's text and file can hold, its numbers exact in each one's printing
#: (a 120 deg turn about (1, 1, 1): KUKA A B C and W P R 90, 0, 90; UR's rotation vector to
#: 1e-10 rad), so that a round trip gives it back within 1e-9.
SAMPLE = ToolData(
    position_mm=(12.5, -3.25, 150.0),
    quaternion=(0.5, 0.5, 0.5, 0.5),
    load=ToolLoad(2.5, (0.0, 0.0, 80.0)),
    name="probe",
    controller_symbol="T_ROB1/user/tProbe",
)


def _sample(maker: Maker) -> ToolData:
    slot = maker.tool_numbers[0] if maker.tool_numbers is not None else 1
    return replace(SAMPLE, slot=slot)


def _same_tcp(position: object, quaternion: object, tool: ToolData) -> bool:
    p, q = np.asarray(position, dtype=float), np.asarray(quaternion, dtype=float)
    return bool(
        np.abs(p - tool.position_mm).max() <= 1e-9
        and min(np.abs(q - tool.quaternion).max(), np.abs(q + tool.quaternion).max()) <= 1e-9
    )


def _text_missing(maker: Maker) -> list[str]:
    text = maker.text()
    if not (callable(getattr(text, "export", None)) and callable(getattr(text, "parse", None))):
        return [f"{maker.format}: its text module has no export or no parse"]
    tool = _sample(maker)
    export = text.export(tool)
    if export.format != maker.format:
        return [f"{maker.format}: its export says format {export.format!r}"]
    if not _same_tcp(*text.parse(export.text), tool):
        return [f"{maker.format}: parse(export(tool)) is not the tool within 1e-9"]
    return []


def _file_missing(maker: Maker) -> list[str]:
    files = maker.file()
    if not (callable(getattr(files, "write", None)) and callable(getattr(files, "read", None))):
        return [f"{maker.format}: its file module has no write or no read"]
    tool = _sample(maker)
    written = files.write([FileTool(tool)], FileContext())
    if written.format != maker.format or not written.name or not written.text.endswith("\n"):
        return [f"{maker.format}: its file is not named, not its format or not ended"]
    back = files.read(written.text)
    if len(back) != 1 or not _same_tcp(back[0].position_mm, back[0].quaternion_wxyz, tool):
        return [f"{maker.format}: read(write([tool])) is not the tool within 1e-9"]
    return []


def _protocol_missing(maker: Maker, wire: WireProtocol) -> list[str]:
    found = []
    if wire.name not in PROTOCOLS:
        found.append(f"{wire.name}: not a word of ProtocolName (app/words.py)")
    ports = [wire.default_port] if wire.default_port is not None else []
    ports += [port for _, port in wire.services]
    if bool(wire.default_port) == bool(wire.services) or not all(1 <= p <= 65535 for p in ports):
        found.append(f"{wire.name}: neither one default port nor its services' ports")
    if isinstance(wire.address, BySlot) and wire.address.numbers != maker.tool_numbers:
        found.append(f"{wire.name}: its slots {wire.address.numbers} are not its maker's")
    target = ToolTarget(slot=maker.tool_numbers[0]) if maker.tool_numbers else ToolTarget()
    if isinstance(wire.address, BySymbol):
        target = ToolTarget(symbol=SAMPLE.controller_symbol)
    if wire.target_problem(target) is not None or not wire.describe(target):
        found.append(f"{wire.name}: cannot address its maker's first tool")
    if wire.connector is None:
        return found  # not written yet: connect() says so (tests/vendors/test_connector)
    connector = wire.connector()
    methods = [m for m in CONNECTOR_METHODS if not callable(getattr(connector, m, None))]
    if not inspect.isclass(connector) or methods:
        found.append(f"{wire.name}: its connector is no class with {', '.join(methods)}")
    elif list(inspect.signature(connector).parameters) != ["settings"]:
        found.append(f"{wire.name}: its connector is not opened with the settings alone")
    return found


def missing(maker: Maker) -> list[str]:
    """What `maker` lacks of what the registry asks, in sentences; [] when nothing."""
    found = []
    if maker.format not in CONTROLLER_FORMATS:
        found.append(f"{maker.format}: not a word of ControllerFormat (app/words.py)")
    if maker.pose_format not in get_args(PoseFormat) or maker.pose_format in ("joints", "matrix"):
        found.append(f"{maker.format}: {maker.pose_format!r} is no pose format a pendant shows")
    if not (maker.name and maker.file_kind and maker.vendor_words):
        found.append(f"{maker.format}: no name, file kind or vendor word")
    if any(w != w.lower() for w in maker.vendor_words + maker.vendor_initials):
        found.append(f"{maker.format}: vendor words are matched in lower case")
    if maker.tool_numbers is not None:
        low, high = maker.tool_numbers
        if not 0 <= low <= high:
            found.append(f"{maker.format}: tool numbers {maker.tool_numbers} are no range")
    if any(arm.name is None for arm in maker.arms):
        found.append(f"{maker.format}: an arm with no preset name")
    found += _text_missing(maker) + _file_missing(maker)
    for wire in maker.protocols:
        found += _protocol_missing(maker, wire)
    return found


@pytest.mark.parametrize("maker", MAKERS, ids=lambda m: m.format)
def test_every_maker_provides_what_the_registry_asks(maker: Maker) -> None:
    assert missing(maker) == []


def test_the_presets_are_the_makers_arms_each_named_once() -> None:
    """PRESETS holds every arm a maker declares, by its name: no two arms share a preset name
    (a second would hide the first)."""
    arms = [arm for maker in MAKERS for arm in maker.arms]
    assert list(registry.PRESETS.values()) == arms
    assert all(registry.PRESETS[name].name == name for name in registry.PRESETS)


def test_importing_the_registry_loads_no_scipy() -> None:
    """The makers' declarations, their arms' DH tables among them, are plain data: the
    registry (and so the API schemas) loads scipy only when a pose is computed."""
    code = "import sys, app.vendors.registry; print('scipy' in sys.modules)"
    run = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT
    )
    assert run.stdout.strip() == "False"


@pytest.mark.parametrize("maker", MAKERS, ids=lambda m: m.format)
def test_every_vendor_word_names_its_maker(maker: Maker) -> None:
    for word in maker.vendor_words:
        assert vendor_formats(f"{word.title()} Robotics") == (maker.format,)
    for initials in maker.vendor_initials:
        assert vendor_formats(f"{initials.upper()} 10") == (maker.format,)


@pytest.mark.parametrize("maker", MAKERS, ids=lambda m: m.format)
def test_a_vendors_pose_format_is_its_makers(maker: Maker) -> None:
    for word in maker.vendor_words:
        assert registry.vendor_pose_format(f"{word.title()} Robotics") == maker.pose_format
    assert registry.vendor_pose_format("Acme") is None
    assert registry.vendor_pose_format(None) is None


def test_the_calibrate_page_and_the_cli_copy_no_makers_table() -> None:
    """The console's calibrate page reads a robot's pose format from the API (its
    controller's and its own `pose_format`) and the CLI's --ports help the services from the
    registry (issue 46): calibrate.js:8-9 copied each protocol's and vendor's pose format,
    app/cli/connection.py:138 each protocol's services. Neither names a maker, its vendor
    words, its protocols or its pendant's pose format."""
    app = Path(__file__).resolve().parents[2] / "app"
    words = {
        word
        for m in MAKERS
        for word in (m.format, m.pose_format, *m.vendor_words, *(w.name for w in m.protocols))
    }
    alternatives = "|".join(sorted(map(re.escape, words)))
    pattern = re.compile(rf"\b({alternatives})\b", re.IGNORECASE)
    page = (app / "console" / "calibrate.js").read_text()
    named = [
        f"calibrate.js:{n}: {m.group(1)}"
        for n, line in enumerate(page.splitlines(), 1)
        for m in pattern.finditer(line)
    ]
    # The CLI's --ports help: no protocol named with its services (it said "techman
    # listen_node, ethernet_slave; ..."), but read off SERVICE_PORTS.
    services = re.compile(
        "|".join(
            rf"\b{re.escape(p)} {re.escape(next(iter(s)))}\b" for p, s in SERVICE_PORTS.items()
        )
    )
    cli = ast.parse((app / "cli" / "connection.py").read_text())
    named += [
        f"connection.py:{node.lineno}: {match.group(0)}"
        for node in ast.walk(cli)
        if isinstance(node, ast.Constant) and isinstance(node.value, str)
        for match in services.finditer(node.value)
    ]
    assert named == []


def test_the_stored_words_are_the_registrys() -> None:
    """ControllerFormat and ProtocolName (mypy's and pydantic's, so the OpenAPI enums) name
    the registered makers and protocols, in the order the API lists them (the protocols of
    one port first: the schema's description lists them so); no two makers claim a format or
    a protocol."""
    assert get_args(ControllerFormat) == tuple(BY_FORMAT) == CONTROLLER_FORMATS
    assert len(BY_FORMAT) == len(MAKERS)
    assert get_args(ProtocolName) == tuple(WIRE_PROTOCOLS) == PROTOCOLS
    assert len(WIRE_PROTOCOLS) == sum(len(m.protocols) for m in MAKERS)
    assert tuple(TARGET_FIELD) == PROTOCOLS
    assert tuple(DEFAULT_PORTS) + tuple(SERVICE_PORTS) == PROTOCOLS
    assert set(SLOT_RANGES) == {p for p, field in TARGET_FIELD.items() if field == "slot"}
    assert {m.format: m.tool_numbers for m in MAKERS if m.tool_numbers} == TOOL_NUMBERS
    assert set(registry.PENDANT_FORMATS) == set(PROTOCOLS)  # every controller's pendant format


def test_the_independence_contract_names_every_maker() -> None:
    """pyproject.toml's import contract keeps the makers from importing each other: it
    names every registered maker's package (a maker left out could import another)."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    contracts = config["tool"]["importlinter"]["contracts"]
    (independent,) = [
        c for c in contracts if c["type"] == "independence" and "app.vendors.kuka" in c["modules"]
    ]
    packages = {inspect.getmodule(m.text).__name__ for m in MAKERS}  # type: ignore[union-attr]
    assert set(independent["modules"]) == packages


def test_the_layers_contract_puts_every_maker_between_the_registry_and_the_shared_modules() -> None:
    """pyproject.toml's layers contract of app.vendors keeps each maker under the registry and
    over maker.py and the shared modules: a maker left out of its layer is held by nothing
    there (it could import the registry, or a shared module import it)."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    contracts = config["tool"]["importlinter"]["contracts"]
    (layers,) = [
        c for c in contracts if c["type"] == "layers" and c.get("containers") == ["app.vendors"]
    ]
    makers = [layer for layer in layers["layers"] if "kuka" in layer.split(" | ")]
    packages = {inspect.getmodule(m.text).__name__ for m in MAKERS}  # type: ignore[union-attr]
    assert [{f"app.vendors.{name}" for name in layer.split(" | ")} for layer in makers] == [
        packages
    ]


def test_the_registrys_table_names_each_protocols_connector() -> None:
    """app/vendors/registry.py's docstring table has a row for every registered protocol, in
    their order, naming the module of its connector (or "(not yet)" without one): the table
    once said yaskawa_hses had none after its connector landed."""
    rows = [
        [cell.strip() for cell in line.strip("|").split("|")]
        for line in (registry.__doc__ or "").splitlines()
        if line.startswith("| ") and not line.startswith("| protocol ")
    ]
    table = {protocol: connector for protocol, connector, _document in rows}
    assert tuple(table) == PROTOCOLS, "a row per registered protocol, in their order"
    for protocol, wire in WIRE_PROTOCOLS.items():
        module = "(not yet)"
        if wire.connector is not None:
            name = inspect.getmodule(wire.connector())
            assert name is not None
            module = name.__name__.removeprefix("app.vendors.").replace(".", "/") + ".py"
        assert table[protocol] == module, protocol


def _module(**functions: object) -> SimpleNamespace:
    return SimpleNamespace(**functions)


def test_a_maker_lacking_a_part_is_told_what_it_lacks() -> None:
    """The check can fail: a planted maker without each part in turn is reported."""
    kuka = BY_FORMAT["kuka"]
    text, files = kuka.text(), kuka.file()
    no_parse = _module(export=text.export)
    no_read = _module(write=files.write)
    wire = kuka.protocols[0]

    class HalfConnector:
        def __init__(self, settings: object) -> None: ...

        def describe(self, target: ToolTarget) -> str:
            return ""

    def mirrored_parse(value: str) -> tuple[object, object]:
        position, quaternion = text.parse(value)
        return position, quaternion * [1, -1, 1, 1]

    planted = {
        "text module has no export or no parse": replace(
            kuka, text=lambda: cast(TextModule, no_parse)
        ),
        "parse(export(tool)) is not the tool": replace(
            kuka, text=lambda: cast(TextModule, _module(export=text.export, parse=mirrored_parse))
        ),
        "file module has no write or no read": replace(
            kuka, file=lambda: cast(FileModule, no_read)
        ),
        "not a word of ControllerFormat": replace(kuka, format="not_a_format"),
        "'joints' is no pose format a pendant shows": replace(kuka, pose_format="joints"),
        "not a word of ProtocolName": replace(
            kuka, protocols=(replace(wire, name="not_a_protocol"),)
        ),
        "its slots (1, 10) are not its maker's": replace(
            kuka, protocols=(replace(wire, address=BySlot((1, 10), "$TOOL_DATA[{}]")),)
        ),
        "neither one default port nor its services' ports": replace(
            kuka, protocols=(replace(wire, services=(("main", 7000),)),)
        ),
        "no class with read_tool, write_tool, read_pose, close": replace(
            kuka, protocols=(replace(wire, connector=lambda: cast(OpenSession, HalfConnector)),)
        ),
    }
    for said, maker in planted.items():
        assert any(said in sentence for sentence in missing(maker)), said


def test_what_a_pendant_teaches_is_a_method_and_the_methods_say_it() -> None:
    """Each maker's `teaches` names a tool calibration method by its word (a typo would name a
    method GET /v1/methods does not have), and that method's description names the maker's
    pendant's name for it, every maker's in one parenthesis ("ABB TCP&Z,X; Fanuc six-point")."""
    from app.methods import METHODS_BY_NAME

    taught = [(maker, method, name) for maker in registry.MAKERS for method, name in maker.teaches]
    assert {method for _maker, method, _name in taught} <= set(METHODS_BY_NAME)
    for maker, method, name in taught:
        description = METHODS_BY_NAME[method].description
        assert f"({registry.taught_as(method)})" in description
        assert f"{maker.name} {name}" in registry.taught_as(method)
    with pytest.raises(KeyError, match="no maker declares"):
        registry.taught_as("no_such_method")
