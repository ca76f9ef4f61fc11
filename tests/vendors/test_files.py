"""Controller files: golden files, file -> parse round trips over random frames and loads,
the FANUC program's LS structure, names safe for each controller, refusals."""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from app.errors import InvalidInput
from app.vendors.files import FileContext, FileTool, ParsedTool, Provenance
from app.vendors.registry import controller_file, parse_controller_file, vendor_formats
from app.vendors.tool import ToolData
from app.words import CONTROLLER_FORMATS
from tests.vendors.fanuc.ls_grammar import check_ls
from tests.vendors.tools import tool_data

GOLDEN = Path(__file__).parent / "golden"
WHEN = datetime(2026, 11, 24, 5, 0, 12, tzinfo=UTC)
SERVER = "https://tcpcal.plant.example"
#: What each file's printed precision gives back: (mm, deg, kg).
PRECISION = {
    "kuka": (1e-6, 1e-6, 5e-4),
    "abb": (1e-6, 1e-6, 5e-4),
    "fanuc": (1e-3, 2e-3, None),
    "ur": (1e-6, 1e-6, 5e-4),
    "yaskawa": (1e-3, 2e-4, 5e-4),
    "techman": (1e-6, 1e-6, 5e-4),
}
SLOTS = {"kuka": (1, 16), "fanuc": (1, 10), "yaskawa": (0, 63)}


def item(
    name: str,
    slot: int | None,
    position: list[float],
    quaternion: list[float],
    mass: float | None = 2.5,
    cog: list[float] | None = None,
    version: int = 4,
    symbol: str | None = None,
) -> FileTool:
    data = tool_data(slot, name, np.array(position), np.array(quaternion), mass,
                    np.array(cog if cog is not None else [0.0, 0.0, 80.0]), symbol)  # fmt: skip
    origin = Provenance(version, WHEN, "alice", "xyz_npoint", f"{SERVER}/ui/tools/t{slot}")
    return FileTool(data, origin)


def golden_tools() -> list[FileTool]:
    h = float(np.sqrt(0.5))
    return [
        item("torch", 3, [1.5, -2.25, 150.0], [h, 0.0, -h, 0.0], 2.5, [0.0, 0.0, 80.0]),
        item(
            "gripper 🤖 Düse",
            1,
            [0.0, 12.0, 95.5],
            [1.0, 0.0, 0.0, 0.0],
            4.25,
            [5, 0, 40],
            symbol="T_ROB1/user/tGripper",
        ),
        item("x" * 60, 5, [-10.0, 0.0, 210.0], [0.5, 0.5, 0.5, 0.5], None),
    ]


def _fits(fmt: str, tool: FileTool) -> bool:
    return not (fmt == "abb" and tool.data.load is None)


@pytest.mark.parametrize("fmt", CONTROLLER_FORMATS)
@pytest.mark.parametrize("table", [False, True], ids=["tool", "table"])
def test_golden_files(fmt: str, table: bool) -> None:
    """The files as reviewed against each module's cited documentation (regenerate with
    TCPCAL_WRITE_GOLDEN=1 and review the diff). A regression check of the layout only: the
    code under test wrote them, and their rotations (-90 deg about Y; 90, 0, 90) cannot show a
    swapped angle order. The conventions are held by test_outside_samples.py (files other
    people wrote, and a general rotation computed with scipy)."""
    tools = golden_tools() if table else golden_tools()[:1]
    out = controller_file(fmt, tools, FileContext("cell7 KR16", SERVER, table=table))
    path = GOLDEN / f"{fmt}_{'table' if table else 'tool'}__{out.name}"
    if os.environ.get("TCPCAL_WRITE_GOLDEN"):
        path.write_text(out.text)
    assert out.text == path.read_text()
    assert out.text.endswith("\n")
    assert all(line == line.rstrip() for line in out.text.splitlines()), "trailing blanks"
    assert out.text.isascii()


def _angle_deg(q1: np.ndarray, q2: np.ndarray) -> float:
    r1 = Rotation.from_quat(np.roll(q1, -1))
    r2 = Rotation.from_quat(np.roll(q2, -1))
    return float(np.degrees((r1.inv() * r2).magnitude()))


def _match(parsed: list[ParsedTool], tool: ToolData, fmt: str) -> ParsedTool:
    if fmt in SLOTS:
        return next(p for p in parsed if p.slot == tool.slot)
    return next(p for p in parsed if np.linalg.norm(p.position_mm - tool.position_mm) < 0.01)


unit_quaternions = (
    st.lists(st.floats(-1, 1, allow_nan=False), min_size=4, max_size=4)
    .filter(lambda q: float(np.linalg.norm(q)) > 0.1)
    .map(lambda q: (np.asarray(q) / np.linalg.norm(q)).tolist())
)
coords = st.lists(st.floats(-1500, 1500, allow_nan=False), min_size=3, max_size=3)
loads = st.one_of(
    st.none(),
    st.tuples(st.floats(0.01, 500), st.lists(st.floats(-500, 500), min_size=3, max_size=3)),
)


