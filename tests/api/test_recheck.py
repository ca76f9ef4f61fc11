"""A re-check after a collision (issue 41) beyond the simulators' happy path, against the
KUKA simulator: Idempotency-Key, a deployment that fails, the audit chain, the propagated
uncertainty, corrections in the drift trend and `frequent_corrections`, and bad input."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from datetime import timedelta
from typing import Any

import numpy as np
import pytest

from app.storage.models import utcnow
from tests.api.controller_rigs import rig
from tests.api.test_capture_controllers import SETUPS, Cell
from tests.api.test_recheck_controllers import (
    ACTIVE_POSITION,
    CRASHED,
    MOVED,
    STANDING,
    TABLES,
    recheck,
    stand_at_reference,
    tool_at_reference,
)
from tests.api.touches import row_counts
from tests.conftest import Api
from tests.controllers.simbase import go_silent


@pytest.fixture
def kuka() -> Iterator[Cell]:
    with rig("kuka_kvp") as r:
        yield SETUPS["kuka_kvp"](r)


def _audit(api: Api, tool_id: str) -> list[dict[str, Any]]:
    """The tool's audit events, oldest first."""
    found = api.get("/v1/audit", params={"tool_id": tool_id, "limit": 200}, scope="admin")
    assert found.status_code == 200, found.text
    return list(reversed(found.json()["items"]))


def _row(api: Api, tool_id: str) -> dict[str, Any]:
    rows = {r["id"]: r for r in api.get("/v1/tools?limit=500").json()["items"]}
    return dict(rows[tool_id])


def test_a_repeated_idempotency_key_gets_the_first_answer_and_nothing_is_done_twice(
    api: Api, kuka: Cell
) -> None:
    tool, point_id = tool_at_reference(api, kuka.rig)
    stand_at_reference(kuka, np.asarray(ACTIVE_POSITION) + MOVED)
    key = {"Idempotency-Key": "crash-0312"}
    first = recheck(api, tool["id"], point_id, headers=key)
    assert first.status_code == 201, first.text
    assert first.json()["verdict"] == "corrected"
    assert "Idempotent-Replayed" not in first.headers
    counts, events, held = row_counts(TABLES), len(_audit(api, tool["id"])), kuka.rig.native()
    # the robot is elsewhere now: a second check would find something else, and correct it
    stand_at_reference(kuka, np.asarray(ACTIVE_POSITION) + 2 * MOVED)
    again = recheck(api, tool["id"], point_id, headers=key)
    assert again.status_code == 201, again.text
    assert again.headers["Idempotent-Replayed"] == "true"
    assert again.json() == first.json()  # the deployment's verified status included
    assert row_counts(TABLES) == counts
    assert len(_audit(api, tool["id"])) == events
    assert kuka.rig.native() == held
    other = recheck(api, tool["id"], point_id, headers=key, reason="another body")
    assert other.status_code == 409, other.text
    assert other.json()["type"].endswith("/idempotency-key-reused")


def test_a_failed_deployment_leaves_the_correction_active_and_flags_the_controller(
    api: Api, kuka: Cell, monkeypatch: pytest.MonkeyPatch
) -> None:
    r = kuka.rig
    tool, point_id = tool_at_reference(api, r)
    held = r.native()
    stand_at_reference(kuka, np.asarray(ACTIVE_POSITION) + MOVED)
    monkeypatch.setattr(r.sim, "set_var", lambda name, value: False)  # the KRC refuses writes
    done = recheck(api, tool["id"], point_id)
    assert done.status_code == 201, done.text
    check = done.json()
    assert check["verdict"] == "deployment_failed"
    deployment = check["correction"]["deployment"]
    assert (deployment["status"], deployment["version"]) == ("not_written", 2)
    assert deployment["error"]["type"] == "controller-refused"
    assert "version 2 (version 1 moved by" in check["summary"]
    assert "is active in tcpcal, but its deployment to $TOOL_DATA[3] failed" in check["summary"]
    assert "nothing was written" in check["summary"]
    assert "the controller is flagged: deploy version 2 again" in check["summary"]
    assert api.get(f"/v1/tools/{tool['id']}/tcp").json()["version"] == 2
    assert r.native() == held  # the controller kept what it held
    row = _row(api, tool["id"])
    assert row["attention"] == ["controller_drifted"]
    assert row["controller"]["state"] == "drifted"


