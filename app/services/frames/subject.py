"""The frame as a calibrated subject (app.services.lifecycle.subject): its versions and
activations, named by `frame_id` in every lifecycle table, served under /v1/frames. A version
holds a pose in the robot's base frame (a base's origin and axes, a fixed tool's TCP); at the
controller, its deployments and controller states (app.services.frames.controller)."""

from __future__ import annotations

from typing import Final

from app.services.frames.controller import FRAME_CONTROLLER
from app.services.lifecycle.subject import Subject
from app.storage.models import (
    Frame,
    FrameActivation,
    FrameCalibration,
    FrameControllerState,
    FrameDeployment,
    FrameVersion,
)
from app.words import FRAME_CHECK_ACTION

FRAME: Final = Subject(
    kind="frame",
    model=Frame,
    version_model=FrameVersion,
    activation_model=FrameActivation,
    calibration_model=FrameCalibration,
    key="frame_id",
    value="pose",
    plural="frames",
    leaf="frame",
    folder="Frames",
    check_action=FRAME_CHECK_ACTION,
    deployment_model=FrameDeployment,
    state_model=FrameControllerState,
    controller=FRAME_CONTROLLER,
)
