"""ABB: a frame as a RAPID work object (a base) or a stationary tool (a fixed tool), one
declaration as the text, a RAPID module assigning each frame as the file, and their reader.

Followed: ABB *Technical reference manual - RAPID Instructions, Functions and Data types*,
"wobjdata" (``[robhold, ufprog, ufmec, uframe, oframe]``: robhold FALSE when the robot does
not hold the work object, ufprog TRUE for a fixed user frame, ufmec "" for none, uframe the
user frame in the world, oframe the object frame in the user frame; the object the robot
works in is uframe * oframe) and "tooldata" (robhold FALSE for a stationary tool: tframe is
then the TCP in the world frame, and tload the load of the gripper holding the work object,
which tcpcal does not know), record components assigned by name (the manual's
``gripper.tframe.trans.z := 225.2;``). The module's shape is app.vendors.abb.file's (RAPID
overview, "Modules", comments ``!``).

The text declares the whole value: a base as ``PERS wobjdata name:=[FALSE,TRUE,"",[[x,y,z],
[q1,q2,q3,q4]],[[0,0,0],[1,0,0,0]]];`` (uframe the frame, oframe the identity, so the work
object is the frame), a fixed tool as ``PERS tooldata name:=[FALSE,[[x,y,z],[q1..q4]],
[0,[0,0,0],[1,0,0,0],0,0,0]];`` with tool0's load and a comment saying to set the gripper's.
Public modules declare work objects in the same shape, oframe or uframe set
(tests/data/controller-files/abb_CalibData.mod, which sets oframe: the reader composes both).

What the file changes, and how the controller merges it: a routine ``tcpcal_set_<frames|
frame>`` assigns, for each frame, only what tcpcal calibrated: a work object's uframe and
oframe (the identity: the work object becomes the frame; robhold, ufprog and ufmec stay), a
stationary tool's tframe (its tload stays the gripper's). A frame named by its
controller_symbol is not declared again (its module declares it); one without is declared
here. Load the module into the frame's task, run the routine once (PP to Routine).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from app.arrays import FloatArray
from app.kinematics.frames import compose
from app.vendors.abb.file import LINE_WIDTH, routine_name
from app.vendors.abb.text import (
    FORMAT,
    MAX_IDENTIFIER,
    RapidSyntaxError,
    RapidValue,
    rapid_identifier,
    rapid_name,
    unit_quaternion,
    value_at,
)
from app.vendors.files import (
    ControllerFile,
    FileContext,
    LeftOut,
    header_comments,
    split_fitting,
)
from app.vendors.frame import NOUN, FileFrame, FrameData, ParsedFrame
from app.vendors.names import unique
from app.vendors.text import (
    MM_DECIMALS,
    QUATERNION_DECIMALS,
    ControllerExport,
    checked_tcp,
    fmt_number,
    parse_error,
    rounded,
)

TABLE_MODULE = "tcpcal_frames"
IDENTITY_POSE = "[[0,0,0],[1,0,0,0]]"
#: tool0's load (system module BASE), what a stationary tool's text declares: its tload is
#: the load of the gripper holding the work object, which the robot's integrator sets.
TOOL0_LOAD = "[0,[0,0,0],[1,0,0,0],0,0,0]"

# A declaration (``PERS wobjdata name:=``, TASK or LOCAL too), a whole assignment
# (``name:=``) or a component's (``name.uframe:=``): where a value starts.
_ASSIGNED = re.compile(
    r"(?<![A-Za-z0-9_.])(?:(wobjdata|tooldata)\s+)?([A-Za-z][A-Za-z0-9_]*)"
    r"(?:\.(uframe|oframe|tframe))?\s*:=\s*(?=\[)",
    re.IGNORECASE,
)
_MODULE = re.compile(r"^\s*MODULE\s+[A-Za-z]", re.IGNORECASE | re.MULTILINE)
_END = re.compile(r"^\s*ENDMODULE\s*$", re.IGNORECASE | re.MULTILINE)


def data_type(frame: FrameData) -> str:
    """The RAPID data type of the frame: tooldata for a fixed tool, wobjdata for a base."""
    return "tooldata" if frame.fixed_tool else "wobjdata"


def pose_value(frame: FrameData) -> str:
    """``[[x,y,z],[q1,q2,q3,q4]]``: the frame as a RAPID pose (mm, q1 the scalar part)."""
    position, quaternion = checked_tcp(frame)
    trans = ",".join(fmt_number(v, MM_DECIMALS) for v in position)
    rot = ",".join(fmt_number(v, QUATERNION_DECIMALS) for v in quaternion)
    return f"[[{trans}],[{rot}]]"


def frame_value(frame: FrameData) -> str:
    """The whole wobjdata (uframe the frame, oframe the identity) or stationary tooldata."""
    if frame.fixed_tool:
        return f"[FALSE,{pose_value(frame)},{TOOL0_LOAD}]"
    return f'[FALSE,TRUE,"",{pose_value(frame)},{IDENTITY_POSE}]'


def export(frame: FrameData) -> ControllerExport:
    """``PERS wobjdata <name>:=[FALSE,TRUE,"",<frame>,<identity>];`` for a base, ``PERS
    tooldata <name>:=[FALSE,<frame>,<tool0's load>];`` for a fixed tool."""
    position, quaternion = checked_tcp(frame)
    name = rapid_name(frame)
    text = f"PERS {data_type(frame)} {name}:={frame_value(frame)};"
    if frame.fixed_tool:
        text += "  ! tload: set the load of the gripper holding the work object"
    labels = ("x", "y", "z", "q1", "q2", "q3", "q4")
    numbers = [*position, *quaternion]
    decimals = (MM_DECIMALS,) * 3 + (QUATERNION_DECIMALS,) * 4
    values: dict[str, object] = {
        "name": name,
        "type": data_type(frame),
        "robhold": False,
        **{k: rounded(v, d) for k, v, d in zip(labels, numbers, decimals, strict=True)},
    }
    return ControllerExport(format=FORMAT, text=text, values=values)


@dataclass
class _Found:
    """What a text says of one RAPID frame: its type, and each pose as last written."""

    name: str
    fixed_tool: bool | None = None
    poses: dict[str, tuple[FloatArray, FloatArray]] = field(default_factory=dict)

    def frame(self) -> tuple[FloatArray, FloatArray] | None:
        if "tframe" in self.poses:
            return self.poses["tframe"]
        if "uframe" not in self.poses and "oframe" not in self.poses:
            return None
        identity = (np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]))
        user = self.poses.get("uframe", identity)
        obj = self.poses.get("oframe", identity)
        position, quaternion = compose(user, obj)
        return np.array(position), np.array(quaternion)


