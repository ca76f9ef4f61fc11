"""`tcpcal calibrate-frame` at a terminal: the real command in a pseudo-terminal 80 columns
wide against a live server, a base taught by three typed touches as a person types them;
the role of each is the one the server names next, the finished frame is shown with its
sigmas and the command exits 0 (accepted)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from app.kinematics.poses import pose_to_format
from testbed.live_server import LiveServer
from tests.cli.test_guided_terminal import TCPCAL, Terminal
from tests.cli.test_guided_terminal import server as server  # the live server fixture

pytestmark = pytest.mark.live

TCP = np.array([0.0, 0.0, 150.0])
DOWN = Rotation.from_euler("x", 180, degrees=True)
ORIGIN = np.array([900.0, 100.0, 300.0])


def _typed(point: np.ndarray) -> str:
    flange = point - DOWN.apply(TCP)
    pose = np.ravel(pose_to_format("kuka_abc", DOWN.as_matrix(), flange))
    return " ".join(f"{v:.6f}" for v in pose)


def test_a_base_taught_by_three_typed_touches_at_an_80_column_terminal(
    server: LiveServer,
) -> None:
    with server.client() as http:
        robot = http.post("/v1/robots", json={"name": "kr16", "vendor": "KUKA"}).json()
        tool = http.post(f"/v1/robots/{robot['id']}/tools", json={"name": "pointer"}).json()
        manual = {"method": "manual", "tcp": {"position_mm": TCP.tolist()}}
        assert http.post(f"/v1/tools/{tool['id']}/calibrations", json=manual).is_success
        frame = http.post(
            f"/v1/robots/{robot['id']}/frames",
            json={"name": "fixture", "kind": "base", "slot": 2,
                  "tolerance": {"touch_noise_mm": 0.05}},
        ).json()  # fmt: skip
    term = Terminal(
        [str(TCPCAL), "calibrate-frame", frame["id"], "--pointer", tool["id"],
         "--format", "kuka_abc"],
        server,
    )  # fmt: skip
    term.wait_for("touch 1> ")
    assert "next: touch the frame's origin" in term.shown, term.shown
    term.type(_typed(ORIGIN))
    term.wait_for("touch 2> ")
    assert "at least 82 mm from the origin" in " ".join(term.shown.split()), term.shown
    term.type("1 2 3")  # not a pose of six numbers: refused, nothing kept
    term.wait_for("touch refused")
    term.wait_for("touch 2> ")
    term.type(_typed(ORIGIN + np.array([300.0, 0.0, 0.0])))
    term.wait_for("touch 3> ")
    term.type(_typed(ORIGIN + np.array([0.0, 200.0, 0.0])))
    term.wait_for("done")
    term.type("f")
    code = term.end()
    shown = " ".join(term.shown.split())
    assert code == 0, term.shown
    assert "frame v1 accepted: origin 900.000 100.000 300.000 mm" in shown, term.shown
    assert "1-sigma: position" in shown, term.shown
    with server.client() as http:
        served = http.get(f"/v1/frames/{frame['id']}/frame").json()
    np.testing.assert_allclose(served["frame"]["position_mm"], ORIGIN, atol=1e-9)
