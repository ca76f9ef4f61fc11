"""Each controller file format against files other people wrote, and against a general rotation
computed here, independently of the code under test (issue 42).

The golden files (test_files.py) were written by the code they check, with rotations (a pure
-90 deg about Y; the symmetric 90, 0, 90) that cannot show two angles swapped. Here:

- every format reads an outside sample: a file written by a controller or by someone else's
  tool (tests/data/controller-files, sources and licences in tests/data/README.md), and the
  rotation it holds is compared with scipy's reading of the same numbers under the vendor's
  documented convention;
- every format writes a tool turned by three unequal, non-zero angles, and the angles (or the
  quaternion, or the rotation vector) in the file must be the ones scipy gives under that
  convention: a writer that swaps any two angles, or composes them in another order, fails.

The conventions, written here from the vendors' documents (not from app.kinematics):
- KUKA (KSS 8 manual, "FRAME"): R = Rz(A) Ry(B) Rx(C), i.e. intrinsic z, y', x'' rotations:
  scipy "ZYX" with (A, B, C).
- FANUC W P R (RoboDK's Fanuc post, H = rotz(R) roty(P) rotx(W)), Yaskawa Rx Ry Rz (the same,
  RoboDK's Motoman post) and Techman RX RY RZ (TechmanRobotInc/tmr_ros2 tm_pose_conversion.h:
  tf's setRPY(rx, ry, rz) = Rz(rz) Ry(ry) Rx(rx)): rotations about the fixed x, y, z axes in
  that order: scipy extrinsic "xyz" with (W, P, R).
- ABB (RAPID manual, "orient"): q1 q2 q3 q4 = w x y z, q1 the scalar part.
- UR (URScript manual, "pose"): rx ry rz a rotation vector in radians, positions in metres.
"""

from __future__ import annotations

import itertools
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from app.vendors.files import FileContext, FileTool
from app.vendors.registry import controller_file, parse_controller_file, parse_controller_text
from tests.vendors.tools import tool_data

DATA = Path(__file__).parents[1] / "data" / "controller-files"
#: Three unequal, non-zero angles (deg): any two swapped, or another order, is another rotation.
ANGLES = (35.0, -20.0, 10.0)
POSITION = [10.0, -20.0, 150.0]


def kuka(a: float, b: float, c: float) -> Rotation:
    """KSS FRAME A, B, C: R = Rz(A) Ry(B) Rx(C)."""
    return Rotation.from_euler("ZYX", [a, b, c], degrees=True)


def fixed_xyz(w: float, p: float, r: float) -> Rotation:
    """FANUC W, P, R / Yaskawa Rx, Ry, Rz / Techman RX, RY, RZ: R = Rz(R) Ry(P) Rx(W)."""
    return Rotation.from_euler("xyz", [w, p, r], degrees=True)


def wxyz(rotation: Rotation) -> np.ndarray:
    return np.asarray(rotation.as_quat(scalar_first=True))


def angle_deg(quaternion_wxyz: np.ndarray, rotation: Rotation) -> float:
    read = Rotation.from_quat(quaternion_wxyz, scalar_first=True)
    return float(np.degrees((read.inv() * rotation).magnitude()))


def tool_file(fmt: str, rotation: Rotation, slot: int | None = 3) -> str:
    data = tool_data(slot, "probe", np.array(POSITION), wxyz(rotation), 2.5, np.array([0, 0, 80.0]))
    return controller_file(fmt, [FileTool(data)], FileContext()).text


def numbers(text: str) -> list[float]:
    return [float(n) for n in re.findall(r"[-+]?(?:\d+\.?\d*|\.\d+)", text)]


def test_the_angles_can_tell_a_swap() -> None:
    """Guard: under both conventions every other order of ANGLES is a rotation at least
    10 deg away, so the known-value tests below fail on any swapped pair."""
    for make in (kuka, fixed_xyz):
        reference = make(*ANGLES)
        for order in itertools.permutations(ANGLES):
            if order != ANGLES:
                assert np.degrees((make(*order).inv() * reference).magnitude()) > 10
        assert np.degrees((kuka(*ANGLES).inv() * fixed_xyz(*ANGLES)).magnitude()) > 10


# --- a general rotation, written ---------------------------------------------------------------


def test_kuka_writes_a_b_c_of_rz_ry_rx() -> None:
    text = tool_file("kuka", kuka(*ANGLES))
    assert "TOOL_DATA[3]={X 10.0,Y -20.0,Z 150.0,A 35.0,B -20.0,C 10.0}\n" in text