def pose_of(value: RapidValue, text: str) -> tuple[FloatArray, FloatArray]:
    """A RAPID pose ``[[x,y,z],[q1..q4]]`` -> (position mm, unit quaternion wxyz)."""
    if not (isinstance(value, list) and len(value) == 2):
        raise RapidSyntaxError(f"not a pose [trans, rot]: {text!r}")
    trans, rot = value
    if not (
        isinstance(trans, list) and len(trans) == 3 and isinstance(rot, list) and len(rot) == 4
    ):
        raise RapidSyntaxError(f"not a pose [[x,y,z],[q1,q2,q3,q4]]: {text!r}")
    numbers = [*trans, *rot]
    if not all(isinstance(v, float) and np.isfinite(v) for v in numbers):
        raise RapidSyntaxError(f"a pose member is not a finite number: {text!r}")
    floats = [float(v) for v in numbers if isinstance(v, float)]
    q1, q2, q3, q4 = floats[3:]
    return np.array(floats[:3]), unit_quaternion((q1, q2, q3, q4))


def _record(found: _Found, declared: str | None, value: RapidValue, text: str) -> None:
    """Put a whole wobjdata or tooldata value into `found` (a held tooldata is no frame)."""
    is_wobj = isinstance(value, list) and len(value) == 5 and declared != "tooldata"
    if is_wobj and isinstance(value, list):
        found.fixed_tool = False
        found.poses["uframe"] = pose_of(value[3], text)
        found.poses["oframe"] = pose_of(value[4], text)
        return
    if isinstance(value, list) and len(value) == 3 and value[0] is False:
        found.fixed_tool = True
        found.poses["tframe"] = pose_of(value[1], text)
        return
    raise RapidSyntaxError(f"not a wobjdata or a stationary tooldata: {text!r}")


def _frames(text: str) -> dict[str, _Found]:
    """Every work object and stationary tool of RAPID text, by name (without case), each pose
    as the text leaves it (declared, assigned whole, or by component)."""
    found: dict[str, _Found] = {}
    for match in _ASSIGNED.finditer(text):
        declared, name, part = match.group(1), match.group(2), match.group(3)
        key = name.lower()
        try:
            value = value_at(text, match.end())
            entry = found.get(key, _Found(name))
            if part is not None:
                entry.poses[part.lower()] = pose_of(value, text)
                entry.fixed_tool = part.lower() == "tframe"
            else:
                _record(entry, declared.lower() if declared else None, value, text)
        except RapidSyntaxError:
            continue  # another data type's value (a robtarget, a held tool), or not a value
        found[key] = entry
    return found


