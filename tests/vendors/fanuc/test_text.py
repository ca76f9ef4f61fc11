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
