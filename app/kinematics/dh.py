"""Forward kinematics of serial arms from Denavit-Hartenberg parameters.

Two conventions, as robot vendors publish them:

- ``"dh"`` (classic, distal; the tables of the makers' arms, app/vendors/*/arms.py): link i is
  ``Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``.
- ``"mdh"`` (modified, proximal; Craig): link i is
  ``Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i)``. Row i of a modified table carries
  ``a_{i-1}`` and ``alpha_{i-1}`` (the usual layout of such tables), so a `DHLink` holds them
  in ``a_mm`` and ``alpha_deg``.

In both, ``theta_i = q_i + theta_offset_i``. The base frame is frame 0 of the table and the
flange frame is its last frame; lengths mm, angles degrees. Rotations are composed with
scipy's `Rotation`; no angle is turned into a matrix by hand.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.kinematics.dh_table import CONVENTIONS as CONVENTIONS
from app.kinematics.dh_table import MAX_LINK_DEG as MAX_LINK_DEG
from app.kinematics.dh_table import MAX_LINK_MM as MAX_LINK_MM
from app.kinematics.dh_table import MAX_LINKS as MAX_LINKS
from app.kinematics.dh_table import Convention as Convention
from app.kinematics.dh_table import DHLink as DHLink
from app.kinematics.dh_table import Kinematics as Kinematics
from app.kinematics.urdf import UrdfChain, chain_from_spec
from app.solvers.validation import check_finite

_LINK_FIELDS = ("a", "alpha", "d", "theta_offset")


def _number(value: object, loc: tuple[str | int, ...], *, limit: float) -> float:
    """A finite real number within +-limit, else InvalidInput("invalid-options") at `loc`."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InvalidInput(
            "invalid-options",
            f"kinematics field {_dotted(loc)} must be a number, got {type(value).__name__}",
            loc=loc,
        )
    number = float(value)
    if not np.isfinite(number) or abs(number) > limit:
        raise InvalidInput(
            "invalid-options",
            f"kinematics field {_dotted(loc)} = {number!r} must be finite and within +-{limit:g}",
            loc=loc,
        )
    return number


def _dotted(loc: Sequence[str | int]) -> str:
    return ".".join(str(part) for part in loc)


def kinematics_from_spec(
    spec: Mapping[str, object], *, presets: Mapping[str, Kinematics]
) -> Kinematics | UrdfChain:
    """Read the API `kinematics` object: ``{"preset": name}``, ``{"convention", "links"}`` or
    ``{"urdf", "base_link"?, "tip_link"?}`` (app.kinematics.urdf).

    A preset is one of `presets`, by name: the makers' arms, which the caller reads from
    app.vendors.registry.PRESETS (the makers sit above app.kinematics).

    Links are ``[{a, alpha, d, theta_offset}]`` with a, d in mm and angles in degrees
    (``theta_offset`` may be omitted: 0). A defect raises InvalidInput("invalid-options")
    whose loc names the offending field, e.g. ("kinematics", "links", 2, "alpha").
    """
    base: tuple[str | int, ...] = ("kinematics",)
    if not isinstance(spec, Mapping):
        raise InvalidInput(
            "invalid-options",
            "kinematics must be an object: {'preset': 'ur5e'} or "
            "{'convention': 'dh' | 'mdh', 'links': [{a, alpha, d, theta_offset}]}",
            loc=base,
        )
    # A serialised union model may carry the other variant's fields as None: not given.
    spec = {key: value for key, value in spec.items() if value is not None}
    if "urdf" in spec:
        return chain_from_spec(spec)
    if "preset" in spec:
        return _preset_from_spec(spec, base, presets)
    unknown = sorted(set(spec) - {"convention", "links", "name"})
    if unknown:
        raise InvalidInput(
            "invalid-options",
            f"unknown kinematics field {unknown[0]!r}; expected 'preset' or "
            "'convention' and 'links'",
            loc=(*base, unknown[0]),
        )
    convention = spec.get("convention")
    if convention not in CONVENTIONS:
        raise InvalidInput(
            "invalid-options",
            f"kinematics.convention must be one of {list(CONVENTIONS)}, got {convention!r}",
            loc=(*base, "convention"),
        )
    name = spec.get("name")
    return Kinematics(
        convention=convention,
        links=_links_from_spec(spec.get("links"), base),
        name=name if isinstance(name, str) else None,
    )


def _preset_from_spec(
    spec: Mapping[str, object], base: tuple[str | int, ...], presets: Mapping[str, Kinematics]
) -> Kinematics:
    """The preset of `presets` ``{"preset": name}`` names, refusing other fields and unknown
    names."""
    extra_keys = sorted(set(spec) - {"preset"})
    if extra_keys:
        raise InvalidInput(
            "invalid-options",
            f"kinematics with a preset takes no other fields; got {extra_keys}",
            loc=(*base, extra_keys[0]),
        )
    name = spec["preset"]
    if not isinstance(name, str) or name not in presets:
        raise InvalidInput(
            "invalid-options",
            f"unknown kinematics preset {name!r}; known presets: {sorted(presets)}",
            loc=(*base, "preset"),
        )
    return presets[name]


