"""`tcpcal calibrate-frame` at a terminal: the real command in a pseudo-terminal 80 columns
wide against a live server, a base taught by three typed touches as a person types them;
the role of each is the one the server names next, the finished frame is shown with its
sigmas and the command exits 0 (accepted)."""

from __future__ import annotations

from pathlib import Path

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


#: A fixture drawing's points (mm, in the frame), as a cell's file of them holds them: named,
#: commas or spaces, a comment; the frame's axes are the robot's (tests.live_frames).
NOMINALS = """# fixture-a, drawing 4711 rev B
P1, 0, 0, 0
P2  300 0 0
P3, 0, 200, 0   # the locating pin
P4, 150, 100, 40
"""


def test_fit_points_touches_take_their_nominal_points_from_a_file_at_a_terminal(
    server: LiveServer, tmp_path: Path
) -> None:
    frame, tool = base_to_teach(server, "kr16-fit")
    start = [str(TCPCAL), "calibrate-frame", frame["id"], "--pointer", tool["id"],
             "--format", "kuka_abc", "--method", "fit_points"]  # fmt: skip
    without = Terminal(start, server)
    assert without.end() == 2, without.shown
    assert "give --nominals FILE" in " ".join(without.shown.split()), without.shown
    drawing = tmp_path / "fixture-a.txt"
    drawing.write_text(NOMINALS, encoding="utf-8")
    term = Terminal([*start, "--nominals", str(drawing)], server)
    term.wait_for("touch 1 (P1 0 0 0 mm)> ")
    term.type(typed(ORIGIN))
    term.wait_for("touch 2 (P2 300 0 0 mm)> ")
    term.type(typed(X_TOUCH))
    term.wait_for("touch 3 (P3 0 200 0 mm)> ")
    mark = len(term.shown)
    term.type(typed(X_TOUCH))  # the wrong point touched for P3: dropped, P3 asked again
    term.wait_for("touch 4 (P4 150 100 40 mm)> ", after=mark)
    mark = len(term.shown)
    term.type("d 3")
    term.wait_for("touch 3 (P3 0 200 0 mm)> ", after=mark)
    term.type(typed(XY_TOUCH))
    term.wait_for("touch 4 (P4 150 100 40 mm)> ")
    term.type(typed(ORIGIN + np.array([150.0, 100.0, 40.0])))
    term.wait_for("touch 5> ")
    term.type("f")
    code = term.end()
    shown = " ".join(term.shown.split())
    assert code == 0, term.shown
    assert "frame v1 accepted: origin 900.000 100.000 300.000 mm" in shown, term.shown
    with server.client() as http:
        served = http.get(f"/v1/frames/{frame['id']}/frame").json()
        fiducials = http.get(f"/v1/frames/{frame['id']}/fiducials").json()
    assert served["method"] == "fit_points"
    np.testing.assert_allclose(served["frame"]["position_mm"], ORIGIN, atol=1e-6)
    # the touches kept are the file's four points, in its order: the wrong P3 was dropped
    assert [f["nominal_mm"] for f in fiducials["items"]] == [
        [0.0, 0.0, 0.0], [300.0, 0.0, 0.0], [0.0, 200.0, 0.0], [150.0, 100.0, 40.0]
    ]  # fmt: skip
