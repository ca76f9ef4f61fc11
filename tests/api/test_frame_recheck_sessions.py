"""A frame's re-check as a guided session (API.md v1.4: `"method": "recheck"`, issue 49):
the frame's stored fiducials touched again one by one, typed or captured from the robot's
controller (the KUKA simulator), next_role naming the next stored fiducial not yet touched,
finished as the frame's check (POST /v1/frames/{frame_id}/checks' answer, a FrameCheck)."""

from __future__ import annotations

import threading
from typing import Any

import numpy as np
import pytest
from sqlalchemy import select

from app.errors import InvalidInput
from app.services.checks import frame_recheck
from app.storage.db import session_scope
from app.storage.models import AuditEvent
from testbed.sim.cell_frames import FIXTURE_MM, touch_frame
from tests.api.controller_rigs import rig
from tests.api.frame_fiducials import NAMES, POINTER_TCP, calibrated_frame, cell, touches
from tests.api.test_capture_controllers import SETUPS
from tests.api.test_capture_controllers import secret_key as secret_key  # autouse
from tests.api.test_frame_checks import O_FIXTURE, R_FIXTURE, _moved_in_frame, _on_controller
from tests.conftest import Api

#: The move of test_frame_checks: 1.5 mm and 0.3 deg about the fixture's z.
ALONG = R_FIXTURE @ (1.5 * np.array([-300.0, 500.0, 0.0]) / np.hypot(300.0, 500.0))


def _recheck(api: Api, frame_id: str, tool_id: str, fmt: str, **options: Any) -> dict[str, Any]:
    body = {"method": "recheck", "tool_id": tool_id, "format": fmt, "options": options}
    made = api.post(f"/v1/frames/{frame_id}/sessions", body, scope="calibrate")
    assert made.status_code == 201, made.text
    return dict(made.json())


def _touch(api: Api, sid: str, **body: Any) -> Any:
    return api.post(f"/v1/sessions/{sid}/poses", body, scope="calibrate")


def test_typed_fiducial_touches_are_guided_and_finish_as_the_frames_check(api: Api) -> None:
    robot, pointer = cell(api)
    frame = calibrated_frame(
        api, robot["id"], "fixture-a", R_FIXTURE, O_FIXTURE, pointer_id=pointer["id"]
    )
    R1, o1 = _moved_in_frame(R_FIXTURE, O_FIXTURE, list(ALONG), 0.3)
    typed = touches(pointer["id"], R1, o1)["touches"]
    state = _recheck(
        api, frame["id"], pointer["id"], "matrix", correct="within_limits", reason="unbolted"
    )
    sid = state["id"]
    assert state["next"] == {"role": "a", "takes": "fiducial"}
    assert state["next_role"] == "touch fiducial 'a' again"
    refused = _touch(api, sid, fiducial="nope", pose=typed[0]["pose"])
    assert refused.status_code == 422, refused.text
    assert refused.json()["errors"][0]["loc"] == ["body", "fiducial"]
    assert "it has a, b, c, d, pin1, pin2" in refused.json()["detail"]
    for i, touch in enumerate(typed):
        added = _touch(api, sid, fiducial=touch["fiducial"], pose=touch["pose"])
        assert added.status_code == 200, added.text
        following = None if i == len(typed) - 1 else NAMES[i + 1]
        assert (added.json()["next"] or {}).get("role") == following
    again = _touch(api, sid, fiducial="a", pose=typed[0]["pose"])
    assert again.status_code == 422
    assert "already fiducial 'a'" in again.json()["detail"]
    assert api.get(f"/v1/sessions/{sid}").json()["done"] is True
    done = api.post(f"/v1/sessions/{sid}/finish", {}, scope="calibrate")
    assert done.status_code == 201, done.text
    check = done.json()
    assert check["verdict"] == "corrected"
    assert check["correction"]["version"] == 2
    assert check["shift"]["angle_deg"] == pytest.approx(0.3, abs=1e-9)
    assert api.get(f"/v1/sessions/{sid}").json()["status"] == "finished"
    twice = api.post(f"/v1/sessions/{sid}/finish", {}, scope="calibrate")
    assert twice.status_code == 409, twice.text


@pytest.mark.parametrize("protocol", ["kuka_kvp"])
def test_captured_fiducial_touches_of_a_moved_fixture_correct_it(api: Api, protocol: str) -> None:
    """Each fiducial read from the KUKA simulator (the still check of every capture): the
    fixture moved 1.5 mm / 0.3 deg is corrected, as the typed check corrects it."""
    with rig(protocol) as r:
        place = SETUPS[protocol](r)
        _, pointer, frame = _on_controller(api, r)  # the fixture at KUKA base 3
        R1, o1 = _moved_in_frame(R_FIXTURE, O_FIXTURE, list(ALONG), 0.3)
        moved = touch_frame(
            np.random.default_rng(49), FIXTURE_MM, frame=(R1, o1), tcp_mm=np.array(POINTER_TCP)
        )
        sid = _recheck(
            api, frame["id"], pointer["id"], "kuka_abc", correct="within_limits", deploy=False
        )["id"]
        for name, rot, pos in zip(NAMES, moved.rotations, moved.positions_mm, strict=True):
            place.place(rot, pos)
            added = _touch(api, sid, fiducial=name, capture=True)
            assert added.status_code == 200, added.text
        state = api.get(f"/v1/sessions/{sid}").json()
        assert [t["source"] for t in state["touches"]] == ["controller"] * len(NAMES)
        assert [t["fiducial"] for t in state["touches"]] == NAMES
        done = api.post(f"/v1/sessions/{sid}/finish", {}, scope="calibrate")
    assert done.status_code == 201, done.text
    check = done.json()
    assert check["verdict"] == "corrected"
    distances = [d["distance_mm"] for d in check["deviations"]]
    assert max(distances) == pytest.approx(1.5 + np.radians(0.3) * np.hypot(500, 300), abs=0.01)
    assert check["shift"]["angle_deg"] == pytest.approx(0.3, abs=1e-3)


