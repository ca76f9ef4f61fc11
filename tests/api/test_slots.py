"""A tool's slot is one of its robot's controller's tool numbers (KUKA 1-16, Fanuc 1-10,
Yaskawa 0-63), at creation, on change, and when the robot's vendor changes."""

from __future__ import annotations

from typing import Any

import pytest

from app.services.robots.slots import numbered_vendor
from tests.conftest import Api


def _refused(response: Any, field: str, words: str) -> None:
    assert response.status_code == 422, response.text
    problem = response.json()
    assert problem["type"].endswith("/out-of-range")
    assert problem["errors"][0]["loc"] == ["body", field]
    assert words in problem["detail"]


@pytest.mark.parametrize(
    ("vendor", "bad", "good", "words"),
    [
        ("KUKA", 99, 16, "1-16"),
        ("Kuka Roboter GmbH", 0, 1, "1-16"),
        ("kuka", 17, 3, "1-16"),
        ("FANUC", 11, 10, "1-10"),
        ("Fanuc America", 0, 1, "1-10"),
        ("Yaskawa", 64, 0, "0-63"),
        ("YASKAWA Motoman", 64, 63, "0-63"),
        ("Motoman", 100, 63, "0-63"),
    ],
)
def test_slot_outside_the_vendors_tool_numbers_is_refused_at_creation(
    api: Api, vendor: str, bad: int, good: int, words: str
) -> None:
    robot = api.robot("r", vendor=vendor)
    _refused(api.post(f"/v1/robots/{robot['id']}/tools", {"name": "t", "slot": bad}), "slot", words)
    assert api.get(f"/v1/robots/{robot['id']}/tools").json()["items"] == []
    assert api.tool(robot["id"], "t", slot=good)["slot"] == good


@pytest.mark.parametrize("vendor", ["ABB", "Universal Robots", "UR", None, "Stäubli"])
def test_abb_ur_and_unknown_vendors_keep_any_slot(api: Api, vendor: str | None) -> None:
    robot = api.robot("r", **({} if vendor is None else {"vendor": vendor}))
    assert api.tool(robot["id"], "t", slot=99)["slot"] == 99


def test_slot_change_is_checked(api: Api) -> None:
    robot = api.robot("r", vendor="KUKA")
    tool = api.tool(robot["id"], "t", slot=3)
    _refused(api.patch(f"/v1/tools/{tool['id']}", {"slot": 99}), "slot", "1-16")
    assert api.get(f"/v1/tools/{tool['id']}").json()["slot"] == 3
    assert api.patch(f"/v1/tools/{tool['id']}", {"slot": 16}).json()["slot"] == 16
    assert api.patch(f"/v1/tools/{tool['id']}", {"slot": None}).json()["slot"] is None


def test_vendor_change_that_would_strand_a_tool_is_refused(api: Api) -> None:
    robot = api.robot("r", vendor="ABB")
    api.tool(robot["id"], "torch", slot=12)
    api.tool(robot["id"], "gripper", slot=2)
    refused = api.patch(f"/v1/robots/{robot['id']}", {"vendor": "FANUC"})
    _refused(refused, "vendor", "torch (slot 12)")
    assert "gripper" not in refused.json()["detail"]
    assert api.get(f"/v1/robots/{robot['id']}").json()["vendor"] == "ABB"
    assert api.patch(f"/v1/robots/{robot['id']}", {"vendor": "KUKA"}).status_code == 200


@pytest.mark.parametrize(
    ("vendor", "key"),
    [
        ("KUKA", "kuka"),
        (" kuka ", "kuka"),
        ("KUKA-Roboter", "kuka"),
        ("FANUC", "fanuc"),
        ("fanuc robotics", "fanuc"),
        ("Yaskawa Motoman", "yaskawa"),
        ("ABB", None),
        ("Universal Robots", None),
        ("Kukaesque", None),
        ("", None),
        (None, None),
    ],
)
def test_vendor_matching(vendor: str | None, key: str | None) -> None:
    assert numbered_vendor(vendor) == key