def _links_from_spec(links_in: object, base: tuple[str | int, ...]) -> tuple[DHLink, ...]:
    """The links of ``{"links": [{a, alpha, d, theta_offset}]}``: 1 to MAX_LINKS, checked."""
    if not isinstance(links_in, Sequence) or isinstance(links_in, str | bytes):
        raise InvalidInput(
            "invalid-options",
            "kinematics.links must be a list of {a, alpha, d, theta_offset}",
            loc=(*base, "links"),
        )
    if not 1 <= len(links_in) <= MAX_LINKS:
        raise InvalidInput(
            "invalid-options",
            f"kinematics.links must have 1 to {MAX_LINKS} links, got {len(links_in)}",
            loc=(*base, "links"),
        )
    return tuple(_link_from_row(row, (*base, "links", i)) for i, row in enumerate(links_in))


def _link_from_row(row: object, here: tuple[str | int, ...]) -> DHLink:
    """One link ``{a, alpha, d, theta_offset?}`` at loc `here` (..., "links", i)."""
    i = here[-1]
    if not isinstance(row, Mapping):
        raise InvalidInput(
            "invalid-options",
            f"kinematics.links.{i} must be an object {{a, alpha, d, theta_offset}}",
            loc=here,
        )
    bad = sorted(set(row) - set(_LINK_FIELDS))
    if bad:
        raise InvalidInput(
            "invalid-options",
            f"kinematics.links.{i} has unknown field {bad[0]!r}; expected {list(_LINK_FIELDS)}",
            loc=(*here, bad[0]),
        )
    for required in ("a", "alpha", "d"):
        if required not in row:
            raise InvalidInput(
                "invalid-options",
                f"kinematics.links.{i}.{required} is missing",
                loc=(*here, required),
            )
    return DHLink(
        a_mm=_number(row["a"], (*here, "a"), limit=MAX_LINK_MM),
        alpha_deg=_number(row["alpha"], (*here, "alpha"), limit=MAX_LINK_DEG),
        d_mm=_number(row["d"], (*here, "d"), limit=MAX_LINK_MM),
        theta_offset_deg=_number(
            row.get("theta_offset", 0.0), (*here, "theta_offset"), limit=MAX_LINK_DEG
        ),
    )


def _check_joints(
    kinematics: Kinematics, joints_deg: ArrayLike, loc: Sequence[str | int]
) -> FloatArray:
    """(N, n) joint angles in degrees, finite, n matching the model."""
    q = check_finite(joints_deg, loc=loc)
    if q.ndim != 2 or q.shape[1] != kinematics.n_joints:
        raise InvalidInput(
            "invalid-pose",
            f"joint angles must have shape (N, {kinematics.n_joints}) for this "
            f"{kinematics.n_joints}-axis model, got {q.shape}",
            loc=loc,
        )
    return q


def flange_poses(
    kinematics: Kinematics,
    joints_deg: ArrayLike,
    *,
    loc: Sequence[str | int] = ("poses",),
) -> tuple[FloatArray, FloatArray]:
    """Flange poses in the base frame for (N, n) joint angles in degrees.

    Returns ``(base_from_flange rotations (N, 3, 3), flange positions (N, 3) mm)``.
    """
    q = _check_joints(kinematics, joints_deg, loc)
    n_poses = q.shape[0]
    rotation = Rotation.identity(n_poses) if n_poses else Rotation.identity()
    position = np.zeros((n_poses, 3))
    if n_poses == 0:
        return np.zeros((0, 3, 3)), position
    z_axis = np.array([0.0, 0.0, 1.0])
    x_axis = np.array([1.0, 0.0, 0.0])
    for i, link in enumerate(kinematics.links):
        theta = np.radians(q[:, i] + link.theta_offset_deg)
        rot_theta = Rotation.from_rotvec(theta[:, None] * z_axis)
        rot_alpha = Rotation.from_rotvec(np.radians(link.alpha_deg) * x_axis)
        if kinematics.convention == "dh":
            # T = Rz(theta) Tz(d) Tx(a) Rx(alpha)
            rotation = rotation * rot_theta
            position = position + rotation.apply(np.array([link.a_mm, 0.0, link.d_mm]))
            rotation = rotation * rot_alpha
        else:
            # T = Rx(alpha) Tx(a) Rz(theta) Tz(d)
            rotation = rotation * rot_alpha
            position = position + rotation.apply(np.array([link.a_mm, 0.0, 0.0]))
            rotation = rotation * rot_theta
            position = position + rotation.apply(np.array([0.0, 0.0, link.d_mm]))
    matrices: FloatArray = rotation.as_matrix().reshape(n_poses, 3, 3)
    return matrices, position


def flange_pose(kinematics: Kinematics, joints_deg: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Flange pose for one set of n joint angles in degrees: (R (3, 3), position (3,) mm)."""
    q = np.asarray(joints_deg, dtype=np.float64).reshape(1, -1)
    rotations, positions = flange_poses(kinematics, q, loc=("joints",))
    return rotations[0], positions[0]