def parse(text: str) -> tuple[FloatArray, FloatArray]:
    """The first work object or stationary tool of RAPID text -> (position mm, quaternion
    wxyz): a wobjdata's uframe * oframe, a tooldata's tframe."""
    for entry in _frames(text).values():
        pose = entry.frame()
        if pose is not None:
            return pose
    raise parse_error(
        FORMAT, 'wobjdata name:=[FALSE,TRUE,"",[[x,y,z],[q1,q2,q3,q4]],[[...],[...]]]', text
    )


def module_name(frames: list[FileFrame], context: FileContext) -> str:
    """tcpcal_frames for a robot's table, tcpcal_<frame> for one frame (<= 32 characters)."""
    if context.table or len(frames) != 1:
        return TABLE_MODULE
    return rapid_identifier("tcpcal_" + rapid_identifier(frames[0].data.name))


def _data_names(
    kept: list[FileFrame], taken: list[str]
) -> tuple[list[FileFrame], list[str], list[LeftOut]]:
    """(the frames, their data names, the frames left out): a controller_symbol's name as it
    is (it names data on the controller), the others made unique among all of them."""
    seen = {n.lower() for n in taken}
    held: list[FileFrame] = []
    names: list[str] = []
    left: list[LeftOut] = []
    plain: list[int] = []
    for item in kept:
        if item.data.controller_symbol:
            name = rapid_name(item.data)
            if name.lower() in seen:
                reason = f"another frame of this file has the data name {name}"
                left.append(LeftOut(item.data.name, reason))
                continue
            seen.add(name.lower())
        else:
            plain.append(len(held))
            name = rapid_name(item.data)
        held.append(item)
        names.append(name)
    fixed = [*taken, *(n for i, n in enumerate(names) if i not in plain)]
    made = unique([*fixed, *(names[i] for i in plain)], MAX_IDENTIFIER)[len(fixed) :]
    for i, name in zip(plain, made, strict=True):
        names[i] = name
    return held, names, left


def _assignments(frame: FrameData, name: str) -> list[str]:
    """What the routine sets: a work object's uframe and oframe, a stationary tool's tframe."""
    if frame.fixed_tool:
        return [f"    {name}.tframe:={pose_value(frame)};"]
    return [f"    {name}.uframe:={pose_value(frame)};", f"    {name}.oframe:={IDENTITY_POSE};"]


def _how(frames: list[FileFrame], names: list[str], routine: str) -> list[str]:
    """The header's sentences on what the module changes and how to load it."""
    if not frames:
        return ["changes nothing on the controller: it holds no frame"]
    held = []
    for item, name in zip(frames, names, strict=True):
        where = item.data.controller_symbol or "declared here"
        held.append(f"{data_type(item.data)} {name} ({where})")
    return [
        f"changes only {', '.join(held)}: a work object's uframe and oframe (the identity), "
        "a stationary tool's tframe; robhold, ufprog, ufmec, tload and all other data stay",
        f"load it into the frames' task (Program Editor, Modules, Load Module), then run "
        f"{routine} once (PP to Routine): it assigns the values",
        *(
            f"{name} is declared here with tool0's load: set its tload to the load of the "
            "gripper holding the work object"
            for item, name in zip(frames, names, strict=True)
            if item.data.fixed_tool and not item.data.controller_symbol
        ),
    ]


def write(frames: list[FileFrame], context: FileContext) -> ControllerFile:
    """One RAPID module: a header comment, a PERS declaration for each frame without a
    controller_symbol, and a routine assigning every frame."""
    kept, left = split_fitting(frames, export, context)
    module = module_name(frames, context)
    routine = routine_name(module)
    held, names, clashes = _data_names(kept, [module, routine])
    left = [*left, *clashes]
    how = _how(held, names, routine)
    comments = header_comments(held, left, context, how, "  ! ", LINE_WIDTH, NOUN)
    lines = [f"MODULE {module}", *comments]
    for item, name in zip(held, names, strict=True):
        if not item.data.controller_symbol:
            lines.append(f"  PERS {data_type(item.data)} {name}:={frame_value(item.data)};")
    if held:
        lines.append(f"  PROC {routine}()")
        for item, name in zip(held, names, strict=True):
            lines += _assignments(item.data, name)
        lines.append("  ENDPROC")
    lines.append("ENDMODULE")
    return ControllerFile(FORMAT, f"{module}.mod", "\n".join(lines) + "\n", tuple(left))


def read(text: str) -> list[ParsedFrame]:
    """Every work object and stationary tool of a RAPID module, once each by name, as the
    module leaves it (declared, then assigned whole or by component)."""
    if _MODULE.search(text) is None or _END.search(text) is None:
        raise parse_error(FORMAT, "a RAPID module: MODULE <name> ... ENDMODULE", text)
    frames = []
    for entry in _frames(text).values():
        pose = entry.frame()
        if pose is not None:
            frames.append(ParsedFrame(None, entry.name, pose[0], pose[1], entry.fixed_tool))
    return frames
