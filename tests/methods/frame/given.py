"""A stateless frame context for the frame methods' tests: the pointers, the frame's kind and
tolerance given, poses read with no robot (every format but `joints`)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.methods.frame.base import PointerTcp
from app.schemas.common import Pose, Units
from app.schemas.frame_tolerance import FrameTolerance
from app.services.touches.tool_frames import parse_poses_with
from app.solvers.frame import Pointer
from app.words import FrameKind, PoseFormat


@dataclass(frozen=True)
class GivenPointer:
    """A frame context over given pointers: tool id -> its versions (version -> TCP), the
    last one active unless `active` says otherwise (None: no active version)."""

    versions: Mapping[str, Mapping[int, Pointer]] = field(default_factory=dict)
    active: Mapping[str, int | None] = field(default_factory=dict)
    kind: FrameKind = "base"
    tolerance: FrameTolerance = field(default_factory=FrameTolerance)

    @staticmethod
    def of(
        pointer: Pointer,
        *,
        tool_id: str = "pointer",
        kind: FrameKind = "base",
        tolerance: FrameTolerance | None = None,
    ) -> GivenPointer:
        """One pointer tool with one version (1), active."""
        return GivenPointer({tool_id: {1: pointer}}, {}, kind, tolerance or FrameTolerance())

    def pointer(self, tool_id: str, version: int | None) -> PointerTcp | None:
        if tool_id not in self.versions:
            raise InvalidInput("unknown-reference", f"no tool {tool_id}", loc=("tool_id",))
        versions = self.versions[tool_id]
        if version is None:
            version = self.active.get(tool_id, max(versions, default=None))
            if version is None:
                return None
        if version not in versions:
            raise InvalidInput(
                "unknown-reference",
                f"tool {tool_id} has no version {version}",
                loc=("tcp_version",),
            )
        return PointerTcp(tool_id, version, versions[version])

    def parse_poses(
        self,
        fmt: PoseFormat,
        poses: Sequence[Pose],
        units: Units | None,
        *,
        loc: Sequence[str | int],
    ) -> tuple[FloatArray, FloatArray]:
        return parse_poses_with(None, fmt, poses, units, loc=loc)
