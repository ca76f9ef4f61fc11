"""Refuse a submission whose numbers fit far better under another reading than the one given.

When the poses fit badly as given (out of tolerance, refused as too little spread, repeated,
degenerate or out of range, or every flange within a few mm of the robot base), the same
numbers are tried under every other reading of their units and convention
(app.kinematics.readings). If one reading fits within tolerance, and far better than the
given one, the submission is refused with 422 `convention-mismatch` naming that reading;
nothing is stored. Resending with the suggested `format` and `units` solves.

A correct submission is never refused: the diagnosis only runs when the given reading has
already failed, and it only speaks when exactly one simplest reading fits.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass

from app.arrays import FloatArray
from app.errors import InvalidInput
from app.kinematics.readings import (
    NEAR_BASE_MM,
    Reading,
    flange_near_base,
    given_reading,
    other_readings,
)
from app.schemas.common import Units
from app.words import PoseFormat

#: Refusals of the given reading that another reading may explain (a malformed request,
#: a missing value or an unknown reference are not).
EXPLAINABLE = frozenset(
    {"out-of-range", "insufficient-spread", "repeated-poses", "degenerate-poses"}
)
#: Another reading is suggested only when its rms is this many times smaller than the given
#: reading's (when that one could be solved and its flanges are not at the base).
BETTER_BY = 10.0
#: Rms below this (mm) counts as this: below any robot's repeatability, it is rounding.
RMS_FLOOR_MM = 0.005


@dataclass(frozen=True)
class Fit:
    """How well the poses fit under one reading: a figure in mm and whether it is good."""

    rms_mm: float
    good: bool


@dataclass(frozen=True)
class _Candidate:
    reading: Reading
    fit: Fit
    changes: int


#: Reads the submission's poses under a reading: flange positions (N, 3) mm.
Positions = Callable[[PoseFormat, Units | None], FloatArray]
#: Solves (or checks) the submission under a reading.
Attempt = Callable[[PoseFormat, Units], Fit]


def implausible_flanges(positions: Positions, fmt: PoseFormat | None, units: Units | None) -> bool:
    """Read as given, every flange lies within a few mm of the base: not millimetres."""
    if fmt is None:
        return False
    try:
        return flange_near_base(positions(fmt, units))
    except InvalidInput:
        return False


@contextmanager
def refusing_mix_ups(
    fmt: PoseFormat | None,
    units: Units | None,
    attempt: Attempt,
    positions: Positions,
    *,
    within: tuple[str, ...] = ("body",),
    poses_field: str = "poses",
) -> Iterator[None]:
    """Around reading or solving a submission as given: a refusal that another reading may
    explain (EXPLAINABLE: a pendant's degrees read as radians are "out of range") becomes
    `convention-mismatch` when one other reading clearly fits; otherwise it stands."""
    try:
        yield
    except InvalidInput as refusal:
        if refusal.kind in EXPLAINABLE:
            near_base = implausible_flanges(positions, fmt, units)
            refuse_mix_up(
                fmt,
                units,
                attempt,
                positions,
                as_given=None,
                near_base=near_base,
                within=within,
                poses_field=poses_field,
            )
        raise


def one_touch_fits(fmt: PoseFormat, units: Units) -> Fit:
    """The `attempt` for a single touch: with nothing to fit it against, a reading under which
    it reads (in range, the flange off the base) is as good as any."""
    return Fit(0.0, good=True)


def refuse_mix_up(
    fmt: PoseFormat | None,
    units: Units | None,
    attempt: Attempt,
    positions: Positions,
    *,
    as_given: Fit | None,
    near_base: bool,
    within: tuple[str, ...] = ("body",),
    poses_field: str = "poses",
) -> None:
    """Raise `convention-mismatch` when one other reading of the poses clearly fits.

    `attempt` solves the submission under a reading; `as_given` is the given reading's fit
    (None when it was refused); `near_base`: read as given, its flanges are at the base.
    `within` and `poses_field` locate the submission's fields in the request.
    """
    if fmt is None:
        return
    given = given_reading(fmt, None if units is None else units.model_dump(exclude_none=True))
    candidates = []
    outcomes: dict[Reading, Fit | InvalidInput] = {}
    for reading in other_readings(given):
        other_units = Units(length=reading.length, angle=reading.angle)
        try:
            if flange_near_base(positions(reading.format, other_units)):
                continue
            fit = attempt(reading.format, other_units)
        except InvalidInput as refused:
            outcomes[reading] = refused
            continue
        outcomes[reading] = fit
        if fit.good:
            candidates.append(_Candidate(reading, fit, reading.changes_from(given)))
    best = _clear_winner(candidates)
    if best is None:
        if near_base:
            in_metres = Reading(given.format, "m", given.angle)
            raise _at_the_base(given, outcomes.get(in_metres), loc=(*within, poses_field))
        return
    given_rms = None if as_given is None else as_given.rms_mm
    if not near_base and given_rms is not None and given_rms < BETTER_BY * _floored(best):
        return
    raise _mismatch(given, best, given_rms, loc=(*within, "format"))


def _clear_winner(candidates: Sequence[_Candidate]) -> _Candidate | None:
    """The best-fitting of the simplest readings that fit, unless another as simple fits
    about as well (then the numbers cannot tell which reading was meant)."""
    if not candidates:
        return None
    fewest = min(c.changes for c in candidates)
    simplest = sorted((c for c in candidates if c.changes == fewest), key=lambda c: c.fit.rms_mm)
    best = simplest[0]
    if len(simplest) > 1 and _floored(simplest[1]) < BETTER_BY * _floored(best):
        return None
    return best


def _floored(candidate: _Candidate) -> float:
    return max(candidate.fit.rms_mm, RMS_FLOOR_MM)


def _at_the_base(
    given: Reading, in_metres: Fit | InvalidInput | None, loc: tuple[str, ...]
) -> InvalidInput:
    """No reading fits, but millimetres cannot be right either: never grade these. Says what
    the metres reading gave, so that "not millimetres" and "metres do not fit" do not read as
    a contradiction."""
    if isinstance(in_metres, Fit):
        as_metres = f"read as metres they fit only to rms {in_metres.rms_mm:.3g} mm, beyond "
        as_metres += "the tool's tolerance (touches too noisy or missed)"
    elif isinstance(in_metres, InvalidInput):
        as_metres = f"read as metres they are refused too: {in_metres.detail}"
    else:
        as_metres = "read as metres they do not fit either"
    return InvalidInput(
        "out-of-range",
        f"read as {given.describe()}, every flange position lies within {NEAR_BASE_MM:g} mm "
        "of the robot base origin, where no flange can be, so the lengths cannot be "
        f"millimetres; {as_metres}, and no other reading fits within tolerance, so none is "
        "suggested. If the pendant exported metres, resend with units {'length': 'm'} once "
        "the touches are redone; nothing was stored",
        loc=loc,
    )


def _mismatch(
    given: Reading, best: _Candidate, given_rms: float | None, loc: tuple[str, ...]
) -> InvalidInput:
    suggested = best.reading
    as_given = (
        f"rms {given_rms:.3g} mm" if given_rms is not None else "they cannot be solved at all"
    )
    return InvalidInput(
        "convention-mismatch",
        f"the poses fit read as {suggested.describe()} (rms {best.fit.rms_mm:.3g} mm) far "
        f"better than as sent, {given.describe()} ({as_given}): they were probably recorded "
        f"that way. Resend with format {suggested.format!r} and units {suggested.units()!r} "
        "if so; nothing was stored",
        loc=loc,
        members={
            "suggestion": suggested.as_request(),
            "rms_as_given_mm": given_rms,
            "rms_as_suggested_mm": best.fit.rms_mm,
        },
    )