def test_the_audit_shows_the_chain_check_version_activation_deployment(
    api: Api, kuka: Cell
) -> None:
    tool, point_id = tool_at_reference(api, kuka.rig)
    before = len(_audit(api, tool["id"]))
    stand_at_reference(kuka, np.asarray(ACTIVE_POSITION) + MOVED)
    done = recheck(api, tool["id"], point_id, reason="wire stuck, torch bent")
    assert done.status_code == 201, done.text
    chain = _audit(api, tool["id"])[before:]
    assert [e["action"] for e in chain] == [
        "tool.check",
        "version.create",
        "calibration.create",
        "version.activate",
        "tool.deploy",
    ]
    check, created, calibration, activation, deploy = chain
    assert check["version"] == 1  # the version it measured
    assert check["detail"]["verdict"] == "corrected"
    assert check["detail"]["correction"]["version"] == 2
    assert check["detail"]["sources"][0]["source"] == "controller"
    # recorded before the deployment: the check says one follows, tool.deploy says how it went
    follows = "is active; its deployment to the controller follows"
    assert check["detail"]["summary"].endswith(follows)
    [record] = api.get(f"/v1/tools/{tool['id']}/checks").json()["items"]
    assert (record["verdict"], record["correction_version"]) == ("corrected", 2)
    assert (created["version"], created["detail"]["source"]) == (2, "xyz_reference")
    assert calibration["detail"]["method"] == "xyz_reference"
    assert activation["detail"]["kind"] == "check_correction"
    assert activation["detail"]["reason"] == "wire stuck, torch bent"
    assert activation["detail"]["checked_version"] == 1
    np.testing.assert_allclose(activation["detail"]["delta_mm"], MOVED, atol=0.02)
    assert (deploy["detail"]["version"], deploy["detail"]["status"]) == (2, "verified")
    assert deploy["detail"]["reason"] == "wire stuck, torch bent"


def test_the_reference_points_uncertainty_is_the_new_versions(api: Api, kuka: Cell) -> None:
    """Cov(t) = R^T Cov(r) R for one touch of r with no touch noise configured (METHODS.md,
    xyz_reference): the corrected version carries it, as its calibration's covariance."""
    tool, _ = tool_at_reference(api, kuka.rig)
    cov_r = np.diag([0.01, 0.04, 0.09])
    point = api.post(
        f"/v1/robots/{tool['robot_id']}/reference-points",
        {
            "name": "fixture",
            "position_mm": [820.0, -140.0, 305.0],
            "covariance_mm2": cov_r.tolist(),
        },
        scope="calibrate",
    )
    assert point.status_code == 201, point.text
    stand_at_reference(kuka, np.asarray(ACTIVE_POSITION) + MOVED)
    done = recheck(api, tool["id"], point.json()["id"], deploy=False)
    assert done.status_code == 201, done.text
    assert done.json()["correction"]["deployment"] is None
    assert "not deployed: deploy it before the robot runs with it" in done.json()["summary"]
    version = api.get(f"/v1/tools/{tool['id']}/versions/2").json()
    calibration = api.get(f"/v1/calibrations/{version['calibration_id']}").json()
    cov_t = np.asarray(calibration["quality"]["tcp_covariance_mm2"])
    # to 1e-6 mm^2: the flange's angles come back as the controller prints them
    np.testing.assert_allclose(cov_t, STANDING.T @ cov_r @ STANDING, atol=1e-6)
    assert cov_t[0, 0] != pytest.approx(0.01)  # turned by the touch's orientation, not copied
    sigma = np.asarray(calibration["quality"]["tcp_sigma_mm"])
    np.testing.assert_allclose(sigma, np.sqrt(np.diag(cov_t)), rtol=1e-9)