def _touched_session(api: Api, **options: Any) -> tuple[dict[str, Any], str]:
    """A frame and a recheck session of it holding every fiducial of the moved fixture."""
    robot, pointer = cell(api)
    frame = calibrated_frame(
        api, robot["id"], "fixture-a", R_FIXTURE, O_FIXTURE, pointer_id=pointer["id"]
    )
    R1, o1 = _moved_in_frame(R_FIXTURE, O_FIXTURE, list(ALONG), 0.3)
    sid = _recheck(api, frame["id"], pointer["id"], "matrix", **options)["id"]
    for touch in touches(pointer["id"], R1, o1)["touches"]:
        added = _touch(api, sid, fiducial=touch["fiducial"], pose=touch["pose"])
        assert added.status_code == 200, added.text
    return frame, sid


def _finish_at_once(api: Api, sid: str, headers: list[dict[str, str]]) -> list[Any]:
    answers: list[Any] = []
    start = threading.Barrier(len(headers))

    def finish(extra: dict[str, str]) -> None:
        start.wait()
        answers.append(
            api.post(
                f"/v1/sessions/{sid}/finish",
                {},
                scope="calibrate",
                headers={**api.headers("calibrate"), **extra},
            )
        )

    threads = [threading.Thread(target=finish, args=(h,)) for h in headers]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return answers


def _checks_made(frame_id: str) -> int:
    with session_scope(write=False) as s:
        return len(
            s.scalars(
                select(AuditEvent.id).where(
                    AuditEvent.frame_id == frame_id, AuditEvent.action == "frame.check"
                )
            ).all()
        )


def test_concurrent_finishes_without_a_key_make_one_check_and_the_others_are_409(
    api: Api,
) -> None:
    frame, sid = _touched_session(api, correct="within_limits")
    before = _checks_made(frame["id"])
    answers = _finish_at_once(api, sid, [{}, {}, {}])
    assert sorted(a.status_code for a in answers) == [201, 409, 409], [a.text for a in answers]
    for refused in (a for a in answers if a.status_code == 409):
        assert refused.headers["content-type"].startswith("application/problem+json")
        problem = refused.json()
        assert problem["type"].endswith("/conflict")
        assert f"session {sid}" in problem["detail"]
        assert (
            "one finish makes one check" in problem["detail"]
            or "already finished" in (problem["detail"])
        )
    assert _checks_made(frame["id"]) == before + 1
    assert len(api.get(f"/v1/frames/{frame['id']}/versions").json()["items"]) == 2
    assert api.get(f"/v1/sessions/{sid}").json()["status"] == "finished"


def test_concurrent_finishes_with_one_key_make_one_check_and_answer_it_alike(api: Api) -> None:
    frame, sid = _touched_session(api, correct="within_limits")
    before = _checks_made(frame["id"])
    answers = _finish_at_once(api, sid, [{"Idempotency-Key": "finish-1"}] * 3)
    assert [a.status_code for a in answers] == [201, 201, 201], [a.text for a in answers]
    assert len({a.json()["id"] for a in answers}) == 1
    assert _checks_made(frame["id"]) == before + 1


def test_a_refused_finish_leaves_the_session_open_to_finish_again(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A check refused before anything is made gives the claim back: the session is open
    again, not finished without a check, and the next finish checks."""
    frame, sid = _touched_session(api, correct="within_limits")

    def refuse(**_: Any) -> Any:
        raise InvalidInput("invalid-pose", "refused before anything was made")

    with monkeypatch.context() as patched:
        patched.setattr(frame_recheck, "check_frame", refuse)
        refused = api.post(f"/v1/sessions/{sid}/finish", {}, scope="calibrate")
    assert refused.status_code == 422, refused.text
    assert api.get(f"/v1/sessions/{sid}").json()["status"] == "open"
    done = api.post(f"/v1/sessions/{sid}/finish", {}, scope="calibrate")
    assert done.status_code == 201, done.text
    assert done.json()["frame_id"] == frame["id"]


def test_a_finish_failing_after_its_check_was_made_leaves_the_session_finished(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A failure once the check's transaction has committed (its deployment, or anything after
    it) does not give the claim back: the session stays finished, audited with the check it
    made, and a second finish is 409 "already finished" rather than a second check."""
    frame, sid = _touched_session(api, correct="within_limits")
    before = _checks_made(frame["id"])

    def fail_after_storing(check: Any, replayed: bool) -> Any:
        raise OSError("the connection went away after the check was stored")

    with monkeypatch.context() as patched:
        patched.setattr(frame_recheck, "Checked", fail_after_storing)
        failed = api.post(f"/v1/sessions/{sid}/finish", {}, scope="calibrate")
    assert failed.status_code == 500, failed.text
    assert _checks_made(frame["id"]) == before + 1
    assert api.get(f"/v1/sessions/{sid}").json()["status"] == "finished"
    again = api.post(f"/v1/sessions/{sid}/finish", {}, scope="calibrate")
    assert again.status_code == 409, again.text
    assert "already finished" in again.json()["detail"]
    assert _checks_made(frame["id"]) == before + 1
