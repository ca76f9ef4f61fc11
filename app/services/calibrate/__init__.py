"""Submitting a calibration: solve, grade, version, activate, store, all in one transaction.

The path is typed end to end: a request model (one per method, app.methods) -> the
method's run -> `Solved` -> one `CalibrationResult`, which is what is stored and served.
Nothing is written before the solver succeeds, so unsolvable input (a 422) leaves no row.
The tool row is locked first (SELECT ... FOR UPDATE; BEGIN IMMEDIATE on SQLite), which
serialises version numbering and makes idempotency-key replays see the first response.

One module per concern, every name importable from here:
- grading: a request solved by its method and its result graded (`solve`);
- presolve: the snapshot a calibration solves against before its transaction;
- writes: the transaction that stores it (`submit`; `solve_and_submit` for a solver process);
- stored: stored calibrations as served;
- detached: POST /v1/solve's solve, with nothing stored (run in a solver process).

The package also holds what calibrating calls for besides: the use cases POST
.../calibrations (submissions) and POST /v1/solve (stateless) start from, the contexts
a method reads (contexts, tool_frames), guided sessions (sessions), checks and the
re-check after a collision (checks, recheck), reference points and laser devices
(references, laser_devices), and the sentences and refusals a result is given
(verdict, diagnosis).
"""

from __future__ import annotations

from app.services.calibrate.detached import solve_detached, stateless_kinematics, stateless_robot_id
from app.services.calibrate.grading import (
    Outcome,
    graded_result,
    reference_point_to_save,
    solve,
)
from app.services.calibrate.presolve import (
    SNAPSHOT_READ,
    Presolved,
    Snapshot,
    SnapshotRow,
    snapshot_held,
    solve_snapshot,
)
from app.services.calibrate.stored import (
    calibration_out,
    get_calibration,
    list_calibrations,
    served,
)
from app.services.calibrate.writes import Submitted, replayed, solve_and_submit, submit

__all__ = [
    "SNAPSHOT_READ",
    "Outcome",
    "Presolved",
    "Snapshot",
    "SnapshotRow",
    "Submitted",
    "calibration_out",
    "get_calibration",
    "graded_result",
    "list_calibrations",
    "reference_point_to_save",
    "replayed",
    "served",
    "snapshot_held",
    "solve",
    "solve_and_submit",
    "solve_detached",
    "solve_snapshot",
    "stateless_kinematics",
    "stateless_robot_id",
    "submit",
]
