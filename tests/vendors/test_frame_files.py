"""A frame (a base, a fixed tool) in each maker's words and as the file its controller loads
(issue 47): text and file round trips over random frames (hypothesis), each format held
against an outside sample (tests/data/controller-files, sources and licences in
tests/data/README.md), and a frame turned by three unequal angles written with the angles
scipy gives under the vendor's convention (the conventions written in
tests/vendors/test_outside_samples.py, not taken from app code)."""

from __future__ import annotations

import re
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from app.errors import InvalidInput
from app.vendors.files import FileContext, Provenance
from app.vendors.frame import FileFrame, FrameData
from app.vendors.registry import export_frame, frame_file, parse_frame_file, parse_frame_text
from app.words import CONTROLLER_FORMATS
from tests.vendors.test_outside_samples import ANGLES, angle_deg, fixed_xyz, kuka, wxyz

DATA = Path(__file__).parents[1] / "data" / "controller-files"
WHEN = datetime(2026, 12, 2, 4, 30, tzinfo=UTC)
#: What each frame file's printed precision gives back (mm, deg): the texts print 6 decimals
#: of mm and 7 of deg everywhere; the TP program and UFRAME.CND the controller's 3 (and 4).
FILE_PRECISION = {
    "kuka": (1e-6, 1e-6),
    "abb": (1e-6, 1e-6),
    "fanuc": (1e-3, 2e-3),
    "ur": (1e-9, 1e-9),
    "yaskawa": (1e-3, 2e-4),
    "techman": (1e-6, 1e-6),
}
#: The formats whose controllers hold a stationary TCP (Techman's has none).
HOLD_FIXED = ("kuka", "abb", "fanuc", "ur", "yaskawa")
#: A frame number each numbered format takes.
SLOT = 2

coordinate = st.floats(min_value=-3000.0, max_value=3000.0, allow_nan=False)
unit = st.floats(min_value=-1.0, max_value=1.0, allow_nan=False)
quaternions = (
    st.tuples(unit, unit, unit, unit)
    .filter(lambda q: float(np.linalg.norm(q)) > 0.1)
    .map(lambda q: tuple(float(v) for v in np.asarray(q) / np.linalg.norm(q)))
)


def frame(
    position: tuple[float, float, float],
    quaternion: tuple[float, ...],
    fixed: bool = False,
    slot: int | None = SLOT,
    name: str = "fixture A",
    symbol: str | None = None,
) -> FrameData:
    return FrameData(position, quaternion, fixed, slot, name, symbol)  # type: ignore[arg-type]


def close(fmt: str, position: np.ndarray, quaternion: np.ndarray, want: FrameData) -> None:
    mm, deg = FILE_PRECISION[fmt]
    assert np.max(np.abs(position - np.asarray(want.position_mm))) < mm
    assert angle_deg(quaternion, Rotation.from_quat(want.quaternion, scalar_first=True)) < deg