def test_fanuc_writes_w_p_r_about_fixed_x_y_z() -> None:
    text = tool_file("fanuc", fixed_xyz(*ANGLES))
    elements = re.findall(r"PR\[100,(\d)\]=\(?(-?[\d.]+)\)? ;", text)
    assert [(int(i), float(v)) for i, v in elements] == [
        (1, 10.0), (2, -20.0), (3, 150.0), (4, 35.0), (5, -20.0), (6, 10.0),
    ]  # fmt: skip


def test_yaskawa_writes_rx_ry_rz_about_fixed_x_y_z() -> None:
    text = tool_file("yaskawa", fixed_xyz(*ANGLES))
    assert text.splitlines()[2] == "10.000,-20.000,150.000,35.0000,-20.0000,10.0000"


def test_techman_writes_rx_ry_rz_about_fixed_x_y_z() -> None:
    text = tool_file("techman", fixed_xyz(*ANGLES), slot=None)
    assert "\nChangeTCP({10.0,-20.0,150.0,35.0,-20.0,10.0},2.5)\n" in text


def test_abb_writes_q1_to_q4_scalar_first() -> None:
    rotation = kuka(*ANGLES)
    text = tool_file("abb", rotation, slot=None)
    match = re.search(r"probe:=\[TRUE,\[\[([^\]]*)\],\[([^\]]*)\]\]", text)
    assert match is not None, text
    assert numbers(match.group(1)) == POSITION
    q = np.array(numbers(match.group(2)))
    assert np.all(np.abs(q) > 0.05), "a general rotation: no component near zero"
    np.testing.assert_allclose(q, wxyz(rotation), atol=1e-9)


def test_ur_writes_a_rotation_vector_in_radians() -> None:
    rotation = kuka(*ANGLES)
    text = tool_file("ur", rotation, slot=None)
    match = re.search(r"set_tcp\(p\[([^\]]*)\]\)", text)
    assert match is not None, text
    pose = numbers(match.group(1))
    np.testing.assert_allclose(pose[:3], np.array(POSITION) / 1000.0, atol=1e-12)
    np.testing.assert_allclose(pose[3:], rotation.as_rotvec(), atol=1e-9)


# --- outside samples, read ---------------------------------------------------------------------


def test_kuka_reads_a_controllers_config_dat() -> None:
    """KSS 8 $config.dat (EdgarMontielG/Cell-3_R10): the three tools the controller has."""
    tools = {
        t.slot: t
        for t in parse_controller_file("kuka", (DATA / "kuka_config_tools.dat").read_text())
    }
    assert list(tools) == list(range(1, 17))
    assert (tools[1].name, tools[1].mass_kg) == ("TOOL 1", 210.0)
    np.testing.assert_allclose(tools[1].position_mm, [0.0, 0.0, 380.79])
    assert angle_deg(tools[1].quaternion_wxyz, kuka(-90, -90, -90)) < 1e-6
    assert angle_deg(tools[3].quaternion_wxyz, kuka(-180, 0, 0)) < 1e-6
    assert tools[4].mass_kg is None  # M -1: no load data
    assert tools[2].cog_mm is not None
    np.testing.assert_allclose(tools[2].cog_mm, [38.804, -94.451, 136.873])


def test_abb_reads_a_rapid_module_with_tools_and_work_objects() -> None:
    """A RAPID module of a robot cell (DanielPaans/SMR1 CalibData.mod): the five tooldata,
    not the wobjdata; q1 is the scalar part."""
    tools = {
        t.name: t for t in parse_controller_file("abb", (DATA / "abb_CalibData.mod").read_text())
    }
    assert list(tools) == [
        "Gripper", "Gripper_closed", "Gripper_Sleeve", "Gripper_Sleeve_Horizontal",
        "Gripper_closed_V",
    ]  # fmt: skip
    horizontal = tools["Gripper_Sleeve_Horizontal"]
    np.testing.assert_allclose(horizontal.position_mm, [0.0, -21.0, 1700.0])
    assert horizontal.mass_kg == 25.0
    assert horizontal.cog_mm is not None
    assert horizontal.cog_mm.tolist() == [0.0, 0.0, 800.0]
    turned = Rotation.from_quat([0.99998, 0.00625, 0, 0], scalar_first=True)
    assert angle_deg(horizontal.quaternion_wxyz, turned) < 1e-6
    assert 0.7 < np.degrees(turned.magnitude()) < 0.75  # 0.716 deg about x, not 180 deg


