"""Universal Robots: a frame as a feature pose ``p[x,y,z,rx,ry,rz]`` (m, rad): the text is
the feature's variable as PolyScope declares it, ``global <name>=p[...]``, the file a URScript
function per frame returning its pose, and their reader.

Followed: *The URScript Programming Language* (e-Series 5.x), "Pose" (metres and a rotation
vector, rad), "Functions" (``def name(): ... end``, ``return``) and ``pose_trans``; a program
PolyScope saves declares each installation feature it uses as a global pose at its start,
``global Point_1=p[0.0,0.0,0.0,3.141592653589793,0.0,0.0]``
(tests/data/controller-files/ur_example_pristine.script), its numbers as the shortest decimal
that reads back the same double: the text prints them so (never an exponent), which keeps
the frame exactly. A plane feature is taught by three points (PolyScope 5: the first its
origin, the second on +X, the third on the +Y side), app.solvers.frame.construction's
`ur_plane`.

What the file changes, and how the controller merges it: nothing until a function is called;
``tcpcal_<frame>()`` returns the frame's pose, to be used where a feature is
(``pose_trans(tcpcal_fixture(), p[...])``, or a variable a program assigns at its start).
The installation's features are untouched: no remote interface writes a feature (contract
v1.4 "Frames at the controller"), so the file, put in the program (a Script node), is how a
calibration reaches the robot. A fixed tool's function returns the stationary TCP's pose in
the robot's base frame.
"""

from __future__ import annotations

import re

import numpy as np

from app.arrays import FloatArray
from app.kinematics.poses import (
    matrix_from_quaternion_wxyz,
    matrix_from_rotvec,
    quaternion_wxyz_from_matrix,
    rotvec_from_matrix,
)
from app.vendors.files import ControllerFile, FileContext, header_comments, split_fitting
from app.vendors.frame import NOUN, FileFrame, FrameData, ParsedFrame
from app.vendors.names import identifier, unique
from app.vendors.text import NUMBER, ControllerExport, checked_tcp, parse_error
from app.vendors.ur.file import LINE_WIDTH, NAME_CHARS, PREFIX
from app.vendors.ur.text import FORMAT

_LABELS = ("x", "y", "z", "rx", "ry", "rz")
_SIX = r"\s*,\s*".join([f"({NUMBER})"] * 6)
_POSE = re.compile(rf"p\s*\[\s*{_SIX}\s*\]")
_DEF = re.compile(r"^\s*def\s+([A-Za-z][A-Za-z0-9_]*)\s*\(\s*\)\s*:", re.MULTILINE)
_GLOBAL = re.compile(rf"^\s*global\s+([A-Za-z][A-Za-z0-9_]*)\s*=\s*p\s*\[\s*{_SIX}\s*\]", re.M)


def real(value: float) -> str:
    """A URScript number: the shortest decimal that reads back as the same double, in plain
    notation ("3.141592653589793", "0.0", "0.00001"), no negative zero."""
    number = float(value) + 0.0
    text = repr(number)
    if "e" in text or "E" in text:
        text = f"{number:.20f}".rstrip("0")
        text = text + "0" if text.endswith(".") else text
    return text


def feature_pose(frame: FrameData) -> FloatArray:
    """The frame as a UR pose: x, y, z (m) and the rotation vector (rad)."""
    position, quaternion = checked_tcp(frame)
    rotvec = rotvec_from_matrix(matrix_from_quaternion_wxyz(quaternion))
    pose: FloatArray = np.concatenate([position / 1000.0, rotvec])
    return pose


def pose_text(frame: FrameData) -> str:
    """``p[x,y,z,rx,ry,rz]`` of the frame."""
    return "p[" + ",".join(real(v) for v in feature_pose(frame)) + "]"


def variable_name(name: str) -> str:
    """A feature variable's name: the frame's name as an identifier (PolyScope's own
    ``Point_1``, ``Plane_2`` stay as they are)."""
    return identifier(name, NAME_CHARS, fallback="frame")


def export(frame: FrameData) -> ControllerExport:
    """``global <name>=p[x,y,z,rx,ry,rz]`` (m, rad), as PolyScope declares a feature."""
    pose = feature_pose(frame)
    values: dict[str, object] = {
        "name": variable_name(frame.name),
        "pose": [float(v) for v in pose],
        **{label: float(v) for label, v in zip(_LABELS, pose, strict=True)},
    }
    text = f"global {variable_name(frame.name)}={pose_text(frame)}"
    return ControllerExport(format=FORMAT, text=text, values=values)


def _from_numbers(numbers: list[float]) -> tuple[FloatArray, FloatArray]:
    values = np.array(numbers)
    position: FloatArray = values[:3] * 1000.0
    return position, quaternion_wxyz_from_matrix(matrix_from_rotvec(values[3:]))


def parse(text: str) -> tuple[FloatArray, FloatArray]:
    """The first ``p[x,y,z,rx,ry,rz]`` (m, rad) -> (position (3,) mm, quaternion wxyz (4,))."""
    match = _POSE.search(text)
    if match is None:
        raise parse_error(FORMAT, "p[x,y,z,rx,ry,rz] in m and rad", text)
    return _from_numbers([float(g) for g in match.groups()])


def function_name(name: str) -> str:
    """tcpcal_<frame name as an identifier>, at most 40 characters."""
    return PREFIX + identifier(name, NAME_CHARS - len(PREFIX), fallback="frame")


def write(frames: list[FileFrame], context: FileContext) -> ControllerFile:
    """Header comments, then ``def tcpcal_<frame>(): return p[..] end`` each."""
    kept, left = split_fitting(frames, feature_pose, context)
    names = unique([function_name(item.data.name) for item in kept], NAME_CHARS)
    lines = header_comments(kept, left, context, _how(names), "# ", LINE_WIDTH, NOUN)
    for item, name in zip(kept, names, strict=True):
        lines += [f"def {name}():", f"  return {pose_text(item.data)}", "end"]
    file_name = "tcpcal_frames.script" if context.table or len(kept) != 1 else f"{names[0]}.script"
    return ControllerFile(FORMAT, file_name, "\n".join(lines) + "\n", tuple(left))


def _how(names: list[str]) -> list[str]:
    """The header's sentences on what the file changes."""
    if not names:
        return ["changes nothing: it holds no frame"]
    return [
        f"defines {', '.join(f'{n}()' for n in names)}, each returning its frame's pose "
        "(m, rad) in the robot's base frame, to use where a feature is; changes nothing",
        "the installation's features are untouched",
    ]


def read(text: str) -> list[ParsedFrame]:
    """Every function's returned pose of a URScript file, and every feature variable
    (``global <name>=p[...]``) a program declares."""
    starts = list(_DEF.finditer(text))
    frames = []
    for i, match in enumerate(starts):
        end = starts[i + 1].start() if i + 1 < len(starts) else len(text)
        pose = _POSE.search(text[match.end() : end])
        if pose is not None and re.search(r"\breturn\s+p\s*\[", text[match.end() : end]):
            position, quaternion = _from_numbers([float(g) for g in pose.groups()])
            frames.append(ParsedFrame(None, match.group(1), position, quaternion))
    for match in _GLOBAL.finditer(text):
        position, quaternion = _from_numbers([float(g) for g in match.groups()[1:]])
        frames.append(ParsedFrame(None, match.group(1), position, quaternion))
    if not frames:
        raise parse_error(FORMAT, "def tcpcal_<frame>(): return p[...] end", text)
    return frames
