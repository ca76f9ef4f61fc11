"""Forward kinematics of a serial arm from its URDF (the ROS robot description format).

The URDF is parsed by `yourdfpy` (PyPI, MIT; https://github.com/clemense/yourdfpy), after a
well-formedness check by lxml (the document comes from a client: a DOCTYPE is refused, so no
entity is expanded and nothing fetched; undeclared namespace prefixes such as `drake:` on
attributes, which real URDFs carry, are let through as ROS's parsers let them through).
Format reference: the URDF specification, http://wiki.ros.org/urdf/XML/joint and
http://wiki.ros.org/urdf/XML/link: a joint's <origin xyz rpy> places its child link's frame
in its parent's (metres; roll-pitch-yaw, fixed axes X then Y then Z, i.e. R = Rz(y) Ry(p)
Rx(r)); a revolute joint turns the child about <axis> (in the joint frame) by the joint
value; <limit lower upper> bound it (radians). yourdfpy gives each origin as a 4x4 matrix.

What is supported along the chain: `revolute` joints (limits checked), `continuous` joints
(no limits), and `fixed` joints; joints off the chain (a gripper's fingers) are not read.
Refused with 422, naming the joint, when on the chain: `prismatic`
(a linear track: model the arm from its carriage), `floating` and `planar` joints (not an
arm), `mimic` joints (a joint driven by another: not a serial arm's axis). The chain runs
from `base_link` (default: the URDF's root link) to `tip_link` (default: the leaf link at the
end of the most movable joints, e.g. ROS-Industrial's `tool0`); `base_link` may be
any link reached from the root through fixed joints only (a controller's base frame, such as
ROS-Industrial's `base`, may hang off `base_link` turned by 180 deg about z). Joint values
are given in the chain's order, radians unless the request's `units` says degrees; lengths
come out in mm.
"""

from __future__ import annotations

import io
import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Protocol

import numpy as np
from lxml import etree
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.solvers.validation import check_finite

#: Largest URDF document accepted (characters); the arms' are 5-60 kB.
MAX_URDF_CHARS = 1_000_000
#: Most movable joints along a chain (7-axis arms plus a track or two).
MAX_CHAIN_JOINTS = 12
#: A joint value this far (rad) outside its limits is still taken as within (rounding).
LIMIT_SLACK_RAD = 1e-9
SUPPORTED = ("revolute", "continuous", "fixed")
_LOC = ("kinematics", "urdf")


class _Limit(Protocol):
    lower: float | None
    upper: float | None


class _Mimic(Protocol):
    joint: str


class _Joint(Protocol):
    """The fields of a yourdfpy Joint read here (yourdfpy ships no type information)."""

    name: str
    type: str
    parent: str
    child: str
    origin: FloatArray | None
    axis: FloatArray | None
    limit: _Limit | None
    mimic: _Mimic | None


class _Link(Protocol):
    name: str


class _Robot(Protocol):
    name: str
    joints: list[_Joint]
    links: list[_Link]


class _Model(Protocol):
    robot: _Robot


@dataclass(frozen=True)
class ChainJoint:
    """One joint along the chain: its fixed origin (rotation, translation mm), its motion."""

    name: str
    kind: str  # revolute | continuous | fixed
    rotation: Rotation
    translation_mm: FloatArray
    axis: FloatArray
    lower_rad: float | None
    upper_rad: float | None


