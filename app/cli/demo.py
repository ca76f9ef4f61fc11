"""`tcpcal demo`: fill an empty database with a small, realistic fleet and 14 months of history.

Five cells, five robots of four vendors, nine tools. Every calibration goes through the same
use cases as the API (app.services), from touches simulated with a seeded RNG: touch noise
of a careful operator, the tool's TCP drifting a little between calibrations, one touch that
missed the pin by 3 mm, one calibration too noisy to accept, one check that failed, one tool
not calibrated for over a year and one never calibrated. The rows are stamped with the days
they happened on (app.storage.models.clock_at), so ages and drift plots look like a real fleet's.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta

import numpy as np
from scipy.spatial.transform import Rotation
from sqlalchemy import func, select
from sqlalchemy.orm import Session

from app.jsontypes import JsonObject
from app.kinematics.poses import pose_to_format
from app.kinematics.touchsets import flange_positions, random_cone_rotations
from app.methods.manual import MANUAL
from app.methods.npoint import XYZ_NPOINT
from app.methods.requests import CALIBRATION_REQUESTS
from app.schemas.references import CheckCreate, ReferencePointCreate
from app.schemas.robots import RobotCreate
from app.schemas.tools import Load, ToolCreate
from app.security.auth import Principal
from app.services.calibrations import writes
from app.services.checks import checks
from app.services.references import references
from app.services.robots import robots
from app.services.tools import tools
from app.storage.models import Robot, clock_at
from app.vendors.registry import BY_FORMAT
from app.words import ControllerFormat, PoseFormat

SEED = 20261123
TOOL_DOWN = Rotation.from_euler("x", 180.0, degrees=True)


@dataclass(frozen=True)
class Event:
    """Something that happened to a tool `days_ago`: a calibration or a check."""

    days_ago: float
    kind: str = "calibration"  # or "check", or MANUAL.name: a TCP entered by hand
    drift_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)  # the tool bent since the start
    n_touches: int = 8
    noise_mm: float = 0.03
    missed_touch: int | None = None  # index of a touch 3 mm off the pin
    note: str | None = None


@dataclass(frozen=True)
class DemoTool:
    name: str
    slot: int
    tcp_mm: tuple[float, float, float]
    description: str
    events: tuple[Event, ...] = ()
    mass_kg: float = 2.0


@dataclass(frozen=True)
class DemoRobot:
    """A robot of the demo plant, by its maker's controller format: its vendor field is the
    maker's name and its touches are typed in the maker's pendant format (the registry's)."""

    name: str
    maker: ControllerFormat
    model: str
    cell: str
    tools: tuple[DemoTool, ...] = field(default_factory=tuple)

    @property
    def vendor(self) -> str:
        return BY_FORMAT[self.maker].name

    @property
    def fmt(self) -> PoseFormat:
        return BY_FORMAT[self.maker].pose_format


FLEET = (
    DemoRobot(
        "weld12-kr16",
        "kuka",
        "KR 16 R1610-2",
        "weld-12",
        (
            DemoTool(
                "torch",
                1,
                (1.2, -0.8, 402.5),
                "Fronius MTB 330i, 22 deg neck",
                (
                    Event(410, note="commissioning"),
                    Event(230, drift_mm=(0.25, 0.1, -0.2), note="after nozzle change"),
                    Event(95, drift_mm=(0.6, 0.2, -0.5), note="quarterly"),
                    Event(60, kind="check", drift_mm=(0.7, 0.2, -0.5)),
                    Event(12, drift_mm=(0.8, 0.3, -0.6), missed_touch=2, note="after crash"),
                    Event(3, kind="check", drift_mm=(0.8, 0.3, -0.6)),
                ),
            ),
            DemoTool(
                "torch-spare",
                2,
                (1.0, -0.6, 401.9),
                "spare neck, kept on the stand",
                (Event(420, note="commissioning"),),
            ),
        ),
    ),
    DemoRobot(
        "weld14-kr16",
        "kuka",
        "KR 16 R1610-2",
        "weld-14",
        (
            DemoTool(
                "torch",
                1,
                (0.6, 0.4, 398.7),
                "Fronius MTB 330i, 36 deg neck",
                (
                    Event(300, note="commissioning"),
                    Event(140, drift_mm=(0.3, -0.2, 0.1), note="quarterly"),
                    Event(30, kind="check", drift_mm=(1.6, -0.9, 0.4)),
                    Event(2, drift_mm=(1.7, -0.9, 0.4), noise_mm=0.6, note="hurried, 8 touches"),
                ),
            ),
        ),
    ),
    DemoRobot(
        "assy3-irb2600",
        "abb",
        "IRB 2600-20/1.65",
        "assy-3",
        (
            DemoTool(
                "gripper",
                1,
                (0.0, 0.0, 185.0),
                "Schunk PGN-plus 100, finger tips",
                (
                    Event(200, kind=MANUAL.name, note="data sheet"),
                    Event(150, n_touches=10, noise_mm=0.05, note="fingers reground"),
                    Event(20, kind="check", drift_mm=(0.1, 0.0, 0.1)),
                ),
            ),
            DemoTool(
                "glue-nozzle",
                2,
                (35.2, 0.0, 142.8),
                "Nordson nozzle, 1.2 mm",
                (
                    Event(80, n_touches=6, note="new nozzle"),
                    Event(8, n_touches=6, drift_mm=(0.2, 0.1, -0.1), note="monthly"),
                ),
            ),
        ),
    ),
    DemoRobot(
        "mach1-ur10e",
        "ur",
        "UR10e",
        "mach-1",
        (
            DemoTool(
                "spindle",
                1,
                (0.0, -2.1, 231.4),
                "deburring spindle, 6 mm cutter",
                (
                    Event(120, note="new cutter"),
                    Event(40, drift_mm=(0.05, -0.1, -0.3), note="cutter change"),
                ),
            ),
            DemoTool(
                "probe",
                2,
                (0.0, 0.0, 118.6),
                "Renishaw touch probe, 2 mm ruby",
                (
                    Event(60, n_touches=12, noise_mm=0.01, note="reference probe"),
                    Event(5, kind="check", drift_mm=(0.01, 0.0, 0.02)),
                ),
            ),
            DemoTool("deburr", 3, (12.0, 0.0, 160.0), "compliant deburring head", ()),
        ),
    ),
    DemoRobot(
        "pal2-m20id",
        "fanuc",
        "M-20iD/25",
        "pal-2",
        (
            DemoTool(
                "vacuum",
                1,
                (0.0, 0.0, 260.0),
                "vacuum cup gripper",
                (Event(560, n_touches=5, noise_mm=0.08, note="commissioning"),),
            ),
        ),
    ),
)


class FleetNotEmpty(RuntimeError):
    """The demo only fills an empty database."""


def fill(session: Session, *, now: datetime | None = None, seed: int = SEED) -> dict[str, int]:
    """Write the demo fleet into `session` (which must hold no robot); counts of what was made."""
    if session.scalar(select(func.count()).select_from(Robot)):
        raise FleetNotEmpty("the database already holds robots: the demo fills an empty one")
    today = now or datetime.now(UTC)
    rng = np.random.default_rng(seed)
    actor = Principal(key_id="demo", name="demo", scope="admin")
    counts = {"robots": 0, "tools": 0, "calibrations": 0, "checks": 0}
    for spec in FLEET:
        robot_days = max((e.days_ago for t in spec.tools for e in t.events), default=30) + 5
        with clock_at(today - timedelta(days=robot_days)):
            robot = robots.create_robot(
                session,
                data=RobotCreate(
                    name=spec.name, vendor=spec.vendor, model=spec.model, cell=spec.cell
                ),
                actor=actor,
            )
            pin = references.register_reference_point(
                session,
                robot_id=robot.id,
                data=ReferencePointCreate(name="check pin", position_mm=[850.0, 120.0, 310.0]),
                actor=actor,
            )
        counts["robots"] += 1
        for tool_spec in spec.tools:
            with clock_at(today - timedelta(days=robot_days)):
                tool = tools.create_tool(
                    session,
                    robot_id=robot.id,
                    data=ToolCreate(
                        name=tool_spec.name,
                        slot=tool_spec.slot,
                        description=tool_spec.description,
                        load=Load(
                            mass_kg=tool_spec.mass_kg,
                            cog_mm=[round(v / 2, 1) for v in tool_spec.tcp_mm],
                        ),
                    ),
                    actor=actor,
                )
            counts["tools"] += 1
            for event in tool_spec.events:
                with clock_at(today - timedelta(days=event.days_ago)):
                    kind = _play(session, rng, spec.fmt, tool.id, tool_spec, event, pin.id, actor)
                counts[kind] += 1
            session.flush()
    return counts


def _play(
    session: Session,
    rng: np.random.Generator,
    fmt: str,
    tool_id: str,
    spec: DemoTool,
    event: Event,
    pin_id: str,
    actor: Principal,
) -> str:
    """One event of a tool's history; the kind of record it made."""
    tcp = np.asarray(spec.tcp_mm) + np.asarray(event.drift_mm)
    if event.kind == MANUAL.name:
        body: JsonObject = {
            "method": MANUAL.name,
            "tcp": {"position_mm": [float(v) for v in tcp]},
            "note": event.note,
        }
        _submit(session, tool_id, body, actor)
        return "calibrations"
    point = np.array([850.0, 120.0, 310.0]) if event.kind == "check" else _a_pin(rng)
    n = 1 if event.kind == "check" else event.n_touches
    rotations = random_cone_rotations(rng, n, TOOL_DOWN, max_tilt_deg=35.0, max_spin_deg=90.0)
    flanges = flange_positions(rotations, tcp, point) + rng.normal(0, event.noise_mm, (n, 3))
    if event.missed_touch is not None:
        miss = rng.normal(size=3)
        flanges[event.missed_touch] += 3.0 * miss / np.linalg.norm(miss)
    poses = [pose_to_format(fmt, r, f) for r, f in zip(rotations.as_matrix(), flanges, strict=True)]
    if event.kind == "check":
        data = CheckCreate.model_validate(
            {"reference_point_id": pin_id, "format": fmt, "poses": poses}
        )
        checks.run_check(session, tool_id=tool_id, data=data, actor=actor)
        return "checks"
    body = {"method": XYZ_NPOINT.name, "format": fmt, "poses": poses}
    if event.note:
        body["note"] = event.note
    _submit(session, tool_id, body, actor)
    return "calibrations"


def _a_pin(rng: np.random.Generator) -> np.ndarray:
    """A calibration pin somewhere on the table in front of the robot."""
    return np.array([700.0, 0.0, 250.0]) + rng.uniform(-150.0, 150.0, 3) * [1.0, 1.0, 0.2]


def _submit(session: Session, tool_id: str, body: JsonObject, actor: Principal) -> None:
    writes.submit(
        session,
        tool_id=tool_id,
        request=CALIBRATION_REQUESTS.validate_python(body),
        raw_body=body,
        idempotency_key=None,
        actor=actor,
    )
