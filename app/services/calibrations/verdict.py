"""The verdict of a result in one sentence, and the rule that holds a large jump back.

A technician reads `summary` first, so it says what happened and what to do next. Touches
are numbered from 1 in every sentence (arrays stay 0-based).
"""

from __future__ import annotations

from app.errors import DomainError
from app.methods import ENTERED_BY_HAND
from app.methods.base import ActiveFrame
from app.schemas.references import CheckResult
from app.schemas.results import CalibrationResult, QualityOut
from app.schemas.tools import Tolerance
from app.solvers.numbering import numbered


def change_warning(change_mm: float, previous: ActiveFrame, tolerance: Tolerance) -> str:
    """Why a result that moved the TCP far was not activated, and how to activate it."""
    return (
        f"the TCP moved {change_mm:.2f} mm from active version {previous.version}, more than "
        f"the tool's max_change_mm {tolerance.max_change_mm:g} mm: stored but not activated. "
        "If the tool really changed (a new tool, a crash), activate this version "
        "(POST /v1/tools/{tool_id}/versions/{version}/activate) or resend with "
        'activate: "always"; otherwise check the units and the tool number'
    )


def _touches(n: int) -> str:
    return f"{n} touch" if n == 1 else f"{n} touches"


def _touches_beyond(quality: QualityOut, limit_mm: float) -> list[tuple[int, float]]:
    """The 0-based index and residual of each touch used in the fit that is off by more than
    `limit_mm`, in touch order."""
    set_aside = set(quality.outliers)
    return [
        (i, r) for i, r in enumerate(quality.residuals_mm) if i not in set_aside and r > limit_mm
    ]


def _out_of_tolerance(result: CalibrationResult, tolerance: Tolerance) -> str:
    quality = result.quality
    limit = tolerance.max_residual_mm
    beyond = _touches_beyond(quality, limit)
    if len(beyond) == 1:
        [(index, residual)] = beyond
        return (
            f"out of tolerance: {numbered('touch', [index])} is {residual:.2f} mm off the "
            f"others (max_residual_mm {limit:g}), touch it again"
        )
    if beyond:  # name every touch past the limit, not only the worst
        figures = ", ".join(f"{residual:.2f}" for _, residual in beyond)
        return (
            f"out of tolerance: {numbered('touch', [i for i, _ in beyond])} are {figures} mm "
            f"off the others (max_residual_mm {limit:g}), touch them again"
        )
    rms = quality.rms_mm or 0.0
    return (
        f"out of tolerance: {rms:.2f} mm rms over {_touches(quality.n_poses)} exceeds "
        f"max_rms_mm {tolerance.max_rms_mm:g}; touch again with care, from orientations "
        "further apart"
    )


def summarise(
    result: CalibrationResult,
    *,
    previous: ActiveFrame | None,
    tolerance: Tolerance,
    held: bool,
) -> str:
    """One sentence: the verdict, the TCP, the fit, the move from the active version."""
    if result.status == "out_of_tolerance":
        return _out_of_tolerance(result, tolerance)
    x, y, z = result.tcp.position_mm
    parts = [f"TCP ({x:.2f}, {y:.2f}, {z:.2f}) mm"]
    quality = result.quality
    if quality.rms_mm is not None:
        parts.append(f"{quality.rms_mm:.2f} mm rms over {_touches(quality.n_poses)}")
    elif quality.n_poses <= 1:
        parts.append("entered by hand" if result.method in ENTERED_BY_HAND else "from one pose")
    if quality.outliers:
        parts.append(f"{numbered('touch', quality.outliers)} set aside as off the others")
    if result.orientation_change_deg is not None:
        parts.append(f"turned {result.orientation_change_deg:.2f} deg")
    if previous is not None and result.change_from_active_mm is not None:
        parts.append(f"moved {result.change_from_active_mm:.2f} mm from version {previous.version}")
    sentence = ", ".join(parts)
    if held:
        return (
            f"accepted but not activated: {sentence}, more than max_change_mm "
            f"{tolerance.max_change_mm:g} mm; activate it if the tool really changed"
        )
    return f"accepted: {sentence}"


