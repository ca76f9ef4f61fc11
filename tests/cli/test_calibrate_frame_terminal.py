"""`tcpcal calibrate-frame` at a terminal: the real command in a pseudo-terminal 80 columns
wide against a live server, a base taught by three typed touches as a person types them;
the role of each is the one the server names next, the finished frame is shown with its
sigmas and the command exits 0 (accepted)."""

from __future__ import annotations

import numpy as np
import pytest

from testbed.live_server import LiveServer
from tests.cli.test_guided_terminal import TCPCAL, Terminal
from tests.cli.test_guided_terminal import server as server  # the live server fixture
from tests.live_frames import ORIGIN, X_TOUCH, XY_TOUCH, base_to_teach, typed

pytestmark = pytest.mark.live


def test_a_base_taught_by_three_typed_touches_at_an_80_column_terminal(
    server: LiveServer,
) -> None:
    frame, tool = base_to_teach(server)
    term = Terminal(
        [str(TCPCAL), "calibrate-frame", frame["id"], "--pointer", tool["id"],
         "--format", "kuka_abc"],
        server,
    )  # fmt: skip
    term.wait_for("touch 1> ")
    assert "next: touch the frame's origin" in term.shown, term.shown
    term.type(typed(ORIGIN))
    term.wait_for("touch 2> ")
    assert "at least 82 mm from the origin" in " ".join(term.shown.split()), term.shown
    term.type("1 2 3")  # not a pose of six numbers: refused, nothing kept
    term.wait_for("touch refused")
    term.wait_for("touch 2> ")
    term.type(typed(X_TOUCH))
    term.wait_for("touch 3> ")
    term.type(typed(XY_TOUCH))
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
