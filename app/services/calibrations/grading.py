"""Solving a calibration request and grading what its method found: the result document
(graded against the tolerance, compared with the active version, summed up, every number
finite), with a unit or convention mix-up refused instead of graded
(app.services.touches.diagnosis).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from app.arrays import FloatArray
from app.errors import InvalidInput, located_in
from app.helpers.tolerance import grade
from app.jsontypes import JsonObject
from app.methods import method_of
from app.methods.base import MethodContext, MethodRequest, Solved, StoredPoint
from app.methods.npoint import NPointOptions
from app.metrics import SOLVE_SECONDS
from app.schemas.common import Units
from app.schemas.results import (
    CalibrationResult,
)
from app.schemas.tools import Tcp
from app.services.calibrations.verdict import change_warning, summarise
from app.services.lifecycle.activation import held_for_change
from app.services.tools.versions import IDENTITY_QUATERNION
from app.services.touches.diagnosis import (
    Fit,
    implausible_flanges,
    refuse_mix_up,
    refusing_mix_ups,
)
from app.words import MethodName, PoseFormat


@dataclass(frozen=True)
class Outcome:
    """A graded result, and the point the touches met when the method finds one."""

    result: CalibrationResult
    touched_point: StoredPoint | None


def solve(request: MethodRequest, ctx: MethodContext) -> Outcome:
    """Run the request's method and grade its outcome against the context's tolerance;
    refuse a unit or convention mix-up (app.services.touches.diagnosis) instead of grading it."""

    def attempt(fmt: PoseFormat, units: Units) -> Fit:
        changed = request.model_copy(update={"format": fmt, "units": units})
        result = _solve_as_given(changed, ctx).result
        return Fit(result.quality.rms_mm or 0.0, result.status == "accepted")

    def positions(fmt: PoseFormat, units: Units | None) -> FloatArray:
        return ctx.parse_poses(fmt, request.poses or [], units, loc=())[1]

    fmt, units = request.format, request.units
    with refusing_mix_ups(fmt, units, attempt, positions):
        outcome = _solve_as_given(request, ctx)
    result = outcome.result
    near_base = implausible_flanges(positions, fmt, units)
    if result.status != "accepted" or near_base:
        as_given = Fit(result.quality.rms_mm or 0.0, good=False)
        refuse_mix_up(fmt, units, attempt, positions, as_given=as_given, near_base=near_base)
    return outcome


def _solve_as_given(request: MethodRequest, ctx: MethodContext) -> Outcome:
    with SOLVE_SECONDS.labels(request.method).time(), located_in("body"):
        solved = method_of(request).solve(request, ctx)
        return Outcome(graded_result(request.method, solved, ctx), solved.reference_point)


def graded_result(method: MethodName, solved: Solved, ctx: MethodContext) -> CalibrationResult:
    """The result of a method's outcome: graded, orientation completed, compared with the
    active version, summed up in a sentence, every number finite."""
    tolerance = ctx.tolerance
    status, reasons = grade(solved.quality, tolerance, graded=solved.graded)
    previous = ctx.active_frame()
    quaternion = solved.quaternion
    if quaternion is None:  # a position-only method keeps the active orientation
        quaternion = previous.quaternion if previous else np.asarray(IDENTITY_QUATERNION)
    change = None
    if previous is not None:
        change = float(np.linalg.norm(solved.position_mm - previous.position_mm))
    held = held_for_change(change, tolerance)
    if held and change is not None and previous is not None:
        reasons.append(change_warning(change, previous, tolerance))
    point = solved.reference_point
    result = CalibrationResult(
        **solved.extras.model_dump(),
        method=method,
        algorithm=solved.algorithm,
        status=status,
        tcp=Tcp(
            position_mm=[float(v) for v in solved.position_mm],
            quaternion=[float(v) for v in quaternion],
        ),
        reference_point_mm=[float(v) for v in point.position_mm] if point else None,
        quality=solved.quality,
        warnings=[*solved.warnings, *reasons],
        change_from_active_mm=change,
    )
    result.summary = summarise(result, previous=previous, tolerance=tolerance, held=held)
    _refuse_non_finite(result.model_dump())  # python mode: a NaN stays a NaN
    return result


def _refuse_non_finite(doc: JsonObject) -> None:
    """The solvers promise finite results; should one not, the input did not determine the
    result: answer 422 before anything is stored, never store or send a NaN."""
    try:
        # json's C encoder meets every number in one pass (a walk in Python cost 5 % of a
        # calibration's solve); only a refused document is walked, to name the number.
        json.dumps(doc, allow_nan=False)
    except ValueError:
        _name_non_finite(doc)
        raise


def _name_non_finite(value: object, path: tuple[str | int, ...] = ()) -> None:
    """Raise the 422 that names the first non-finite number in `value`."""
    if isinstance(value, Mapping):
        for key, item in value.items():
            _name_non_finite(item, (*path, str(key)))
    elif isinstance(value, list | tuple):
        for i, item in enumerate(value):
            _name_non_finite(item, (*path, i))
    elif isinstance(value, float) and not math.isfinite(value):
        where = ".".join(str(p) for p in path)
        raise InvalidInput(
            "non-finite",
            f"the solution's {where} is not a finite number: these poses do not determine it",
            loc=path,
        )


def reference_point_to_save(request: MethodRequest) -> str | None:
    """The name under which the request asks to keep the point its touches met, if it does."""
    options = getattr(request, "options", None)
    return options.save_reference_point if isinstance(options, NPointOptions) else None
