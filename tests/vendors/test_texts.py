"""Controller texts: known outputs, vendor examples, export -> parse round trips, refusals."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from app.errors import InvalidInput
from app.vendors.abb.text import rapid_identifier
from app.vendors.registry import export_tool, parse_controller_text
from app.vendors.tool import ToolData
from app.words import CONTROLLER_FORMATS
from tests.vendors.tools import tool_data

H = math.sqrt(0.5)


def tool(
    position: list[float] | None = None,
    quaternion: list[float] | None = None,
    *,
    slot: int | None = 3,
    name: str = "gripper",
    mass: float | None = 1.5,
    cog: list[float] | None = None,
) -> ToolData:
    return tool_data(
        slot,
        name,
        position if position is not None else [0.0, 0.0, 150.0],
        quaternion if quaternion is not None else [1.0, 0, 0, 0],
        mass,
        cog if cog is not None else [0.0, 0.0, 60.0],
    )


# --- known texts -------------------------------------------------------------------------------


def test_kuka_text_as_in_api_doc() -> None:
    """API.md's example, to the character: $TOOL_DATA[3]={X 0.0,Y 0.0,Z 150.0,A 0.0,B 0.0,C 0.0}."""
    out = export_tool("kuka", tool())
    assert out.text == ("$TOOL_DATA[3]={X 0.0,Y 0.0,Z 150.0,A 0.0,B 0.0,C 0.0}")
    assert out.values == {"slot": 3, "X": 0.0, "Y": 0.0, "Z": 150.0, "A": 0.0, "B": 0.0, "C": 0.0}


def test_kuka_tool_z_along_flange_x() -> None:
    """Tool turned -90 deg about flange Y (quaternion [cos45, 0, -sin45, 0]): B = -90 in
    KUKA's Rz(A) Ry(B) Rx(C) (independent: the rotation is a pure Ry)."""
    out = export_tool("kuka", tool([10, 20, 30], [H, 0, -H, 0]))
    assert out.values["B"] == pytest.approx(-90.0)
    assert out.values["A"] == pytest.approx(0.0, abs=1e-7)
    assert out.values["C"] == pytest.approx(0.0, abs=1e-7)


def test_abb_text_and_load() -> None:
    """ABB tooldata layout of the RAPID reference manual; quaternion q1 is the scalar."""
    out = export_tool(
        "abb", tool([97.4, 0, 223.1], [0.92388, 0, 0.382683, 0], cog=[23, 0, 75], mass=5)
    )
    assert out.text.startswith("PERS tooldata gripper:=[TRUE,[[97.4,0.0,223.1],[")
    assert out.text.endswith("],[5.0,[23.0,0.0,75.0],[1,0,0,0],0,0,0]];")
    assert out.values["mass_kg"] == 5.0
    assert out.values["cog_mm"] == [23.0, 0.0, 75.0]
    assert out.values["q1"] == pytest.approx(0.92388, abs=1e-5)


def test_abb_parses_manual_example() -> None:
    """The RAPID reference manual's tooldata example parses: TCP (97.4, 0, 223.1),
    tool X and Z turned 45 deg about wrist Y."""
    text = (
        "PERS tooldata gripper := [ TRUE, [[97.4, 0, 223.1], [0.924, 0, 0.383 ,0]],\n"
        "[5, [23, 0, 75], [1, 0, 0, 0], 0, 0, 0]];"
    )
    position, quaternion = parse_controller_text("abb", text)
    assert_allclose(position, [97.4, 0, 223.1])
    angle = Rotation.from_quat(np.roll(quaternion, -1)).as_rotvec()
    assert_allclose(np.degrees(angle), [0, 45, 0], atol=0.05)


def test_ur_text_metres_radians() -> None:
    """UR: set_tcp(p[x,y,z,rx,ry,rz]) in m/rad; 90 deg about Z is rz = pi/2."""
    out = export_tool("ur", tool([0, 0, 150], [H, 0, 0, H]))
    first = out.text.splitlines()[0]
    assert first.startswith("set_tcp(p[0.0,0.0,0.15,")
    assert out.values["pose"] == pytest.approx([0, 0, 0.15, 0, 0, math.pi / 2])
    assert "set_payload(1.5, [0.0,0.0,0.06])" in out.text


@pytest.mark.parametrize(
    ("fmt", "start"),
    [
        (
            "fanuc",
            "UTOOL[3]: X 0.0 Y 0.0 Z 150.0 W 90.0 P 0.0 R 0.0",
        ),
        (
            "yaskawa",
            "TOOL[3]: X 0.0 Y 0.0 Z 150.0 Rx 90.0 Ry 0.0 Rz 0.0 W 1.5",
        ),
        (
            "techman",
            "ChangeTCP({0.0,0.0,150.0,90.0,0.0,0.0},1.5)",
        ),
    ],
)
def test_fixed_axis_texts(fmt: str, start: str) -> None:
    """Fanuc/Yaskawa/Techman: 90 deg about flange X is W (Rx, RX) = 90."""
    out = export_tool(fmt, tool([0, 0, 150], [H, H, 0, 0]))
    assert out.text.startswith(start), out.text


