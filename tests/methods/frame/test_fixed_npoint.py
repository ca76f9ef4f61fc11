"""fixed_npoint through its request model: a stationary tip touched 8 times by a pointer whose
TCP is unknown (both found, noise-free within 0.01 mm), its axes from align or role touches,
and its refusals."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from app.errors import InvalidInput
from app.jsontypes import JsonObject
from app.solvers.frame import Pointer
from testbed.sim.cell_frames import flange_rotations, random_frame
from tests.methods.frame.bodies import angle_deg, poses, solve
from tests.methods.frame.given import GivenPointer

#: The pointer's TCP as its active version has it; the touches are made with another.
ACTIVE_TCP = np.array([1.5, -2.0, 180.0])


def _ctx(kind: str = "fixed_tool") -> GivenPointer:
    return GivenPointer.of(Pointer.of(ACTIVE_TCP, [0.02] * 3), kind=kind)  # type: ignore[arg-type]


def _tip_touches(rng: np.random.Generator, tip, tcp, n: int = 8):  # type: ignore[no-untyped-def]
    R = flange_rotations(rng, n, 40.0)
    return R, tip - np.einsum("nij,j->ni", R, tcp)


def _body(rows: list[list[float]], roles: list[str | None], **extra: object) -> JsonObject:
    return {
        "method": "fixed_npoint",
        "tool_id": "pointer",
        "format": "xyz_wxyz",
        "touches": [
            {"pose": p} if r is None else {"role": r, "pose": p}
            for p, r in zip(rows, roles, strict=True)
        ],
        **extra,
    }


def test_8_touches_with_an_unknown_pointer_tcp_give_the_tip_and_the_tcp() -> None:
    rng = np.random.default_rng(60)
    for _ in range(50):
        tip = rng.uniform(-600, 600, size=3)
        tcp = ACTIVE_TCP + rng.normal(0, 3, size=3)
        R, f = _tip_touches(rng, tip, tcp)
        body = _body(poses(R, f), [None] * 8, options={"align": {"z": "-z"}})
        solved = solve(body, _ctx())
        assert np.abs(solved.position_mm - tip).max() < 0.01
        assert solved.tool is not None
        assert solved.tool.version is None  # the active TCP is not used ...
        assert np.abs(np.array(solved.tool.tcp_found_mm) - tcp).max() < 0.01
        # ... but compared with the TCP found
        assert solved.tool.distance_from_active_mm == pytest.approx(
            float(np.linalg.norm(tcp - ACTIVE_TCP)), abs=0.01
        )
        np.testing.assert_allclose(
            Rotation.from_quat(solved.quaternion, scalar_first=True).as_matrix()[:, 2],
            [0, 0, -1],
            atol=1e-12,
        )
    assert "tip is within" in solved.summary
    assert "from its active one" in solved.summary
    assert [f.name for f in solved.fiducials] == ["tip"]


def test_no_align_and_no_roles_is_the_base_frames_axes() -> None:
    rng = np.random.default_rng(61)
    R, f = _tip_touches(rng, np.array([300.0, 200.0, 100.0]), ACTIVE_TCP)
    solved = solve(_body(poses(R, f), [None] * 8), _ctx())
    np.testing.assert_allclose(solved.quaternion, [1, 0, 0, 0], atol=1e-12)


def test_role_touches_give_the_tool_frames_axes() -> None:
    """Three more touches, of the tool frame's origin, +X and XY points, read with the TCP
    the tip touches found: over 200 seeded tool frames, the position (the tip) and the
    pointer's TCP to 1e-9 mm, the axes to 1e-9 deg."""
    rng = np.random.default_rng(62)
    for _ in range(200):
        frame_R, tip = random_frame(rng)
        tcp = ACTIVE_TCP + rng.normal(0, 3, size=3)
        R, f = _tip_touches(rng, tip, tcp)
        nominal = np.array([[0.0, 0, 0], [300, 0, 0], [80, 250, 0]])
        targets = nominal @ frame_R.T + tip
        Rr = flange_rotations(rng, 3, 20.0)
        fr = targets - np.einsum("nij,j->ni", Rr, tcp)
        rows = poses(np.concatenate([Rr[:1], R, Rr[1:]]), np.concatenate([fr[:1], f, fr[1:]]))
        roles: list[str | None] = ["origin", *[None] * 8, "x", "xy"]
        solved = solve(_body(rows, roles, options={"touch_noise_mm": 0.05}), _ctx())
        assert np.abs(solved.position_mm - tip).max() < 1e-9
        assert angle_deg(solved.quaternion, frame_R) < 1e-9
        assert solved.tool is not None
        assert np.abs(np.array(solved.tool.tcp_found_mm) - tcp).max() < 1e-9
        assert solved.quality.outliers == []
        assert solved.quality.angle_sigma_deg is not None
        assert max(solved.quality.angle_sigma_deg) > 0
    assert [f.name for f in solved.fiducials] == ["tip", "origin", "x", "xy"]
    np.testing.assert_allclose([f.nominal_mm for f in solved.fiducials[2:]], nominal[1:], atol=1e-6)


def _refused(body: JsonObject, ctx: GivenPointer | None = None) -> InvalidInput:
    with pytest.raises(InvalidInput) as caught:
        solve(body, ctx or _ctx())
    return caught.value


def test_a_base_frame_is_refused() -> None:
    rng = np.random.default_rng(63)
    R, f = _tip_touches(rng, np.array([300.0, 200.0, 100.0]), ACTIVE_TCP)
    error = _refused(_body(poses(R, f), [None] * 8), _ctx("base"))
    assert (error.kind, error.loc) == ("unsupported", ("method",))


def test_too_few_tip_touches_and_two_sources_of_axes_are_refused() -> None:
    rng = np.random.default_rng(64)
    R, f = _tip_touches(rng, np.array([300.0, 200.0, 100.0]), ACTIVE_TCP, n=6)
    error = _refused(_body(poses(R, f), ["origin", "x", "xy", None, None, None]))
    assert (error.kind, error.loc) == ("too-few-poses", ("touches",))
    error = _refused(
        _body(poses(R, f), [None, None, None, None, "origin", "x"], options={"align": {"z": "-z"}})
    )
    assert (error.kind, error.loc) == ("invalid-options", ("options", "align"))


def test_a_repeated_role_names_its_touch_in_the_body() -> None:
    rng = np.random.default_rng(65)
    R, f = _tip_touches(rng, np.array([300.0, 200.0, 100.0]), ACTIVE_TCP, n=7)
    roles: list[str | None] = [None, None, "x", None, None, "x", "xy"]
    error = _refused(_body(poses(R, f), roles, options={"touch_noise_mm": 0.05}))
    assert (error.kind, error.loc) == ("repeated-role", ("touches", 5, "role"))
    assert "touches 3 and 6" in error.detail
