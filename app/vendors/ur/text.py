"""Universal Robots URScript: ``set_tcp(p[x, y, z, rx, ry, rz])`` in m and rad.

A UR pose ``p[x, y, z, rx, ry, rz]`` is a position in metres and a rotation vector
(axis * angle, rad) (URScript manual, "Pose" and ``set_tcp(pose)``; ``set_payload(m, cog)``
takes kg and a centre of gravity in metres).
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
from app.vendors.text import (
    KG_DECIMALS,
    NUMBER,
    SI_DECIMALS,
    ControllerExport,
    checked_tcp,
    comment_text,
    fmt_list,
    fmt_number,
    parse_error,
    rounded,
)
from app.vendors.tool import ToolData

FORMAT = "ur"
_LABELS = ("x", "y", "z", "rx", "ry", "rz")


def export(tool: ToolData) -> ControllerExport:
    """``set_tcp(p[x,y,z,rx,ry,rz])`` (m, rad) and, with a load, ``set_payload(m, [cog m])``."""
    position, quaternion = checked_tcp(tool)
    rotvec = rotvec_from_matrix(matrix_from_quaternion_wxyz(quaternion))
    pose = np.concatenate([position / 1000.0, rotvec])
    pose_text = f"p[{fmt_list(pose, SI_DECIMALS)}]"
    values: dict[str, object] = {
        "slot": tool.slot,
        "pose": [rounded(v, SI_DECIMALS) for v in pose],
        **{label: rounded(v, SI_DECIMALS) for label, v in zip(_LABELS, pose, strict=True)},
    }
    lines = [f"set_tcp({pose_text})  # {comment_text(tool.name)}"]
    if tool.load is not None and tool.load.mass_kg > 0:
        cog_m = np.asarray(tool.load.cog_or_origin) / 1000.0
        values["mass_kg"] = rounded(tool.load.mass_kg, KG_DECIMALS)
        values["cog_m"] = [rounded(c, SI_DECIMALS) for c in cog_m]
        mass_text = fmt_number(tool.load.mass_kg, KG_DECIMALS)
        lines.append(f"set_payload({mass_text}, [{fmt_list(cog_m, SI_DECIMALS)}])")
    return ControllerExport(format=FORMAT, text="\n".join(lines), values=values)


def parse(text: str) -> tuple[FloatArray, FloatArray]:
    """The first ``p[x,y,z,rx,ry,rz]`` (m, rad) -> (position (3,) mm, quaternion wxyz (4,))."""
    six = r"\s*,\s*".join([f"({NUMBER})"] * 6)
    match = re.search(rf"p\s*\[\s*{six}\s*\]", text)
    if match is None:
        raise parse_error(FORMAT, "p[x,y,z,rx,ry,rz] in m and rad", text)
    numbers = np.array([float(g) for g in match.groups()])
    position: FloatArray = numbers[:3] * 1000.0
    quaternion = quaternion_wxyz_from_matrix(matrix_from_rotvec(numbers[3:]))
    return position, quaternion
