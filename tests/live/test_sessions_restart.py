"""A guided session lives in the database: stop the server in the middle of it, start a new
one on the same database, and the session continues where it was (two workers each time, so
consecutive touches are served by different processes too)."""

from __future__ import annotations

from pathlib import Path

import pytest

from testbed.live_server import fresh_database, live_server
from tests.api.test_sessions import TOOL_DOWN, Operator, _rotation

pytestmark = pytest.mark.live


def test_a_session_survives_a_restart(tmp_path: Path) -> None:
    operator = Operator(seed=8, noise_mm=0.02, misses={})
    with fresh_database("sqlite", tmp_path, None) as url:
        with live_server(url, workers=2, solvers=0) as server, server.client() as http:
            robot = http.post("/v1/robots", json={"name": "kr16"}).json()
            tool = http.post(f"/v1/robots/{robot['id']}/tools", json={"name": "torch"}).json()
            sid = http.post(
                f"/v1/tools/{tool['id']}/sessions",
                json={
                    "method": "xyz_npoint",
                    "format": "kuka_abc",
                    "target_sigma_mm": 0.012,
                    "options": {"touch_noise_mm": 0.02},
                },
            ).json()["id"]
            state = http.post(
                f"/v1/sessions/{sid}/poses", json={"pose": operator.touch(TOOL_DOWN.as_matrix())}
            ).json()
            for _ in range(4):
                state = http.post(
                    f"/v1/sessions/{sid}/poses",
                    json={"pose": operator.touch(_rotation(state["next_pose"]))},
                ).json()
            before = http.get(f"/v1/sessions/{sid}").json()
        assert before["n_poses"] == 5
        assert before["estimate"] is not None
        with live_server(url, workers=2, solvers=0) as server, server.client() as http:
            after = http.get(f"/v1/sessions/{sid}").json()
            assert after == before  # same touches, estimate, next pose, messages
            state = after
            while not state["done"]:
                assert state["n_poses"] < 15, state
                state = http.post(
                    f"/v1/sessions/{sid}/poses",
                    json={"pose": operator.touch(_rotation(state["next_pose"]))},
                ).json()
            finished = http.post(f"/v1/sessions/{sid}/finish", json={"note": "after restart"})
            assert finished.status_code == 201, finished.text
            assert finished.json()["status"] == "accepted"
            assert finished.json()["version"] == 1