@pytest.mark.parametrize(
    ("fmt", "fixed"),
    [
        (fmt, fixed)
        for fmt in CONTROLLER_FORMATS
        for fixed in (False, True)
        if fmt in HOLD_FIXED or not fixed
    ],
)
@settings(
    max_examples=60, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
@given(position=st.tuples(coordinate, coordinate, coordinate), quaternion=quaternions)
def test_a_frames_text_reads_back_within_1e6(
    fmt: str, fixed: bool, position: tuple[float, float, float], quaternion: tuple[float, ...]
) -> None:
    data = frame(position, quaternion, fixed)
    export = export_frame(fmt, data)
    assert export.format == fmt
    back_position, back_quaternion = parse_frame_text(fmt, export.text)
    assert np.max(np.abs(back_position - np.asarray(position))) < 1e-6
    assert angle_deg(back_quaternion, Rotation.from_quat(quaternion, scalar_first=True)) < 1e-6


@pytest.mark.parametrize("fmt", CONTROLLER_FORMATS)
@settings(
    max_examples=30, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
@given(
    poses=st.lists(
        st.tuples(st.tuples(coordinate, coordinate, coordinate), quaternions, st.booleans()),
        min_size=1,
        max_size=3,
    )
)
def test_a_robots_frame_table_reads_back_each_frame(
    fmt: str, poses: list[tuple[tuple[float, float, float], tuple[float, ...], bool]]
) -> None:
    frames = [
        frame(
            p,
            q,
            fixed and fmt in HOLD_FIXED,
            slot=n + 1,
            name=f"frame {n + 1}",
            symbol=f"T_ROB1/user/wf{n + 1}",
        )
        for n, (p, q, fixed) in enumerate(poses)
    ]
    origin = Provenance(3, WHEN, "alice", "three_point")
    context = FileContext(robot="cell 7 robot", server_url="https://tcpcal.example", table=True)
    written = frame_file(fmt, [FileFrame(f, origin) for f in frames], context)
    assert written.left_out == ()
    read = parse_frame_file(fmt, written.text)
    assert len(read) == len(frames)
    for want, got in zip(frames, read, strict=True):
        close(fmt, got.position_mm, got.quaternion_wxyz, want)
        if got.slot is not None:
            assert got.slot == want.slot
        if got.fixed_tool is not None:
            assert got.fixed_tool == want.fixed_tool


@pytest.mark.parametrize("fmt", CONTROLLER_FORMATS)
def test_one_frames_file_says_what_it_holds_and_reads_back(fmt: str) -> None:
    data = frame((100.0, -250.5, 30.0), tuple(wxyz(kuka(*ANGLES))), symbol="T_ROB1/user/wFix")
    origin = Provenance(4, WHEN, "bob", "three_point", "https://tcpcal.example/ui/frames/f1")
    written = frame_file(fmt, [FileFrame(data, origin)], FileContext())
    (back,) = parse_frame_file(fmt, written.text)
    close(fmt, back.position_mm, back.quaternion_wxyz, data)
    if fmt != "yaskawa":  # a condition file has no comment: no header
        assert "frame fixture A" in written.text
        assert "version 4" in written.text


@pytest.mark.parametrize("fmt", ["kuka", "fanuc", "yaskawa"])
def test_a_numbered_format_refuses_a_frame_without_its_number(fmt: str) -> None:
    data = frame((0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0), slot=None)
    with pytest.raises(InvalidInput) as err:
        export_frame(fmt, data)
    assert err.value.loc == ("slot",)
    assert "set the frame's slot" in err.value.detail
    table = frame_file(fmt, [FileFrame(data)], FileContext(robot="r", table=True))
    assert [item.name for item in table.left_out] == ["fixture A"]


# --- KUKA: the base table of a KSS 8 controller's $config.dat --------------------------------


def test_kuka_reads_the_base_table_of_a_controllers_config_dat() -> None:
    text = (DATA / "kuka_config_bases.dat").read_text()
    bases = {b.slot or 0: b for b in parse_frame_file("kuka", text)}
    assert sorted(bases) == list(range(1, 33))
    nut = bases[3]
    assert nut.name == "NUT WELDER"
    assert nut.fixed_tool is False
    assert np.allclose(nut.position_mm, [21.84, 1866.09, 658.47], atol=1e-9)
    assert angle_deg(nut.quaternion_wxyz, kuka(90.0, 0.0, 180.0)) < 1e-9
    assert angle_deg(bases[1].quaternion_wxyz, kuka(-90.0, 0.0, 0.0)) < 1e-9
    assert bases[5].name is None
    assert bases[5].fixed_tool is None


def test_kuka_writes_the_name_and_type_lines_of_the_sample_byte_for_byte() -> None:
    """Bases 1-4 read from the sample and written again: BASE_NAME and BASE_TYPE lines equal
    the controller's; BASE_DATA holds the same numbers (tcpcal prints the fewest digits that
    keep 1e-6, the controller six significant ones: "-175.000" is "-175.0")."""
    text = (DATA / "kuka_config_bases.dat").read_text()
    sample = set(text.splitlines())
    parsed = [b for b in parse_frame_file("kuka", text) if b.slot is not None and b.slot <= 4]
    frames = [
        FileFrame(
            FrameData(tuple(b.position_mm), tuple(b.quaternion_wxyz), False, b.slot, b.name or "")
        )
        for b in parsed
    ]
    written = frame_file("kuka", frames, FileContext(robot="cell 3", table=True)).text
    lines = [line for line in written.splitlines() if not line.startswith(";")]
    names_types = [line for line in lines if not line.startswith("BASE_DATA")]
    assert len(names_types) == 8
    assert set(names_types) <= sample
    for line in (line for line in lines if line.startswith("BASE_DATA")):
        slot = int(re.match(r"BASE_DATA\[(\d+)\]", line).group(1))  # type: ignore[union-attr]
        theirs = next(s for s in sample if s.startswith(f"BASE_DATA[{slot}]="))
        assert _numbers(line) == pytest.approx(_numbers(theirs), abs=1e-9)


def test_kuka_writes_a_fixed_tool_as_an_external_tcp() -> None:
    data = frame((1200.0, 0.0, 800.0), (1.0, 0.0, 0.0, 0.0), fixed=True, slot=7, name="nozzle")
    written = frame_file("kuka", [FileFrame(data)], FileContext()).text
    assert "BASE_TYPE[7]=#TCP" in written.splitlines()
    assert export_frame("kuka", data).values["type"] == "#TCP"
    (back,) = parse_frame_file("kuka", written)
    assert back.fixed_tool is True
    assert back.name == "nozzle"


def _numbers(text: str) -> list[float]:
    return [float(n) for n in re.findall(r"[-+]?\d+\.?\d*", text.split("=", 1)[1])]


# --- ABB: the work objects of a robot cell's RAPID module ------------------------------------


def test_abb_reads_the_work_objects_of_an_outside_module_and_no_held_tool() -> None:
    """CalibData.mod sets its work objects' oframe (uframe the identity): the object the robot
    works in is uframe * oframe. Its five tooldata are held (robhold TRUE): no frame."""
    found = {f.name: f for f in parse_frame_file("abb", (DATA / "abb_CalibData.mod").read_text())}
    assert set(found) == {"Sleeves", "Mandrell", "Laser"}
    sleeves = found["Sleeves"]
    assert np.allclose(sleeves.position_mm, [992.91, -2164.96, 1565.0], atol=1e-9)
    assert (
        angle_deg(sleeves.quaternion_wxyz, Rotation.from_quat([0, 0, 1, 0], scalar_first=True))
        < 1e-9
    )
    mandrell = Rotation.from_quat([0.27444, 0.27271, 0.64992, 0.65415], scalar_first=True)
    assert angle_deg(found["Mandrell"].quaternion_wxyz, mandrell) < 1e-9
    assert all(f.fixed_tool is False for f in found.values())


def test_abb_reads_a_work_object_whose_uframe_and_oframe_are_both_set() -> None:
    user = Rotation.from_euler("z", 90, degrees=True)
    line = (
        'PERS wobjdata w:=[FALSE,TRUE,"",[[100,0,0],'
        f"[{','.join(str(v) for v in wxyz(user))}]],[[10,0,0],[1,0,0,0]]];"
    )
    position, quaternion = parse_frame_text("abb", line)
    assert np.allclose(position, [100.0, 10.0, 0.0], atol=1e-9)  # oframe's x turned into y
    assert angle_deg(quaternion, user) < 1e-9


def test_abb_writes_a_base_as_uframe_and_a_fixed_tool_as_a_stationary_tooldata() -> None:
    base = frame((1457.0, -1157.0, -235.0), (1.0, 0.0, 0.0, 0.0), name="Laser")
    assert export_frame("abb", base).text == (
        'PERS wobjdata Laser:=[FALSE,TRUE,"",[[1457.0,-1157.0,-235.0],[1.0,0.0,0.0,0.0]],'
        "[[0,0,0],[1,0,0,0]]];"
    )
    tool = frame((900.0, 0.0, 400.0), (1.0, 0.0, 0.0, 0.0), fixed=True, symbol="T_ROB1/m/tGlue")
    text = export_frame("abb", tool).text
    assert text.startswith("PERS tooldata tGlue:=[FALSE,[[900.0,0.0,400.0],")
    module = frame_file("abb", [FileFrame(base), FileFrame(tool)], FileContext(table=True)).text
    assert "    tGlue.tframe:=[[900.0,0.0,400.0],[1.0,0.0,0.0,0.0]];" in module.splitlines()
    assert "    Laser.oframe:=[[0,0,0],[1,0,0,0]];" in module.splitlines()
    assert "PERS tooldata tGlue" not in module  # its own module declares it: not again
    found = {f.name: f for f in parse_frame_file("abb", module)}
    assert found["tGlue"].fixed_tool is True
    assert found["Laser"].fixed_tool is False


# --- FANUC: an outside LS position written as a user frame -----------------------------------


def test_fanuc_writes_an_outside_ls_positions_w_p_r_as_a_user_frame() -> None:
    """P[1] of Surfacerobot/crs_application_sizen's LS (W 4.26, P 13.56, R 12.08) as UFRAME[3]:
    the same W P R in the register, read back to the same rotation."""
    rotation = fixed_xyz(4.261677, 13.559316, 12.082948)
    data = frame((653.350855, 600.959864, 660.701574), tuple(wxyz(rotation)), slot=3)
    text = frame_file("fanuc", [FileFrame(data)], FileContext()).text
    elements = dict(re.findall(r"PR\[100,(\d)\]=\(?(-?[\d.]+)\)? ;", text))
    assert [float(elements[str(i)]) for i in range(1, 7)] == [
        653.351, 600.96, 660.702, 4.262, 13.559, 12.083,
    ]  # fmt: skip
    assert "UFRAME[3]=PR[100] ;" in text
    assert "UTOOL[" not in text.split("/MN")[1]
    assert text.startswith("/PROG  TCPUF03\n")
    (back,) = parse_frame_file("fanuc", text)
    assert back.slot == 3
    assert angle_deg(back.quaternion_wxyz, rotation) < 2e-3
    assert export_frame("fanuc", data).text.startswith("UFRAME[3]: X 653.350855 Y 600.959864")


def test_fanuc_refuses_uframe_zero_the_world() -> None:
    with pytest.raises(InvalidInput) as err:
        export_frame("fanuc", frame((0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0), slot=0))
    assert "world frame" in err.value.detail


# --- Yaskawa: UFRAME.CND blocks --------------------------------------------------------------


def test_yaskawa_writes_a_uframe_block_in_the_documented_order() -> None:
    """knowledge.motoman.com, "Information in UFRAME.CND": UFRAME, NAME, TOOL, GROUP, then the
    taught points RORG, RXX, RXY and BUSER (X, Y, Z, Rx, Ry, Rz)."""
    rotation = fixed_xyz(*ANGLES)
    data = frame((350.0, -120.25, 5.5), tuple(wxyz(rotation)), slot=4, name="jig, left")
    text = frame_file("yaskawa", [FileFrame(data)], FileContext()).text
    lines = text.splitlines()
    heads = [re.match(r"/+([A-Z]+)", line).group(1) for line in lines]  # type: ignore[union-attr]
    assert heads == ["UFRAME", "NAME", "TOOL", "GROUP", "PULSE", "RORG", "RXX", "RXY", "BUSER"]
    assert lines[0] == "//UFRAME 4"
    assert lines[1] == "///NAME jig left"
    assert lines[-1] == "////BUSER 350.000,-120.250,5.500,35.0000,-20.0000,10.0000"
    (back,) = parse_frame_file("yaskawa", text)
    assert back.slot == 4
    assert back.name == "jig left"


#: A YRC1000's UFRAME.CND as the controller saved it (three user frames taught on the pendant:
#: pulses in RORG, RXX, RXY; BASICFRM and BASEP lines), tests/data/README.md names its source.
UFRAME_CND = (DATA / "yaskawa_UFRAME.CND").read_text()
_BUSER = re.compile(r"^////BUSER (.+)$", re.MULTILINE)


def test_yaskawa_reads_every_user_frame_of_a_controllers_uframe_cnd() -> None:
    """The controller's own file: each block's number, name and BUSER (X Y Z mm, Rx Ry Rz deg
    about the fixed axes, R = Rz Ry Rx), the angles read as scipy reads the same numbers."""
    frames = parse_frame_file("yaskawa", UFRAME_CND)
    assert [(f.slot, f.name) for f in frames] == [(1, "REAMER"), (2, "S1"), (3, "S2")]
    for parsed, line in zip(frames, _BUSER.findall(UFRAME_CND), strict=True):
        x, y, z, rx, ry, rz = (float(v) for v in line.split(","))
        assert np.asarray(parsed.position_mm) == pytest.approx([x, y, z], abs=1e-9)
        assert angle_deg(np.asarray(parsed.quaternion_wxyz), fixed_xyz(rx, ry, rz)) < 1e-9


def test_yaskawa_writes_a_controllers_frame_as_its_block_lines_byte_for_byte() -> None:
    """Each frame of the controller's file, as tcpcal would serve it, gives back the file's own
    //UFRAME, ///NAME, ///TOOL, ///GROUP and ////BUSER lines (3 decimals of mm, 4 of deg; a
    tenth of a thousandth of a degree, so a swapped or negated angle fails). The controller's
    block also holds ///BASICFRM and ///BASEP lines and the taught pulses, which tcpcal does
    not know and does not write (app/vendors/yaskawa/frame.py says so)."""
    blocks = UFRAME_CND.split("//UFRAME ")[1:]
    for parsed, saved in zip(parse_frame_file("yaskawa", UFRAME_CND), blocks, strict=True):
        data = frame(
            tuple(parsed.position_mm),
            tuple(parsed.quaternion_wxyz),
            slot=parsed.slot,
            name=parsed.name or "",
        )
        written = frame_file("yaskawa", [FileFrame(data)], FileContext()).text.splitlines()
        saved_lines = ("//UFRAME " + saved).splitlines()
        kept = [line for line in saved_lines if not line.startswith(("///BASICFRM", "///BASEP"))]
        assert written[:5] == kept[:5]  # UFRAME, NAME, TOOL, GROUP, PULSE
        assert written[-1] == kept[-1]  # BUSER


# --- UR: a PolyScope program's feature variable ----------------------------------------------


def test_ur_writes_a_polyscope_feature_line_byte_for_byte() -> None:
    """PolyScope declares the program's Point_1 feature as a global pose: read, then written
    under the same name, it is the same line."""
    line = next(
        raw.strip()
        for raw in (DATA / "ur_example_pristine.script").read_text().splitlines()
        if raw.strip().startswith("global Point_1=")
    )
    assert line == "global Point_1=p[0.0,0.0,0.0,3.141592653589793,0.0,0.0]"
    position, quaternion = parse_frame_text("ur", line)
    assert angle_deg(quaternion, Rotation.from_rotvec([np.pi, 0, 0])) < 1e-12
    data = frame(tuple(position), tuple(quaternion), slot=None, name="Point_1")
    assert export_frame("ur", data).text == line


def test_ur_reads_the_features_of_a_polyscope_program() -> None:
    found = {
        f.name: f for f in parse_frame_file("ur", (DATA / "ur_example_pristine.script").read_text())
    }
    assert "Point_1" in found


# --- every format: a frame turned by three unequal angles -----------------------------------


def test_each_format_writes_the_angles_of_its_vendors_convention() -> None:
    rotation = kuka(*ANGLES)
    data = frame((10.0, -20.0, 150.0), tuple(wxyz(rotation)))
    values = {fmt: export_frame(fmt, data).values for fmt in CONTROLLER_FORMATS}
    assert [values["kuka"][k] for k in "ABC"] == pytest.approx(ANGLES, abs=1e-6)
    w, p, r = rotation.as_euler("xyz", degrees=True)
    assert [values["fanuc"][k] for k in "WPR"] == pytest.approx([w, p, r], abs=1e-6)
    assert [values["yaskawa"][k] for k in ("Rx", "Ry", "Rz")] == pytest.approx([w, p, r], abs=1e-6)
    assert [values["techman"][k] for k in ("RX", "RY", "RZ")] == pytest.approx([w, p, r], abs=1e-6)
    quaternion = wxyz(rotation)
    assert [values["abb"][k] for k in ("q1", "q2", "q3", "q4")] == pytest.approx(
        quaternion, abs=1e-9
    )
    assert values["ur"]["pose"] == pytest.approx(
        [0.01, -0.02, 0.15, *rotation.as_rotvec()], abs=1e-12
    )


@pytest.mark.parametrize(("fmt", "slot"), [("kuka", 33), ("fanuc", 10), ("yaskawa", 64)])
def test_a_numbered_format_refuses_a_number_its_controllers_do_not_have(
    fmt: str, slot: int
) -> None:
    with pytest.raises(InvalidInput) as err:
        export_frame(fmt, frame((0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0), slot=slot))
    assert err.value.loc == ("slot",)
    assert f"slot {slot} of frame 'fixture A' is not a" in err.value.detail


def test_abb_says_to_set_the_load_of_a_stationary_tool_it_declares() -> None:
    """A stationary tooldata's tload is the load of the gripper holding the work object, which
    tcpcal does not know: declared here (no controller_symbol) with tool0's, the header says so."""
    tool = frame((1.0, 2.0, 3.0), (1.0, 0.0, 0.0, 0.0), fixed=True, slot=None, name="glue nozzle")
    module = frame_file("abb", [FileFrame(tool)], FileContext()).text
    assert "PERS tooldata glue_nozzle:=[FALSE," in module
    assert "glue_nozzle is declared here with tool0's load: set its tload" in module


def test_techman_has_no_stationary_tcp_and_says_so() -> None:
    """TMflow's ChangeBase sets a base and ChangeTCP the flange's TCP, none a stationary tool
    (as the connector, app.vendors.techman.tmflow): a fixed tool's text is refused at its kind,
    and a robot's table leaves it out naming why."""
    nozzle = frame((900.0, 0.0, 400.0), (1.0, 0.0, 0.0, 0.0), fixed=True, name="nozzle")
    with pytest.raises(InvalidInput) as err:
        export_frame("techman", nozzle)
    assert err.value.loc == ("kind",)
    base = frame((1.0, 2.0, 3.0), (1.0, 0.0, 0.0, 0.0), name="jig")
    table = frame_file("techman", [FileFrame(base), FileFrame(nozzle)], FileContext(table=True))
    assert [item.name for item in table.left_out] == ["nozzle"]
    assert "ChangeBase({1.0,2.0,3.0,0.0,0.0,0.0})" in table.text.splitlines()
    assert "left out: nozzle: frame 'nozzle' is a fixed tool" in table.text