def test_fanuc_parses_tp_position_register_form() -> None:
    """A TP program loads a tool frame through a position register, one element at a time
    (ros-industrial-attic/robodk_postprocessors Fanuc_R30iA.py ``setTool``); a negative
    constant may be stored in parentheses and the register may carry a comment."""
    text = (
        "PR[95,1]=10.000 ;\nPR[95,2]=(-20.5) ;\nPR[95,3]=150.000 ;\n"
        "PR[95,4]=90.000 ;\nPR[95,5]=0.000 ;\nPR[95,6]=0.000 ;\n"
        "PR[96,1]=999 ;\nUTOOL[1]=PR[95:tool] ;\nUTOOL_NUM=1 ;"
    )
    position, quaternion = parse_controller_text("fanuc", text)
    assert_allclose(position, [10.0, -20.5, 150.0])
    assert _angle_deg(np.array([H, H, 0, 0]), quaternion) < 1e-9


def test_fanuc_tp_form_needs_all_six_elements() -> None:
    text = "PR[95,1]=10 ;\nPR[95,2]=0 ;\nPR[95,3]=150 ;\nUTOOL[1]=PR[95] ;"
    with pytest.raises(InvalidInput) as info:
        parse_controller_text("fanuc", text)
    assert info.value.kind == "invalid-pose"


@pytest.mark.parametrize(
    "text",
    [
        # TM's ROS driver, TmCommand::change_tcp (RAMLABNL/tmr_ros2 tm_driver/src/tm_command.cpp)
        "ChangeTCP(0,0,150,90,0,0)",
        "ChangeTCP(0,0,150,90,0,0,1.5)",
        "ChangeTCP(0,0,150,90,0,0,1.5,0.01,0.01,0.01,0,0,60,0,0,0)",
        # the (float[], float) syntax, as we write it
        "ChangeTCP({0, 0, 150, 90, 0, 0}, 1.5)",
    ],
)
def test_techman_parses_array_and_flat_forms(text: str) -> None:
    """ChangeTCP takes X, Y, Z, RX, RY, RZ first, in braces or flat, then mass/inertia."""
    position, quaternion = parse_controller_text("techman", text)
    assert_allclose(position, [0.0, 0.0, 150.0])
    assert _angle_deg(np.array([H, H, 0, 0]), quaternion) < 1e-9


@pytest.mark.parametrize(
    "text", ['ChangeTCP("NOTOOL")', "ChangeTCP({0,0,150,90,0,0,1.5})", "ChangeTCP(0,0,150,90,0})"]
)
def test_techman_refuses_tool_names_and_bad_arrays(text: str) -> None:
    with pytest.raises(InvalidInput) as info:
        parse_controller_text("techman", text)
    assert info.value.kind == "invalid-pose"


def test_values_are_plain_json() -> None:
    import json

    for fmt in CONTROLLER_FORMATS:
        out = export_tool(fmt, tool([1.5, -2.25, 100], [0.5, 0.5, 0.5, 0.5]))
        assert json.loads(json.dumps(out.values)) == out.values
        assert out.format == fmt


def test_names_cannot_inject_lines() -> None:
    """A tool name is user input: it never starts a new program line."""
    for fmt in CONTROLLER_FORMATS:
        out = export_tool(fmt, tool(name="x\nmovej([0,0,0,0,0,0])"))
        lines = out.text.splitlines()
        assert not any(line.lstrip().startswith("movej") for line in lines), out.text
        assert len(lines) == (2 if fmt == "ur" else 1)


@pytest.mark.parametrize(
    ("name", "ident"),
    [
        ("gripper", "gripper"),
        ("Weld gun #2", "Weld_gun_2"),
        ("2nd tool", "t2nd_tool"),
        ("", "t"),
        ("tool0", "tool0_1"),
        ("PERS", "PERS_1"),
        ("a" * 40, "a" * 32),
        ("Düse", "Duse"),
        ("🔥" * 60, "t"),
        ("🔥 torch", "torch"),
    ],
)
def test_rapid_identifier(name: str, ident: str) -> None:
    assert rapid_identifier(name) == ident


# --- round trips ---------------------------------------------------------------------------------

quaternions = st.lists(st.floats(-1, 1, allow_nan=False), min_size=4, max_size=4).filter(
    lambda q: np.linalg.norm(q) > 0.1
)
coords = st.floats(-1000, 1000, allow_nan=False)


def _angle_deg(q1: np.ndarray, q2: np.ndarray) -> float:
    r1 = Rotation.from_quat(np.roll(q1, -1))
    r2 = Rotation.from_quat(np.roll(q2, -1))
    return float(np.degrees((r1.inv() * r2).magnitude()))