def _fanuc_positions(text: str) -> dict[int, list[float]]:
    """The /POS section's X Y Z W P R of each P[n], read here (not by app code)."""
    found = {}
    for n, body in re.findall(r"^P\[(\d+)\]\{(.*?)\};", text, re.M | re.S):
        values = dict(re.findall(r"([XYZWPR]) =\s*(-?[\d.]+)", body))
        found[int(n)] = [float(values[k]) for k in "XYZWPR"]
    return found


def test_fanuc_writes_and_reads_the_orientation_of_an_outside_ls_position() -> None:
    """An LS program with Cartesian positions (Surfacerobot/crs_application_sizen): its P[1]
    (W 4.26, P 13.56, R 12.08: three unequal angles), as a tool frame, is written with the
    same W P R and read back to the same rotation."""
    position = _fanuc_positions((DATA / "fanuc_surface_cartesian.ls").read_text())
    assert sorted(position) == [1, 4]
    x, y, z, w, p, r = position[1]
    rotation = fixed_xyz(w, p, r)
    data = tool_data(5, "p1", np.array([x, y, z]), wxyz(rotation))
    text = controller_file("fanuc", [FileTool(data)], FileContext()).text
    elements = dict(re.findall(r"PR\[100,(\d)\]=\(?(-?[\d.]+)\)? ;", text))
    assert [float(elements[str(i)]) for i in range(4, 7)] == [4.262, 13.559, 12.083]
    (back,) = parse_controller_file("fanuc", text)
    assert angle_deg(back.quaternion_wxyz, rotation) < 2e-3
    line = f"X {x} Y {y} Z {z} W {w} P {p} R {r}"
    _, quaternion = parse_controller_text("fanuc", line)
    assert angle_deg(quaternion, rotation) < 1e-6
    _, other = parse_controller_text("fanuc", f"X {x} Y {y} Z {z} W {r} P {p} R {w}")
    assert angle_deg(other, rotation) > 1  # the sample's angles can tell W from R


def test_yaskawa_reads_a_yrc1000_tool_file_and_writes_its_block_alike() -> None:
    """YRC1000 TOOL.CND (lukelalondePZ/Komatsu-Press-Demo, ///CRC lines and loads): read; and
    the block written for SUCTION1's values has the controller's pose, centre of gravity and
    mass lines character for character."""
    text = (DATA / "yaskawa_TOOL_yrc1000.CND").read_text()
    tools = {t.slot: t for t in parse_controller_file("yaskawa", text)}
    assert [tools[n].name for n in (2, 3, 4)] == ["POINTER TCP", "SUCTION1", "SUCTION2"]
    suction = tools[3]
    assert angle_deg(suction.quaternion_wxyz, fixed_xyz(0, -90, 0)) < 1e-6
    assert angle_deg(tools[4].quaternion_wxyz, fixed_xyz(-90, 0, 0)) < 1e-6
    assert suction.mass_kg == 3.586
    data = tool_data(3, "SUCTION1", suction.position_mm, suction.quaternion_wxyz,
                    suction.mass_kg, suction.cog_mm)  # fmt: skip
    ours = controller_file("yaskawa", [FileTool(data)], FileContext()).text.splitlines()
    theirs = text.splitlines()[10:14]
    assert ours[1:5] == [theirs[0], *theirs[1:]]  # ///NAME, pose, cog, mass


def test_ur_reads_a_polyscope_program_and_its_waypoint_rotation() -> None:
    """A program PolyScope saved (portal301/ur-python-tutorial example_pristine.script): the
    TCP and set_target_payload's 0.29 kg read; a waypoint's pose (a rotation vector with three
    unequal components) reads as scipy's rotation vector."""
    text = (DATA / "ur_example_pristine.script").read_text()
    (program,) = parse_controller_file("ur", text)
    assert program.name == "tet"
    assert program.mass_kg == 0.29
    np.testing.assert_allclose(program.position_mm, [0, 0, 0])
    pose = re.search(r"_2_p=(p\[[^\]]*\])", text)
    assert pose is not None
    values = numbers(pose.group(1))
    position, quaternion = parse_controller_text("ur", pose.group(1))
    np.testing.assert_allclose(position, np.array(values[:3]) * 1000.0)
    assert angle_deg(quaternion, Rotation.from_rotvec(values[3:])) < 1e-9


@pytest.mark.parametrize(
    "line",
    [
        # The TMflow manual's Listen Node example (I848, sec. "ScriptExit", as public notes
        # transcribe it): a TCP chosen by name holds no values.
        'ChangeTCP("NOTOOL")',
        'ChangeTCP("T1")',
    ],
)
def test_techman_named_tcps_of_the_manual_are_not_values(line: str) -> None:
    with pytest.raises(Exception, match="ChangeTCP"):
        parse_controller_text("techman", line)
