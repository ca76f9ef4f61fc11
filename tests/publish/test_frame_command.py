"""The MQTT command `{prefix}/commands/recheck-frame` (issue 49) runs the frame's re-check
after a move as POST /v1/frames/{frame_id}/checks does, its request_id the Idempotency-Key:
answered with the FrameCheck, a repeat with the first answer and no second version, a
malformed one with the HTTP layer's 422 naming the field."""

from __future__ import annotations

import json

import numpy as np

from app.publish.commands import RECHECK_FRAME, answer, command_of, recheck_topic
from tests.api.frame_fiducials import calibrated_frame, cell, touches
from tests.conftest import Api


def test_a_frame_command_corrects_once_and_a_repeat_gets_the_first_answer(api: Api) -> None:
    robot, pointer = cell(api)
    R, o = np.eye(3), np.array([500.0, 0.0, 0.0])
    frame = calibrated_frame(api, robot["id"], "fixture", R, o, pointer_id=pointer["id"])
    moved = touches(pointer["id"], R, o + np.array([1.0, 0.5, 0.0]))
    command = {"request_id": "plc-7", "frame_id": frame["id"], **moved, "correct": "within_limits"}
    payload = json.dumps(command).encode()
    assert command_of("cell", recheck_topic("cell", RECHECK_FRAME)) == RECHECK_FRAME
    first = answer("cell", payload, api.keys["calibrate"], RECHECK_FRAME)
    assert (first.topic, first.status, first.replayed) == ("cell/replies/plc-7", 201, False)
    check = json.loads(first.payload)
    assert check["verdict"] == "corrected"
    assert check["correction"]["version"] == 2
    again = answer("cell", payload, f"Bearer {api.keys['calibrate']}", RECHECK_FRAME)
    assert (again.status, again.replayed) == (201, True)
    assert json.loads(again.payload)["id"] == check["id"]
    assert len(api.get(f"/v1/frames/{frame['id']}/versions").json()["items"]) == 2


def test_a_frame_command_without_its_frame_or_touches_is_refused_naming_them(api: Api) -> None:
    reply = answer(
        "cell", json.dumps({"request_id": "plc-8"}).encode(), api.keys["calibrate"], RECHECK_FRAME
    )
    assert reply.status == 422
    locs = [e["loc"] for e in json.loads(reply.payload)["errors"]]
    assert ["body", "frame_id"] in locs
    assert ["body", "touches"] in locs
    read = answer(
        "cell", json.dumps({"request_id": "plc-9"}).encode(), api.keys["read"], RECHECK_FRAME
    )
    assert read.status == 403
