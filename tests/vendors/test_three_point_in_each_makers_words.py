"""three_point, for the same three touched points, equals a construction written here with
plain numpy cross products (not the project's code), in each maker's words and both ways
(issue 47 "What it must show"): the numbers each maker's frame text prints for the project's
frame are the angles scipy gives the independent frame under the vendor's convention, and the
rotation those printed numbers stand for (scipy, the same convention) is the independent
frame's, to 1e-6 mm and 1e-6 deg, over 200 seeded sets of points and each convention.

The conventions are tests/vendors/test_outside_samples.py's, written from the vendors'
documents: KUKA R = Rz(A) Ry(B) Rx(C); FANUC W P R, Yaskawa Rx Ry Rz, Techman RX RY RZ about
the fixed x, y, z axes; ABB q1..q4 scalar first; UR a rotation vector (rad) and metres.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from app.solvers.frame import THREE_POINT
from app.vendors.frame import FrameData
from app.vendors.registry import export_frame, parse_frame_text
from app.words import CONTROLLER_FORMATS
from tests.vendors.test_outside_samples import fixed_xyz, kuka

SETS = 200
TOLERANCE_MM = 1e-6
TOLERANCE_DEG = 1e-6


def independent(convention: str, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R frame -> base, origin) by cross products: origin_x_xy and ur_plane (KUKA 3-point,
    FANUC three point, Yaskawa ORG/XX/XY, PolyScope's plane: origin, +X, the +Y side), and
    abb_user (X1, X2 on X; Y1 on +Y; the origin the foot of Y1 on the X1-X2 line)."""
    a, b, c = p
    x_axis = (b - a) / np.linalg.norm(b - a)
    origin = a if convention != "abb_user" else a + np.dot(c - a, x_axis) * x_axis
    z_axis = np.cross(x_axis, c - origin)
    z_axis /= np.linalg.norm(z_axis)
    y_axis = np.cross(z_axis, x_axis)
    return np.column_stack([x_axis, y_axis, z_axis]), origin


def point_sets(seed: int) -> list[np.ndarray]:
    """Three points well apart and off one line, anywhere in a 2 m cell."""
    rng = np.random.default_rng(seed)
    sets: list[np.ndarray] = []
    while len(sets) < SETS:
        p = rng.uniform(-1000.0, 1000.0, size=(3, 3))
        a, b, c = p
        if (
            min(
                np.linalg.norm(b - a),
                np.linalg.norm(np.cross(b - a, c - a)) / np.linalg.norm(b - a),
            )
            > 50
        ):
            sets.append(p)
    return sets


def printed(fmt: str, text: str) -> list[float]:
    """The numbers of a maker's frame text, read here: the six (or seven) of its pose."""
    if fmt == "abb":
        inner = re.search(r"\[\[([^\]]*)\],\[([^\]]*)\]\]", text)
        assert inner is not None
        return [float(v) for part in inner.groups() for v in part.split(",")]
    if fmt == "ur":
        inner = re.search(r"p\[([^\]]*)\]", text)
        assert inner is not None
        return [float(v) for v in inner.group(1).split(",")]
    if fmt == "kuka":
        return [float(v) for v in re.findall(r"[XYZABC] (-?[\d.]+)", text.split("=", 1)[1])]
    if fmt == "techman":
        inner = re.search(r"ChangeBase\(\{([^}]*)\}\)", text)
        assert inner is not None
        return [float(v) for v in inner.group(1).split(",")]
    return [float(v) for v in re.findall(r"(?:X|Y|Z|W|P|R|Rx|Ry|Rz) (-?[\d.]+)", text)]


def rotation_of(fmt: str, numbers: list[float]) -> tuple[np.ndarray, Rotation]:
    """(position mm, rotation) the printed numbers stand for under the vendor's convention."""
    if fmt == "abb":
        return np.array(numbers[:3]), Rotation.from_quat(numbers[3:], scalar_first=True)
    if fmt == "ur":
        return np.array(numbers[:3]) * 1000.0, Rotation.from_rotvec(numbers[3:])
    if fmt == "kuka":
        return np.array(numbers[:3]), kuka(*numbers[3:])
    return np.array(numbers[:3]), fixed_xyz(*numbers[3:])


def vendor_angles(fmt: str, rotation: Rotation) -> np.ndarray:
    """The independent frame's angles under the vendor's convention (scipy)."""
    if fmt == "kuka":
        return np.asarray(rotation.as_euler("ZYX", degrees=True))
    if fmt in ("fanuc", "yaskawa", "techman"):
        return np.asarray(rotation.as_euler("xyz", degrees=True))
    if fmt == "ur":
        return np.asarray(rotation.as_rotvec())
    return np.asarray(rotation.as_quat(scalar_first=True))


def angle_between(a: Rotation, b: Rotation) -> float:
    return float(np.degrees((a.inv() * b).magnitude()))


@pytest.mark.parametrize("fmt", CONTROLLER_FORMATS)
@pytest.mark.parametrize("convention", ["origin_x_xy", "abb_user", "ur_plane"])
def test_three_point_equals_the_cross_product_frame_in_each_makers_angles(
    convention: str, fmt: str
) -> None:
    worst_mm = worst_deg = worst_angle = 0.0
    for p in point_sets(seed=47):
        truth_R, truth_origin = independent(convention, p)
        truth = Rotation.from_matrix(truth_R)
        R, origin = THREE_POINT[convention].build(p)  # type: ignore[index]
        quaternion = Rotation.from_matrix(R).as_quat(scalar_first=True)
        data = FrameData(tuple(origin), tuple(quaternion), slot=3, name="fixture")
        text = export_frame(fmt, data).text
        numbers = printed(fmt, text)
        # one way: the printed numbers stand for the independent frame
        position, rotation = rotation_of(fmt, numbers)
        worst_mm = max(worst_mm, float(np.max(np.abs(position - truth_origin))))
        worst_deg = max(worst_deg, angle_between(rotation, truth))
        # the other: the printed angles are scipy's for the independent frame (away from a
        # gimbal lock, where Euler angles are not one set; wrapped to +-180 deg)
        want = vendor_angles(fmt, truth)
        got = np.array(numbers[3:])
        if fmt in ("kuka", "fanuc", "yaskawa", "techman"):
            if abs(want[1]) > 89.0:
                continue
            diff = (got - want + 180.0) % 360.0 - 180.0
        elif fmt == "abb":
            diff = min(got - want, got + want, key=lambda d: float(np.max(np.abs(d))))
        else:
            diff = np.degrees(got - want)
        worst_angle = max(worst_angle, float(np.max(np.abs(diff))))
        back_position, back_quaternion = parse_frame_text(fmt, text)
        back = Rotation.from_quat(back_quaternion, scalar_first=True)
        assert np.max(np.abs(back_position - truth_origin)) < TOLERANCE_MM
        assert angle_between(back, truth) < TOLERANCE_DEG
    assert worst_mm < TOLERANCE_MM, f"{fmt} {convention}: {worst_mm} mm"
    assert worst_deg < TOLERANCE_DEG, f"{fmt} {convention}: {worst_deg} deg"
    assert worst_angle < TOLERANCE_DEG, f"{fmt} {convention}: printed angles off {worst_angle}"
