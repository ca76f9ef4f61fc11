"""Controllers no remote interface of which writes a frame (a UR's installation feature, a
Yaskawa user frame in UFRAME.CND): the connector says why and which file to load by hand,
sends nothing, and the service answers 501 /no-frame-writer with both."""

from __future__ import annotations

import pytest

from app.errors import NoFrameWriter
from app.services.controllers.failures import controller_problem
from app.vendors.connector import UNREAD_FRAME, Frame, FrameTarget, FrameWriterMissing
from app.vendors.registry import connect
from tests.controllers.fixtures import ur_settings, yaskawa_settings
from tests.controllers.ur_sim import UrSimulator
from tests.controllers.yaskawa_sim import YaskawaSimulator

FRAME = Frame((500.0, 0.0, 200.0), (1.0, 0.0, 0.0, 0.0))


def test_a_ur_frame_is_a_urscript_file_to_load_and_nothing_is_sent(ur_sim: UrSimulator) -> None:
    with connect(ur_settings(ur_sim)) as ur:
        assert ur.describe_frame(FrameTarget()) == "installation feature"
        with pytest.raises(FrameWriterMissing, match="installation feature") as missing:
            ur.write_frame(FrameTarget(), FRAME)
        with pytest.raises(FrameWriterMissing):
            ur.read_frame(FrameTarget(kind="fixed_tool"))
        assert ur.read_pose().live_frame == UNREAD_FRAME
    assert "URScript" in missing.value.file
    assert missing.value.write_sent is False
    assert ur_sim.programs == []


def test_a_yaskawa_user_frame_is_uframe_cnd_to_load_and_nothing_is_sent(
    yaskawa_sim: YaskawaSimulator,
) -> None:
    with connect(yaskawa_settings(yaskawa_sim)) as hses:
        assert hses.describe_frame(FrameTarget(slot=3)) == "UFRAME.CND user frame 3"
        with pytest.raises(ValueError, match="1-63"):
            hses.write_frame(FrameTarget(slot=64), FRAME)
        yaskawa_sim.requests.clear()
        with pytest.raises(FrameWriterMissing, match=r"RORG, RXX, RXY") as missing:
            hses.write_frame(FrameTarget(slot=3), FRAME)
        with pytest.raises(FrameWriterMissing):
            hses.read_frame(FrameTarget(slot=3))
        assert yaskawa_sim.requests == []
        assert hses.read_pose().live_frame == UNREAD_FRAME
    assert missing.value.file == "UFRAME.CND"
    assert missing.value.write_sent is False
    assert yaskawa_sim.files["UFRAME.CND"] == b""


def test_the_service_answers_501_no_frame_writer_with_the_reason_and_the_file(
    yaskawa_sim: YaskawaSimulator,
) -> None:
    settings = yaskawa_settings(yaskawa_sim)
    with connect(settings) as hses, pytest.raises(FrameWriterMissing) as missing:
        hses.write_frame(FrameTarget(slot=3), FRAME)
    problem = controller_problem(
        missing.value,
        settings,
        robot_id="r1",
        left="nothing was written",
        refusal="remedy",
        members={"status": "not_written"},
    )
    assert isinstance(problem, NoFrameWriter)
    assert (problem.status, problem.kind) == (501, "no-frame-writer")
    assert problem.members == {
        "status": "not_written",
        "reason": missing.value.reason,
        "file": "UFRAME.CND",
    }
    assert "load UFRAME.CND by hand instead (nothing was sent); nothing was written" in (
        problem.detail
    )
