"""app.vendors.fanuc.text's reader of a TP program: ``PR[n,1..6]=.. ; UTOOL[t]=PR[n]``.

``UTOOL[t]=PR[n]`` copies the register as it stands when the line runs (HandlingTool's
"UTOOL[i]=PR[j]" assignment; ros-industrial-attic/robodk_postprocessors Fanuc_R30iA.py
``setTool`` sets the six elements first): an element set after the assignment is not the
tool frame's.
"""

from __future__ import annotations

import math

import pytest
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from app.errors import InvalidInput
from app.vendors.fanuc.text import parse

SIX = "PR[95,1]=10.0 ;\nPR[95,2]=-20.5 ;\nPR[95,3]=150.0 ;\nPR[95,4]=0.0 ;\nPR[95,5]=0.0 ;\n"


def test_an_element_set_after_the_assignment_is_not_the_tool_frames() -> None:
    text = SIX + "PR[95,6]=90.0 ;\nUTOOL[1]=PR[95] ;\nPR[95,3]=0.0 ;\nPR[95,6]=0.0 ;\n"
    position, quaternion = parse(text)
    assert_allclose(position, [10.0, -20.5, 150.0])
    w, x, y, z = quaternion
    rz = Rotation.from_quat([x, y, z, w]).as_euler("xyz", degrees=True)[2]
    assert math.isclose(rz, 90.0, abs_tol=1e-9), rz


def test_the_six_elements_must_all_come_before_the_assignment() -> None:
    """The sixth element set only after ``UTOOL[1]=PR[95]``: the register was not complete
    when copied, and the text is read as the one-line form (which it is not)."""
    text = SIX + "UTOOL[1]=PR[95] ;\nPR[95,6]=0.0 ;\n"
    with pytest.raises(InvalidInput) as refused:
        parse(text)
    assert refused.value.kind == "invalid-pose"
    assert refused.value.detail.startswith("cannot read fanuc tool data: expected X <number>")


def _z(text: str, **kwargs: int) -> float:
    position, _ = parse(text, **kwargs)
    return float(position[2])


def test_the_last_assignment_of_the_tool_is_what_the_controller_holds() -> None:
    """Two ``UTOOL[1]=PR[95]``, Z 100 then Z 200: the second overwrites the first, and the
    controller holds 200 once the program has run."""
    first = SIX.replace("PR[95,3]=150.0", "PR[95,3]=100.0") + "PR[95,6]=0.0 ;\nUTOOL[1]=PR[95] ;\n"
    text = first + "PR[95,3]=200.0 ;\nUTOOL[1]=PR[95] ;\n"
    assert _z(text) == 200.0


def test_an_element_set_between_two_assignments_is_the_seconds() -> None:
    """R 0 at the first ``UTOOL[1]=PR[95]``, R 90 set before the second: the frame held is
    rotated 90 deg about Z, and X, Y, Z (set once, before both) are kept."""
    text = SIX + "PR[95,6]=0.0 ;\nUTOOL[1]=PR[95] ;\nPR[95,6]=90.0 ;\nUTOOL[1]=PR[95] ;\n"
    position, quaternion = parse(text)
    assert_allclose(position, [10.0, -20.5, 150.0])
    w, x, y, z = quaternion
    rz = Rotation.from_quat([x, y, z, w]).as_euler("xyz", degrees=True)[2]
    assert math.isclose(rz, 90.0, abs_tol=1e-9), rz


def test_the_tool_asked_for_is_read_and_not_the_last_of_another() -> None:
    """UTOOL[1] from Z 100, then UTOOL[2] from Z 200 (the same register): read for tool 1,
    the frame is tool 1's as last assigned, Z 100; for tool 2, Z 200."""
    text = (
        SIX.replace("PR[95,3]=150.0", "PR[95,3]=100.0")
        + "PR[95,6]=0.0 ;\nUTOOL[1]=PR[95] ;\nPR[95,3]=200.0 ;\nUTOOL[2]=PR[95] ;\n"
    )
    assert _z(text, tool=1) == 100.0
    assert _z(text, tool=2) == 200.0


def test_two_tool_numbers_and_none_asked_for_is_refused_naming_them() -> None:
    """The program loads UTOOL[1] and UTOOL[2]: both frames are held, the text's one TCP
    would be one of them under no number, so the reader refuses and names both."""
    text = SIX + "PR[95,6]=0.0 ;\nUTOOL[2]=PR[95] ;\nUTOOL[1]=PR[95] ;\n"
    with pytest.raises(InvalidInput) as refused:
        parse(text)
    assert refused.value.kind == "invalid-pose"
    assert "UTOOL[1] and UTOOL[2]" in refused.value.detail, refused.value.detail


def test_a_tool_the_program_does_not_load_is_refused_naming_those_it_does() -> None:
    text = SIX + "PR[95,6]=0.0 ;\nUTOOL[1]=PR[95] ;\n"
    with pytest.raises(InvalidInput) as refused:
        parse(text, tool=3)
    assert refused.value.kind == "invalid-pose"
    assert "no UTOOL[3]" in refused.value.detail, refused.value.detail
    assert "only UTOOL[1]" in refused.value.detail, refused.value.detail