@dataclass(frozen=True)
class UrdfChain:
    """A serial chain read from a URDF, base link to tip link."""

    robot: str
    base_link: str
    tip_link: str
    joints: tuple[ChainJoint, ...]
    #: the base link's frame in the root's (through fixed joints), rotation and mm
    base_rotation: Rotation
    base_translation_mm: FloatArray

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The movable joints, in the order their values are given."""
        return tuple(j.name for j in self.joints if j.kind != "fixed")

    @property
    def n_joints(self) -> int:
        """Number of movable joints (values per pose)."""
        return len(self.joint_names)

    def flange_poses(
        self, joints_rad: ArrayLike, *, loc: Sequence[str | int] = ("poses",)
    ) -> tuple[FloatArray, FloatArray]:
        """Tip poses in the base link's frame for (N, n) joint values in radians.

        Returns (rotations (N, 3, 3), positions (N, 3) mm). A value outside its joint's
        limits raises InvalidInput("out-of-range") naming the pose and the joint.
        """
        q = check_finite(joints_rad, loc=loc)
        n_poses = q.shape[0]
        if q.ndim != 2 or q.shape[1] != self.n_joints:
            raise InvalidInput(
                "invalid-pose",
                f"joint values must have shape (N, {self.n_joints}) for this URDF chain "
                f"({', '.join(self.joint_names)}), got {q.shape}",
                loc=loc,
            )
        if n_poses == 0:
            return np.zeros((0, 3, 3)), np.zeros((0, 3))
        self._check_limits(q, loc)
        rotation = Rotation.identity(n_poses)
        position = np.zeros((n_poses, 3))
        k = 0
        for joint in self.joints:
            position = position + rotation.apply(joint.translation_mm)
            rotation = rotation * joint.rotation
            if joint.kind != "fixed":
                rotation = rotation * Rotation.from_rotvec(q[:, k, None] * joint.axis)
                k += 1
        # From the root into the base link's frame (fixed).
        to_base = self.base_rotation.inv()
        rotation = to_base * rotation
        position = to_base.apply(position - self.base_translation_mm)
        matrices: FloatArray = rotation.as_matrix().reshape(n_poses, 3, 3)
        return matrices, position

    def _check_limits(self, q: FloatArray, loc: Sequence[str | int]) -> None:
        movable = [j for j in self.joints if j.kind != "fixed"]
        for k, joint in enumerate(movable):
            if joint.lower_rad is None or joint.upper_rad is None:
                continue
            low, high = joint.lower_rad - LIMIT_SLACK_RAD, joint.upper_rad + LIMIT_SLACK_RAD
            bad = np.flatnonzero((q[:, k] < low) | (q[:, k] > high))
            if bad.size:
                i = int(bad[0])
                raise InvalidInput(
                    "out-of-range",
                    f"pose {i}: joint {joint.name!r} (q{k + 1}) = {np.degrees(q[i, k]):.4g} deg "
                    f"is outside its limits {np.degrees(joint.lower_rad):.4g} .. "
                    f"{np.degrees(joint.upper_rad):.4g} deg in the URDF (check the joint order "
                    f"{', '.join(self.joint_names)} and the angle units)",
                    loc=(*loc, i, "joints"),
                    context={"joint": joint.name, "value_deg": float(np.degrees(q[i, k]))},
                )


def chain_from_spec(spec: Mapping[str, object]) -> UrdfChain:
    """Read the API object {"urdf": "<robot ...>", "base_link"?, "tip_link"?}."""
    unknown = sorted(set(spec) - {"urdf", "base_link", "tip_link"})
    if unknown:
        raise InvalidInput(
            "invalid-kinematics",
            f"unknown kinematics field {unknown[0]!r} beside 'urdf'; expected 'base_link' and "
            "'tip_link'",
            loc=("kinematics", unknown[0]),
        )
    text, base, tip = spec.get("urdf"), spec.get("base_link"), spec.get("tip_link")
    if not isinstance(text, str) or not text.strip():
        raise _bad("kinematics.urdf must be the URDF document as a string: '<robot ...>'")
    for name, value in (("base_link", base), ("tip_link", tip)):
        if value is not None and not isinstance(value, str):
            raise InvalidInput(
                "invalid-kinematics",
                f"kinematics.{name} must be a link name",
                loc=("kinematics", name),
            )
    if len(text) > MAX_URDF_CHARS:
        raise _bad(f"the URDF has {len(text)} characters, more than {MAX_URDF_CHARS} accepted")
    return _chain(
        text, base if isinstance(base, str) else None, tip if isinstance(tip, str) else None
    )


@lru_cache(maxsize=16)
def _chain(text: str, base: str | None, tip: str | None) -> UrdfChain:
    """Parse and walk a URDF (cached: the same robot's URDF is read at every solve)."""
    _check_xml(text)
    model = _parse(text)
    links = [link.name for link in model.robot.links]
    by_child = _joints_by_child(list(model.robot.joints))
    base_link = _base_link(base, tip, links, by_child)
    base_path = _path_from_root(base_link, by_child)
    root = base_path[0].parent if base_path else base_link
    tip_link = tip if tip is not None else _default_tip(links, by_child, root)
    path = _path_from_root(tip_link, by_child)
    if (path[0].parent if path else tip_link) != root:
        raise InvalidInput(
            "invalid-kinematics",
            f"no path from base_link {base_link!r} to tip_link {tip_link!r}: they are in "
            "separate trees of the URDF (no chain of joints joins them); name a tip link on "
            "the arm that stands on the base",
            loc=("kinematics", "tip_link"),
        )
    moving_base = [j.name for j in base_path if j.type != "fixed"]
    if moving_base:
        raise InvalidInput(
            "invalid-kinematics",
            f"base_link {base_link!r} moves with joint {moving_base[0]!r}: the base must be "
            "fixed to the URDF's root",
            loc=("kinematics", "base_link"),
        )
    chain = tuple(_chain_joint(j) for j in path)
    if sum(j.kind != "fixed" for j in chain) > MAX_CHAIN_JOINTS:
        raise _bad(f"more than {MAX_CHAIN_JOINTS} movable joints from base to tip")
    base_rot, base_pos = Rotation.identity(), np.zeros(3)
    for joint in base_path:
        fixed = _chain_joint(joint)
        base_pos = base_pos + base_rot.apply(fixed.translation_mm)
        base_rot = base_rot * fixed.rotation
    return UrdfChain(
        robot=str(model.robot.name),
        base_link=base_link,
        tip_link=tip_link,
        joints=chain,
        base_rotation=base_rot,
        base_translation_mm=base_pos,
    )


def _joints_by_child(joints: list[_Joint]) -> dict[str, _Joint]:
    """Each joint by its child link; refuses a link that is the child of two (not a tree)."""
    by_child: dict[str, _Joint] = {}
    for joint in joints:
        if joint.child in by_child:
            raise _bad(f"link {joint.child!r} is the child of two joints: not a tree")
        by_child[joint.child] = joint
    return by_child


def _base_link(
    base: str | None, tip: str | None, links: list[str], by_child: dict[str, _Joint]
) -> str:
    """The base link: the one named, else the URDF's only root; the named links must exist."""
    roots = [name for name in links if name not in by_child]
    if base is None and len(roots) != 1:
        raise InvalidInput(
            "invalid-kinematics",
            f"the URDF has {len(roots)} root links ({', '.join(roots[:5])}): name the robot's "
            "base as base_link",
            loc=("kinematics", "base_link"),
        )
    base_link = base if base is not None else roots[0]
    for name, field in ((base_link, "base_link"), (tip, "tip_link")):
        if name is not None and name not in links:
            raise InvalidInput(
                "invalid-kinematics",
                f"the URDF has no link {name!r} (its links: {', '.join(links[:20])})",
                loc=("kinematics", field),
            )
    return base_link


def _check_xml(text: str) -> None:
    """Well-formed XML with a <robot> root. Undeclared namespace prefixes (`drake:`,
    `xacro:` attributes that real URDFs carry) are namespace-validity errors, not
    well-formedness ones: they are let through, as ROS's own parsers do."""
    parser = etree.XMLParser(
        resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False, recover=True
    )
    try:
        data = text.encode("utf-8")
    except UnicodeEncodeError as exc:
        raise _bad(f"the URDF is not valid text ({exc.reason} at character {exc.start})") from exc
    try:
        root = etree.fromstring(data, parser=parser)
    except etree.XMLSyntaxError as exc:
        raise _bad(f"the URDF is not well-formed XML: {exc}") from exc
    if root is not None and root.getroottree().docinfo.doctype:
        # entities would be expanded by the parser behind yourdfpy: no DTD at all
        raise _bad("the URDF carries a <!DOCTYPE>; a URDF needs none: remove it")
    errors = [e for e in parser.error_log if e.domain_name != "NAMESPACE" and e.level >= 2]
    if errors:
        first = errors[0]
        raise _bad(
            f"the URDF is not well-formed XML: {first.message.strip()} (line {first.line}, "
            f"column {first.column})"
        )
    if root is None or root.tag != "robot":
        tag = "nothing" if root is None else f"<{root.tag}>"
        raise _bad(f"a URDF's root element is <robot>, this one's is {tag}")


class _Quiet(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        return False


def _parse(text: str) -> _Model:
    import yourdfpy  # imported here: it pulls in trimesh, needed only for URDF robots

    log = logging.getLogger("yourdfpy")
    quiet = _Quiet()
    log.addFilter(quiet)
    try:
        model: _Model = yourdfpy.URDF.load(
            io.BytesIO(text.encode("utf-8")),
            build_scene_graph=False,
            build_collision_scene_graph=False,
            load_meshes=False,
            load_collision_meshes=False,
        )
        return model
    except Exception as exc:  # yourdfpy raises KeyError, TypeError, ValueError... on bad input
        raise _bad(f"the URDF could not be read ({type(exc).__name__}: {exc})") from exc
    finally:
        log.removeFilter(quiet)


def _path_from_root(link: str, by_child: Mapping[str, _Joint]) -> list[_Joint]:
    path = []
    seen = {link}
    while link in by_child:
        joint = by_child[link]
        path.append(joint)
        link = joint.parent
        if link in seen:
            raise _bad(f"the URDF's joints form a loop through link {link!r}")
        seen.add(link)
    return path[::-1]


def _default_tip(links: Sequence[str], by_child: Mapping[str, _Joint], root: str) -> str:
    """The leaf link with the most movable joints above it; refuse a tie (two grippers)."""
    parents = {j.parent for j in by_child.values()}
    leaves = [
        name
        for name in links
        if name not in parents
        and name != root
        and _path_from_root(name, by_child)[0].parent == root
    ]
    counted = [
        (sum(j.type != "fixed" for j in _path_from_root(leaf, by_child)), leaf) for leaf in leaves
    ]
    best = max((c for c, _ in counted), default=0)
    if best == 0:
        raise _bad("the URDF has no movable joint between its root and any link")
    tied = [leaf for c, leaf in counted if c == best]
    if len(tied) > 1:
        raise InvalidInput(
            "invalid-kinematics",
            f"the URDF's chain branches: {', '.join(tied[:5])} all end {best} movable joints "
            "from the root; name the link the tool is mounted on as tip_link",
            loc=("kinematics", "tip_link"),
        )
    return tied[0]


def _chain_joint(j: _Joint) -> ChainJoint:
    name, kind = str(j.name), str(j.type)
    if j.mimic is not None:
        raise _bad(
            f"joint {name!r} mimics joint {j.mimic.joint!r}: mimic joints are not supported "
            "(a serial arm's axes move independently); give a URDF of the arm alone"
        )
    if kind not in SUPPORTED:
        what = {
            "prismatic": "a linear axis (track): model the arm from its carriage, with "
            "base_link on it",
            "floating": "a free-floating joint: not an arm's axis",
            "planar": "a planar joint: not an arm's axis",
        }.get(kind, "a joint type the URDF specification does not define")
        raise _bad(
            f"joint {name!r} is {kind!r}, {what}; supported joints are revolute, continuous "
            "and fixed"
        )
    origin = np.asarray(j.origin if j.origin is not None else np.eye(4), dtype=np.float64)
    axis = np.asarray(j.axis if j.axis is not None else [1.0, 0.0, 0.0], dtype=np.float64)
    if kind != "fixed":
        norm = float(np.linalg.norm(axis))
        if not np.isfinite(norm) or norm < 1e-9:
            raise _bad(f"joint {name!r} has a zero or non-finite <axis>")
        axis = axis / norm
    if not np.all(np.isfinite(origin)):
        raise _bad(f"joint {name!r} has a non-finite <origin>")
    lower = upper = None
    limit = j.limit
    if kind == "revolute":
        if limit is None or limit.lower is None or limit.upper is None:
            raise _bad(f"revolute joint {name!r} has no <limit lower upper> (URDF requires it)")
        lower, upper = float(limit.lower), float(limit.upper)
        if not lower <= upper:
            raise _bad(f"joint {name!r} has lower limit {lower} above its upper limit {upper}")
    return ChainJoint(
        name=name,
        kind=kind,
        rotation=Rotation.from_matrix(origin[:3, :3]),
        translation_mm=origin[:3, 3] * 1000.0,
        axis=axis,
        lower_rad=lower,
        upper_rad=upper,
    )


def _bad(detail: str) -> InvalidInput:
    return InvalidInput("invalid-kinematics", detail, loc=_LOC)