def test_corrections_are_versions_of_the_drift_trend_and_frequent_ones_are_flagged(
    api: Api, kuka: Cell, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A tool hit four times in four days: each correction is a point of the versions'
    trend, and more than TCPCAL_CORRECTIONS_ALERT (3) corrections in 30 days flag it."""
    import app.services.calibrations.writes as writes

    tool, point_id = tool_at_reference(api, kuka.rig)
    start = utcnow() - timedelta(days=4)
    for day in range(1, 5):
        monkeypatch.setattr(writes, "utcnow", lambda day=day: start + timedelta(days=day))
        stand_at_reference(kuka, np.asarray(ACTIVE_POSITION) + day * MOVED)
        done = recheck(api, tool["id"], point_id, deploy=False)
        assert done.json()["verdict"] == "corrected", done.text
        codes = _row(api, tool["id"])["attention"]
        assert ("frequent_corrections" in codes) == (day == 4), (day, codes)
    drift = api.get(f"/v1/tools/{tool['id']}/drift").json()
    assert drift["versions"]["n"] == 4  # the manual v1 is no measurement; v2..v5 are
    rate = np.asarray(drift["versions"]["rate_mm_per_month"])
    np.testing.assert_allclose(rate, MOVED * 30.44, rtol=0.01)


def test_only_corrections_of_the_last_30_days_count_toward_frequent_corrections(
    api: Api, kuka: Cell
) -> None:
    """Four corrections, the first activated 31 days ago: three in 30 days is not more than
    TCPCAL_CORRECTIONS_ALERT (3), so the tool is not flagged; the first moved back to 29
    days ago makes four, and it is."""
    from sqlalchemy import update

    from app.storage.db import get_engine
    from app.storage.models import Activation

    tool, point_id = tool_at_reference(api, kuka.rig)
    for hit in range(1, 5):
        stand_at_reference(kuka, np.asarray(ACTIVE_POSITION) + hit * MOVED)
        done = recheck(api, tool["id"], point_id, deploy=False)
        assert done.json()["verdict"] == "corrected", done.text
    assert "frequent_corrections" in _row(api, tool["id"])["attention"]

    def first_correction_activated(days_ago: int) -> None:
        with get_engine().begin() as conn:
            moved = conn.execute(
                update(Activation)
                .where(
                    Activation.tool_id == tool["id"],
                    Activation.reason == "check_correction",
                    Activation.version == 2,
                )
                .values(activated_at=utcnow() - timedelta(days=days_ago))
            )
            assert moved.rowcount == 1

    first_correction_activated(31)
    assert "frequent_corrections" not in _row(api, tool["id"])["attention"]
    first_correction_activated(29)
    assert "frequent_corrections" in _row(api, tool["id"])["attention"]


def test_alert_threshold_is_read_from_the_environment(
    api: Api, kuka: Cell, monkeypatch: pytest.MonkeyPatch
) -> None:
    from app.config import get_settings

    monkeypatch.setenv("TCPCAL_CORRECTIONS_ALERT", "0")
    get_settings.cache_clear()
    try:
        tool, point_id = tool_at_reference(api, kuka.rig)
        assert "frequent_corrections" not in _row(api, tool["id"])["attention"]
        stand_at_reference(kuka, np.asarray(ACTIVE_POSITION) + MOVED)
        assert recheck(api, tool["id"], point_id, deploy=False).status_code == 201
        assert "frequent_corrections" in _row(api, tool["id"])["attention"]
    finally:
        get_settings.cache_clear()


def test_correct_never_measures_and_changes_nothing(api: Api, kuka: Cell) -> None:
    tool, point_id = tool_at_reference(api, kuka.rig)
    stand_at_reference(kuka, np.asarray(ACTIVE_POSITION) + MOVED)
    counts = row_counts(TABLES)
    body = {"capture": True, "reference_point_id": point_id}
    done = api.post(f"/v1/tools/{tool['id']}/checks", body, scope="calibrate")
    assert done.status_code == 201, done.text
    assert (done.json()["verdict"], done.json()["correction"]) == ("out_of_tolerance", None)
    assert row_counts(TABLES) == counts
    assert _row(api, tool["id"])["attention"] == ["check_failed"]


def test_a_correction_beyond_the_limit_keeps_check_failed(api: Api, kuka: Cell) -> None:
    tool, point_id = tool_at_reference(api, kuka.rig)
    stand_at_reference(kuka, np.asarray(ACTIVE_POSITION) + CRASHED)
    assert recheck(api, tool["id"], point_id).json()["verdict"] == "recalibrate"
    assert _row(api, tool["id"])["attention"] == ["check_failed"]


@pytest.mark.parametrize(
    ("extra", "words"),
    [
        ({"correct": "within_limits"}, 'send "capture": true in place of format and poses'),
        ({"deploy": True}, '"deploy" applies to a correction'),
        ({"correct": "always"}, "never"),
        ({"reason": ""}, "at least 1 character"),
    ],
)
def test_a_correction_asked_of_typed_touches_or_malformed_is_422(
    api: Api, kuka: Cell, extra: dict[str, Any], words: str
) -> None:
    # A pairing the schema allows (typed touches with correct or deploy) is refused for its
    # meaning, /invalid-options naming the field; a value the schema refuses is /validation
    # (the contract test holds that a schema-valid request never meets /validation).
    tool, point_id = tool_at_reference(api, kuka.rig)
    body = {
        "reference_point_id": point_id,
        "format": "xyz_wxyz",
        "poses": [[800, -140, 130, 0, 1, 0, 0]],
        **extra,
    }
    counts = row_counts(TABLES)
    refused = api.post(f"/v1/tools/{tool['id']}/checks", body, scope="calibrate")
    assert refused.status_code == 422, refused.text
    problem = refused.json()
    assert words in problem["detail"]
    pairing = set(extra) <= {"correct", "deploy"} and extra.get("correct") != "always"
    expected = "/invalid-options" if pairing else "/validation"
    assert problem["type"].endswith(expected), problem
    if pairing:
        assert problem["errors"][0]["loc"] == ["body", next(iter(extra))], problem
    assert row_counts(TABLES) == counts


@pytest.mark.parametrize("value", [0, -1.0, "2", None, True])
def test_max_correction_mm_must_be_a_positive_number(api: Api, value: Any) -> None:
    robot = api.robot()
    body = {"name": "t", "tolerance": {"max_correction_mm": value}}
    refused = api.post(f"/v1/robots/{robot['id']}/tools", body)
    assert refused.status_code == 422, refused.text
    assert "max_correction_mm" in refused.text
    tool = api.tool(robot["id"], "ok", tolerance={"max_correction_mm": 3.5})
    assert tool["tolerance"]["max_correction_mm"] == 3.5
    assert api.tool(robot["id"], "default")["tolerance"]["max_correction_mm"] == 2.0


def test_a_correction_the_controller_could_not_take_is_refused_before_the_robot_is_read(
    api: Api, kuka: Cell
) -> None:
    """A tool without its slot could be checked but not deployed: the re-check is refused
    before anything is read or written, naming the field, unless told not to deploy."""
    tool, point_id = tool_at_reference(api, kuka.rig)
    patched = api.request("PATCH", f"/v1/tools/{tool['id']}", "admin", json={"slot": None})
    assert patched.status_code == 200, patched.text
    stand_at_reference(kuka, np.asarray(ACTIVE_POSITION) + MOVED)
    counts, events = row_counts(TABLES), len(_audit(api, tool["id"]))
    refused = recheck(api, tool["id"], point_id)
    assert refused.status_code == 422, refused.text
    assert refused.json()["field"] == "slot"
    assert row_counts(TABLES) == counts
    assert len(_audit(api, tool["id"])) == events
    done = recheck(api, tool["id"], point_id, deploy=False)
    assert done.json()["verdict"] == "corrected", done.text


def test_a_tcp_within_tolerance_is_left_alone(api: Api, kuka: Cell) -> None:
    tool, point_id = tool_at_reference(api, kuka.rig)
    stand_at_reference(kuka, np.asarray(ACTIVE_POSITION) + MOVED / 4)  # 0.24 mm, check_mm 0.5
    counts = row_counts(TABLES)
    done = recheck(api, tool["id"], point_id)
    assert done.status_code == 201, done.text
    assert (done.json()["verdict"], done.json()["correction"]) == ("within_tolerance", None)
    assert done.json()["summary"].startswith("within tolerance")
    assert row_counts(TABLES) == counts
    assert _row(api, tool["id"])["attention"] == []


def test_a_controller_silent_at_the_write_is_flagged_unreachable_and_said(
    api: Api, kuka: Cell
) -> None:
    """The KRC stops answering as the correction is written: the deployment is unverified
    (it may hold either frame), the new version stays active, the controller is flagged
    unreachable and the answer says what to do."""
    r = kuka.rig
    tool, point_id = tool_at_reference(api, r)
    stand_at_reference(kuka, np.asarray(ACTIVE_POSITION) + MOVED)
    r.sim.fault = go_silent("before", "write $TOOL_DATA[3]")
    done = recheck(api, tool["id"], point_id)
    assert done.status_code == 201, done.text
    check = done.json()
    assert check["verdict"] == "deployment_failed"
    assert check["correction"]["deployment"]["status"] == "unverified"
    assert "the controller may hold v2 or v1" in check["summary"]
    assert "the controller is flagged" in check["summary"]
    assert api.get(f"/v1/tools/{tool['id']}/tcp").json()["version"] == 2
    row = _row(api, tool["id"])
    assert row["attention"] == ["controller_unreachable"]


def test_one_key_sent_four_times_at_once_corrects_once(api: Api, kuka: Cell) -> None:
    """A PLC that repeats its command while the first is under way: the tool's lock orders
    them, the first corrects and the others replay its answer as it ends, the deployment
    included (not the answer kept before the deployment, which said one follows)."""
    tool, point_id = tool_at_reference(api, kuka.rig)
    stand_at_reference(kuka, np.asarray(ACTIVE_POSITION) + MOVED)
    # The KRC moves by a frame its program set, not by $TOOL_DATA[3]: the simulator reselects
    # $TOOL after every change of the table (a KRC copies it once, at selection), so the first
    # request's deployment to $TOOL_DATA[3] changed $TOOL between the $POS_ACT and $TOOL of
    # another request's capture, which then read as a moving robot (409, in a fresh clone's
    # .ci/run). The subject here is the key, not the live tool.
    kuka.rig.sim.set_tool_frame(4.0, -2.5, 170.0, 10.0, -5.0, 3.0)
    counts = row_counts(TABLES)
    barrier = threading.Barrier(4)

    def send(_: int) -> Any:
        barrier.wait()
        return recheck(api, tool["id"], point_id, headers={"Idempotency-Key": "plc-7"})

    with ThreadPoolExecutor(4) as pool:
        answers = list(pool.map(send, range(4)))
    assert [a.status_code for a in answers] == [201] * 4, [a.text for a in answers]
    assert sorted("Idempotent-Replayed" in a.headers for a in answers) == [False, True, True, True]
    assert {a.json()["correction"]["version"] for a in answers} == {2}
    deployments = [(a.json()["correction"]["deployment"] or {}).get("status") for a in answers]
    assert deployments == ["verified"] * 4
    assert all(a.json() == answers[0].json() for a in answers)
    after = row_counts(TABLES)
    assert after["tcp_versions"] == counts["tcp_versions"] + 1
    assert after["activations"] == counts["activations"] + 1
    assert after["deployments"] == counts["deployments"] + 1
