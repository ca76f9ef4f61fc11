"""GET /v1/formats and the formats in GET /v1/methods: enough to write a pose, no docstring."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from app.kinematics.poses import POSE_FORMATS, pose_from_format
from app.vendors.registry import MAKERS
from tests.conftest import Api


def test_every_format_is_listed_with_components_units_and_rotation(api: Api) -> None:
    response = api.get("/v1/formats")
    assert response.status_code == 200, response.text
    items = {f["name"]: f for f in response.json()["items"]}
    assert list(items) == list(POSE_FORMATS)
    assert items["kuka_abc"]["components"] == ["X", "Y", "Z", "A", "B", "C"]
    assert items["kuka_abc"]["default_units"] == {"length": "mm", "angle": "deg"}
    assert "Rz(A) Ry(B) Rx(C)" in items["kuka_abc"]["rotation"]
    assert items["ur_rotvec"]["default_units"] == {"length": "m", "angle": "rad"}
    assert "RPY" in items["ur_rotvec"]["rotation"]
    assert items["xyz_wxyz"]["components"] == ["x", "y", "z", "qw", "qx", "qy", "qz"]
    assert items["xyz_xyzw"]["components"][3:] == ["qx", "qy", "qz", "qw"]
    assert items["joints"]["arity"] is None
    for info in items.values():
        if info["arity"] is not None:
            assert info["arity"] == len(info["components"])
        assert info["rotation"]
    # which maker's pendant shows each format is its declaration's (Maker.pose_format)
    for maker in MAKERS:
        shown = items[maker.pose_format]["rotation"]
        assert f"the pose format of the {maker.name} pendant" in shown
    assert "pendant" not in items["xyz_xyzw"]["rotation"]  # no maker's: ROS's


def test_a_pose_written_from_the_listing_reads_back_as_meant(api: Api) -> None:
    """Follow the listing literally for kuka_abc: A about Z, B about Y, C about X, in degrees."""
    info = next(f for f in api.get("/v1/formats").json()["items"] if f["name"] == "kuka_abc")
    values = dict(zip(info["components"], [500.0, 20.0, 300.0, 30.0, -10.0, 170.0], strict=True))
    rotation, position = pose_from_format("kuka_abc", list(values.values()))
    expected = Rotation.from_euler("ZYX", [values["A"], values["B"], values["C"]], degrees=True)
    assert np.allclose(rotation, expected.as_matrix(), atol=1e-12)
    assert np.allclose(position, [500.0, 20.0, 300.0])


def test_methods_list_their_formats_and_every_format(api: Api) -> None:
    body = api.get("/v1/methods").json()
    assert [f["name"] for f in body["formats"]] == list(POSE_FORMATS)
    methods = {m["name"]: m for m in body["items"]}
    assert methods["xyz_npoint"]["formats"] == list(POSE_FORMATS)
    assert methods["manual"]["formats"] == []


def test_the_formats_that_number_their_tools_are_listed_with_the_numbers(api: Api) -> None:
    """The console tells a tool without a slot why its .LS and TOOL.CND are not offered, with
    the numbers the controller takes (the vendors' ranges, cited in each maker's package,
    app/vendors/<maker>/__init__.py)."""
    body = api.get("/v1/formats").json()
    assert body["tool_numbers"] == {"kuka": [1, 16], "fanuc": [1, 10], "yaskawa": [0, 63]}
    assert set(body["tool_numbers"]) <= set(body["controller_files"])