@pytest.mark.parametrize("fmt", CONTROLLER_FORMATS)
@settings(
    max_examples=150, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
@given(x=coords, y=coords, z=coords, q=quaternions)
def test_export_parse_round_trip(fmt: str, x: float, y: float, z: float, q: list[float]) -> None:
    """export -> parse gives the same TCP within 1e-6 mm and 1e-6 deg."""
    unit = np.asarray(q) / np.linalg.norm(q)
    out = export_tool(fmt, tool([x, y, z], unit.tolist()))
    position, quaternion = parse_controller_text(fmt, out.text)
    assert np.linalg.norm(position - [x, y, z]) < 1e-6
    assert _angle_deg(unit, quaternion) < 1e-6


@pytest.mark.parametrize("fmt", ["kuka", "fanuc", "yaskawa", "techman"])
@pytest.mark.parametrize("quaternion", [[H, 0, H, 0], [H, 0, -H, 0], [0.5, 0.5, 0.5, 0.5]])
def test_export_parse_gimbal_lock(fmt: str, quaternion: list[float]) -> None:
    """Tools turned +-90 deg about flange Y sit at gimbal lock of both Euler conventions."""
    out = export_tool(fmt, tool([1, 2, 3], quaternion))
    _, parsed = parse_controller_text(fmt, out.text)
    assert _angle_deg(np.array(quaternion), parsed) < 1e-6


# --- refusals -----------------------------------------------------------------------------------


@pytest.mark.parametrize("mass", [None, 0.0, -1.0, float("nan")])
def test_abb_refuses_missing_or_zero_mass(mass: float | None) -> None:
    with pytest.raises(InvalidInput) as info:
        export_tool("abb", tool(mass=mass))
    assert info.value.kind == "missing-load"
    assert info.value.loc == ("load", "mass_kg")
    has = "none" if mass is None or math.isnan(mass) else f"{mass:g} kg"
    assert f"tool 'gripper' has {has}. ABB controllers refuse" in info.value.detail


def test_abb_refuses_missing_cog() -> None:
    t = tool_data(1, "g", np.zeros(3), [1.0, 0, 0, 0], mass=2.0)
    with pytest.raises(InvalidInput) as info:
        export_tool("abb", t)
    assert info.value.kind == "missing-load"
    assert info.value.loc == ("load", "cog_mm")


def test_kuka_refuses_missing_slot() -> None:
    with pytest.raises(InvalidInput) as info:
        export_tool("kuka", tool(slot=None))
    assert info.value.kind == "invalid-options"
    assert info.value.loc == ("slot",)
    # The sentence reaches the console's KUKA card and the API's 422: in words, not "got None".
    assert info.value.detail.endswith(
        "(slot 1..16) for $TOOL_DATA[n]; it has none: set the tool's slot"
    )
    with pytest.raises(InvalidInput) as info:
        export_tool("kuka", tool(slot=17))
    assert info.value.detail.endswith("its slot 17 is not one: set the tool's slot")


def _refusal(fmt: str, data: ToolData) -> str | None:
    """What exporting `data` as `fmt` is refused with, or None when it is not."""
    try:
        export_tool(fmt, data)
    except InvalidInput as exc:
        return exc.detail
    return None


def test_a_refusal_never_prints_none() -> None:
    """A tool without slot, load or centre of gravity: whatever a format refuses, it says so in
    words (the console's KUKA card read "got None", the ABB one "has None")."""
    bare = tool_data(None, "bare", np.zeros(3), [1.0, 0, 0, 0])
    refusals = {fmt: _refusal(fmt, bare) for fmt in CONTROLLER_FORMATS}
    said = {fmt: detail for fmt, detail in refusals.items() if detail is not None}
    assert set(said) == {"kuka", "abb"}, refusals
    assert [detail for detail in said.values() if "None" in detail] == []


def test_refuses_unknown_controller_format() -> None:
    with pytest.raises(InvalidInput) as info:
        export_tool("staubli", tool())
    assert info.value.kind == "unknown-format"
    with pytest.raises(InvalidInput):
        parse_controller_text("staubli", "")


def test_refuses_bad_quaternion_and_sentinel() -> None:
    with pytest.raises(InvalidInput) as info:
        export_tool("ur", tool(quaternion=[2, 0, 0, 0]))
    assert info.value.kind == "invalid-rotation"
    assert info.value.loc == ("tcp", "quaternion")
    with pytest.raises(InvalidInput) as info:
        export_tool("ur", tool(position=[-3.7e28, 0, 0]))
    assert info.value.kind == "out-of-range"


@pytest.mark.parametrize("fmt", CONTROLLER_FORMATS)
def test_parse_refuses_garbage(fmt: str) -> None:
    with pytest.raises(InvalidInput) as info:
        parse_controller_text(fmt, "hello robot")
    assert info.value.kind == "invalid-pose"
    assert info.value.loc == ("text",)


@pytest.mark.parametrize("fmt", ["fanuc", "yaskawa"])
def test_json_comments_hold_no_emoji(fmt: str) -> None:
    """Issue 27: an emoji in the tool's name went into the Fanuc and Yaskawa comments."""
    out = export_tool(fmt, tool(name="🔥 Düse torch"))
    assert out.text.isascii()
    assert out.text.endswith("Duse torch")