@pytest.mark.parametrize("fmt", CONTROLLER_FORMATS)
@settings(
    max_examples=60, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
@given(data=st.data())
def test_file_parse_round_trip(fmt: str, data: st.DataObject) -> None:
    """parse(file(tools)) gives every tool's frame and load back to the file's precision."""
    low, high = SLOTS.get(fmt, (1, 99))
    slots = data.draw(st.lists(st.integers(low, high), min_size=1, max_size=4, unique=True))
    tools = []
    for n, slot in enumerate(slots):
        load = data.draw(loads)
        if fmt == "abb" and load is None:
            load = (1.0, [0.0, 0.0, 0.0])
        position = data.draw(coords)
        position[0] += 3000.0 * n  # tell the tools apart where the file has no number
        mass, cog = load if load else (None, None)
        tools.append(item(f"tool {n}", slot, position, data.draw(unit_quaternions), mass, cog))
    text = controller_file(fmt, tools, FileContext("r", SERVER, table=True)).text
    parsed = parse_controller_file(fmt, text)
    mm, deg, kg = PRECISION[fmt]
    for tool in (t.data for t in tools):
        back = _match(parsed, tool, fmt)
        assert np.abs(back.position_mm - tool.position_mm).max() <= mm
        assert _angle_deg(np.array(tool.quaternion), back.quaternion_wxyz) <= deg
        if kg is not None and fmt != "techman":
            assert (back.mass_kg is None) == (tool.load is None)
        if kg is not None and tool.load is not None:
            assert back.mass_kg is not None
            assert abs(back.mass_kg - tool.load.mass_kg) <= kg
            if back.cog_mm is not None and tool.load.cog_mm is not None:
                assert np.abs(back.cog_mm - tool.load.cog_mm).max() <= max(mm, 1e-6)
    if fmt == "fanuc":
        assert check_ls(text) == []


@pytest.mark.parametrize("table", [False, True])
def test_fanuc_program_passes_the_ls_structure_check(table: bool) -> None:
    tools = golden_tools() if table else golden_tools()[:1]
    text = controller_file("fanuc", tools, FileContext("r", SERVER, table=table)).text
    assert check_ls(text) == []


@pytest.mark.parametrize(
    ("change", "complaint"),
    [
        (lambda t: t.replace("/PROG  TCPUT03", "/PROG  TCP_TOOL_03"), "first line"),
        (lambda t: t.replace("/POS\n", ""), "/POS appears 0 times"),
        (lambda t: t.replace("   2:  ", "   3:  ", 1), "expected 2"),
        (lambda t: re.sub(r"LINE_COUNT\t= \d+", "LINE_COUNT\t= 99", t), "LINE_COUNT 99"),
        (lambda t: t.replace("=(-2.250) ;", "=-2.250 ;"), "not one the checker knows"),
        (lambda t: t.replace("!tcpcal tool data ;", "!tcpcal; tool data ;"), "checker knows"),
        (lambda t: t.replace('"tcpcal UTOOL 3"', '"tcpcal UTOOL 3 of the cell"'), "COMMENT"),
        (lambda t: t.replace("/END\n", "/END"), "does not end"),
        (lambda t: t.replace("tool data", "tool dätä"), "not printable ASCII"),
    ],
)
def test_the_ls_check_catches_what_a_controller_would_refuse(
    change: Callable[[str], str], complaint: str
) -> None:
    text = controller_file("fanuc", golden_tools()[:1], FileContext(None, SERVER)).text
    assert check_ls(text) == []
    errors = check_ls(change(text))
    assert any(complaint in e for e in errors), errors


@pytest.mark.parametrize("name", ["🔥🤖💥", "x" * 60, "a;b\nc\"d'e", "2nd/3rd tool", "tool0", ""])
def test_any_name_gives_valid_identifiers(name: str) -> None:
    tools = [item(name, 2, [0, 0, 100], [1, 0, 0, 0]), item(name, 4, [0, 0, 50], [1, 0, 0, 0])]
    context = FileContext(name, SERVER, table=True)
    rapid = controller_file("abb", tools, context).text
    names = re.findall(r"PERS tooldata (\w+):=", rapid)
    assert len({n.lower() for n in names}) == 2
    assert all(re.fullmatch(r"[A-Za-z][A-Za-z0-9_]{0,31}", n) for n in names), names
    assert re.match(r"MODULE [A-Za-z][A-Za-z0-9_]{0,31}\n", rapid)
    script = controller_file("ur", tools, context).text
    functions = re.findall(r"^def (\w+)\(\):$", script, re.MULTILINE)
    assert len(set(functions)) == 2
    assert all(re.fullmatch(r"tcpcal_[A-Za-z][A-Za-z0-9_]*", f) for f in functions), functions
    krl = controller_file("kuka", tools, context).text
    kuka_names = re.findall(r'^TOOL_NAME\[\d+,\]="([^"]*)"$', krl, re.MULTILINE)
    assert len(kuka_names) == 2
    assert all(0 < len(n) <= 24 for n in kuka_names)
    cnd = controller_file("yaskawa", tools, context).text
    assert all(len(n) <= 16 and "," not in n for n in re.findall(r"^///NAME ?(.*)$", cnd, re.M))
    tp = controller_file("fanuc", tools, context).text
    assert check_ls(tp) == []
    for fmt in CONTROLLER_FORMATS:
        text = controller_file(fmt, tools, context).text
        assert text.isascii(), fmt
        assert len(parse_controller_file(fmt, text)) >= 2, fmt


def test_a_single_tool_the_format_cannot_hold_is_refused() -> None:
    with pytest.raises(InvalidInput) as info:
        controller_file("fanuc", [item("t", None, [0, 0, 1], [1, 0, 0, 0])])
    assert info.value.loc == ("slot",)
    with pytest.raises(InvalidInput) as info:
        controller_file("yaskawa", [item("t", 70, [0, 0, 1], [1, 0, 0, 0])])
    assert info.value.loc == ("slot",)
    with pytest.raises(InvalidInput) as info:
        controller_file("abb", [item("t", None, [0, 0, 1], [1, 0, 0, 0], mass=None)])
    assert info.value.loc == ("load", "mass_kg")


def test_a_table_leaves_out_and_names_what_it_cannot_hold() -> None:
    tools = [
        item("numbered", 2, [0, 0, 1], [1, 0, 0, 0]),
        item("loose", None, [0, 0, 2], [1, 0, 0, 0]),
    ]
    out = controller_file("kuka", tools, FileContext("r", SERVER, table=True))
    assert [t.name for t in out.left_out] == ["loose"]
    assert "; left out: loose: a KUKA tool needs its tool number" in out.text
    assert [p.slot for p in parse_controller_file("kuka", out.text) if p.position_mm[2]] == [2]


def test_empty_and_unrelated_text_is_refused() -> None:
    for fmt in CONTROLLER_FORMATS:
        with pytest.raises(InvalidInput) as info:
            parse_controller_file(fmt, "hello robot\n")
        assert info.value.kind == "invalid-pose", fmt


def test_a_real_controllers_tool_block_reads() -> None:
    """TOOL.CND's block as a DX200 saves it (lukelalondePZ/Fiberdome-GP88-Spindle-Cell) and
    $config.dat's lines as KSS 8 saves them (EdgarMontielG/Cell-3_R10): the numbers read."""
    cnd = "//TOOL 0\n///NAME STANDARD TOOL\n0.000,0.000,0.000,0.0000,90.0000,0.0000\n"
    cnd += "-16.507,-21.039,-136.477\n104.011\n0.000,0.000,0.000\n0.000,0,3\n"
    (tool,) = parse_controller_file("yaskawa", cnd)
    assert (tool.slot, tool.name, tool.mass_kg) == (0, "STANDARD TOOL", 104.011)
    assert _angle_deg(tool.quaternion_wxyz, np.array([np.sqrt(0.5), 0, np.sqrt(0.5), 0])) < 1e-9
    krl = (
        "TOOL_DATA[2]={X 420.390,Y 195.500,Z 259.650,A 0.0,B 0.0,C 0.0}\n"
        'TOOL_NAME[2,]="TOOL 2"\n'
        "LOAD_DATA[2]={M 129.297,CM {X 38.8040,Y -94.4510,Z 136.873,A 89.7770,B -0.721000,"
        "C 0.991000},J {X 5.25000,Y 5.57200,Z 7.65800}}\n"
        "LOAD_DATA[4]={M -1.00000,CM {X 0.0,Y 0.0,Z 0.0,A 0.0,B 0.0,C 0.0},J {X 0.0,Y 0.0,Z 0.0}}\n"
    )
    (tool,) = parse_controller_file("kuka", krl)
    assert (tool.slot, tool.name, tool.mass_kg) == (2, "TOOL 2", 129.297)
    assert tool.cog_mm is not None
    assert tool.cog_mm.tolist() == [38.804, -94.451, 136.873]


@pytest.mark.parametrize(
    ("vendor", "formats"),
    [
        ("KUKA", ("kuka",)),
        ("ABB", ("abb",)),
        ("Fanuc", ("fanuc",)),
        ("Universal Robots", ("ur",)),
        ("UR", ("ur",)),
        ("Yaskawa Motoman", ("yaskawa",)),
        ("Techman Robot", ("techman",)),
        ("Stäubli", CONTROLLER_FORMATS),
        (None, CONTROLLER_FORMATS),
    ],
)
def test_vendor_formats(vendor: str | None, formats: tuple[str, ...]) -> None:
    assert vendor_formats(vendor) == formats
