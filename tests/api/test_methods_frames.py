"""GET /v1/methods lists the frame methods beside the tools', with their touches' roles."""

from __future__ import annotations

from app.api.methods import describe
from app.methods import METHODS
from app.methods.frame import FRAME_METHOD_NAMES
from app.solvers.frame import FOUR_POINT, THREE_POINT
from tests.conftest import Api


def test_the_frame_methods_are_listed_with_their_roles(api: Api) -> None:
    body = api.get("/v1/methods").json()
    # the tools' entries are as before
    assert body["items"] == [describe(m).model_dump(mode="json") for m in METHODS]
    frames = {m["name"]: m for m in body["frame_methods"]}
    assert list(frames) == list(FRAME_METHOD_NAMES)
    three = frames["three_point"]
    assert (three["min_touches"], three["max_touches"]) == (3, 3)
    assert three["touch_fields"] == {"role": True}
    for convention, construction in THREE_POINT.items():
        listed = [r["role"] for r in three["roles"] if r["convention"] == convention]
        assert listed == list(construction.roles)
    assert three["options"]["convention"]["default"] == "origin_x_xy"
    assert three["options"]["max_angle_sigma_deg"]["default"] == 0.05
    assert [r["role"] for r in frames["four_point"]["roles"]] == list(FOUR_POINT.roles)
    assert frames["fit_points"]["touch_fields"] == {"nominal_mm": True}
    assert frames["fixed_npoint"]["kinds"] == ["fixed_tool"]
    assert frames["fixed_npoint"]["touch_fields"] == {"role": False}
    assert "tool_id" not in frames["fixed_npoint"]["requires"]
    assert frames["manual"]["min_touches"] == frames["manual"]["max_touches"] == 0
