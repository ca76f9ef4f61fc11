"""The tool as a calibrated subject (app.services.lifecycle.subject): its TCP versions and
activations, named by `tool_id` in every lifecycle table, served under /v1/tools."""

from __future__ import annotations

from typing import Final

from app.services.lifecycle.subject import Subject
from app.storage.models import Activation, Calibration, TcpVersion, Tool
from app.words import CHECK_ACTION

TOOL: Final = Subject(
    kind="tool",
    model=Tool,
    version_model=TcpVersion,
    activation_model=Activation,
    calibration_model=Calibration,
    key="tool_id",
    value="TCP",
    plural="tools",
    leaf="tcp",
    folder="Tools",
    check_action=CHECK_ACTION,
    served_detail="load",
)