def _flange_direction(deviation_flange_mm: list[float], distance_mm: float) -> str:
    """E.g. "2.20 mm along flange +Y" or "0.80 mm along flange +X and 0.30 mm along flange -Y":
    the components that make up at least a tenth of the distance, largest first."""
    parts = sorted(
        ((abs(v), f"{abs(v):.2f} mm along flange {'+' if v >= 0 else '-'}{axis}")
         for v, axis in zip(deviation_flange_mm, "XYZ", strict=True)
         if abs(v) >= 0.1 * distance_mm),
        reverse=True,
    )  # fmt: skip
    return " and ".join(text for _, text in parts) if parts else "no measurable direction"


def check_summary(
    *,
    distance_mm: float,
    deviation_flange_mm: list[float],
    version: int,
    n_touches: int,
    check_mm: float,
    advice: bool = True,
) -> str:
    """A check's verdict: how far and which way (flange frame, new minus old) the tip moved;
    out of tolerance, with what to do (unless `advice` is false: a re-check says its own)."""
    within = distance_mm <= check_mm
    worst = f"worst of {_touches(n_touches)}, " if n_touches > 1 else ""
    sentence = (
        f"{'within tolerance' if within else 'out of tolerance'}: the tool tip is "
        f"{distance_mm:.2f} mm from where version {version} puts it, "
        f"{_flange_direction(deviation_flange_mm, distance_mm)} ({worst}limit {check_mm:g} mm)"
    )
    if within or not advice:
        return sentence
    return sentence + "; recalibrate the tool or look for a bend"


def recheck_summary(
    result: CheckResult,
    *,
    max_correction_mm: float,
    deploying: bool = False,
    failure: DomainError | None = None,
) -> str:
    """A re-check's sentence: the check's verdict and what was done about it. `deploying`:
    the correction's deployment is yet to come (the sentence the check is recorded with)."""
    if result.verdict in ("within_tolerance", "out_of_tolerance"):
        return result.summary
    head = check_summary(
        distance_mm=result.distance_mm,
        deviation_flange_mm=result.deviation_flange_mm,
        version=result.version,
        n_touches=len(result.touches),
        check_mm=result.check_mm,
        advice=False,
    )
    correction = result.correction
    if result.verdict == "recalibrate" or correction is None:
        if result.distance_mm > max_correction_mm:
            why = (
                f"{result.distance_mm:.2f} mm is beyond the tool's max_correction_mm "
                f"({max_correction_mm:g} mm)"
            )
        else:
            why = "the TCP this touch gives is not within the tool's tolerance"
        return (
            f"{head}; {why}, so nothing was changed: recalibrate the tool (several touches, "
            "e.g. xyz_npoint) and look for a bend or a loose part"
        )
    dx, dy, dz = correction.delta_mm
    done = (
        f"{head}; corrected: version {correction.version} (version "
        f"{correction.previous_version} moved by {dx:+.3f}, {dy:+.3f}, {dz:+.3f} mm in the "
        "flange frame) is active"
    )
    deployment = correction.deployment
    if deployment is None and deploying:
        return f"{done}; its deployment to the controller follows"
    if deployment is None:
        return f"{done}, not deployed: deploy it before the robot runs with it"
    if failure is None and deployment.status == "verified":
        return f"{done}, deployed to {deployment.target} and read back as written"
    detail = failure.detail if failure is not None else deployment.status
    return (
        f"{done} in tcpcal, but its deployment to {deployment.target} failed ({detail}); "
        f"the controller is flagged: deploy version {correction.version} again "
        f"(POST /v1/tools/{result.tool_id}/deployments) once it answers"
    )
