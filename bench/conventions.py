"""How often the convention diagnosis raises a false alarm, and how often it catches a mix-up.

Simulated N-point touch sets (seeded): N in {4, 6, 8, 12, 20}, a tilt cone of 15-45 deg
with spin, |TCP| 50-350 mm, touch noise 0.01-0.15 mm, and in a fifth of the sets of 6 or
more touches one touch that missed by 3-5 mm (the robust fit sets it aside). Each set is
submitted through the service's own solve path (app.services.calibrations.grading.solve, the code
behind POST /calibrations and /v1/solve, with the default tolerance):

- correctly, in one format per set (cycling over every pose format but `joints`, which needs
  a robot model): any `convention-mismatch` answer is a false alarm;
- with each mix-up: the numbers written under one reading and sent as another. Detected
  means 422 `convention-mismatch` whose suggestion reads the numbers as they were written;
  resending with the suggestion is then solved and its TCP compared with the truth.

Run from the repository root: `.venv/bin/python -m bench.conventions [--sets N]`.
Writes bench/results/conventions.json and bench/results/conventions.md.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydantic import TypeAdapter

from app.errors import InvalidInput
from app.kinematics.poses import PoseUnits, pose_to_format
from app.kinematics.readings import Reading
from app.methods.requests import SolveRequest
from app.services.calibrations.contexts import StatelessContext
from app.services.calibrations.grading import solve
from testbed.sim.touches import Touches, simulate_touches

RESULTS = Path(__file__).resolve().parent / "results"
FORMATS = ("matrix", "xyz_wxyz", "xyz_xyzw", "kuka_abc", "fanuc_wpr", "ur_rotvec")
TARGETS = {"false_alarms": 0, "detection": 0.99}


@dataclass(frozen=True)
class MixUp:
    """Numbers written as `written` and sent as `sent` (format, units left to defaults)."""

    kind: str
    written: Reading
    sent_format: str
    sent_units: dict[str, str] | None = None


def _r(fmt: str, length: str, angle: str) -> Reading:
    return Reading(fmt, length, angle)  # type: ignore[arg-type]  # literal strings below


MIX_UPS: tuple[MixUp, ...] = (
    *(MixUp("metres as mm", _r(f, "m", "deg"), f) for f in ("xyz_wxyz", "xyz_xyzw", "kuka_abc")),
    MixUp("metres as mm", _r("fanuc_wpr", "m", "deg"), "fanuc_wpr"),
    MixUp("metres as mm", _r("matrix", "m", "deg"), "matrix"),
    MixUp("mm as metres", _r("ur_rotvec", "mm", "rad"), "ur_rotvec"),
    MixUp("mm as metres", _r("kuka_abc", "mm", "deg"), "kuka_abc", {"length": "m"}),
    MixUp("radians as degrees", _r("kuka_abc", "mm", "rad"), "kuka_abc"),
    MixUp("radians as degrees", _r("fanuc_wpr", "mm", "rad"), "fanuc_wpr"),
    MixUp("degrees as radians", _r("ur_rotvec", "m", "deg"), "ur_rotvec"),
    MixUp("xyzw as wxyz", _r("xyz_xyzw", "mm", "deg"), "xyz_wxyz"),
    MixUp("wxyz as xyzw", _r("xyz_wxyz", "mm", "deg"), "xyz_xyzw"),
    MixUp("UR RPY as rotation vector", _r("fanuc_wpr", "m", "rad"), "ur_rotvec"),
    MixUp("KUKA ABC as Fanuc WPR", _r("kuka_abc", "mm", "deg"), "fanuc_wpr"),
    MixUp("Fanuc WPR as KUKA ABC", _r("fanuc_wpr", "mm", "deg"), "kuka_abc"),
)
_REQUEST = TypeAdapter(SolveRequest)


def _touches(seed: int) -> tuple[str, Touches]:
    """A set of one of three kinds: good, too noisy for the tolerance, too little tilt."""
    rng = np.random.default_rng(seed)
    n = int(rng.choice([4, 6, 8, 12, 20]))
    missed = n >= 6 and rng.random() < 0.2
    kind = str(rng.choice(["good", "noisy", "narrow"], p=[0.6, 0.2, 0.2]))
    noise = float(rng.uniform(0.3, 0.8) if kind == "noisy" else rng.uniform(0.01, 0.15))
    tilt = float(rng.uniform(2.0, 6.0) if kind == "narrow" else rng.uniform(15.0, 45.0))
    return kind, simulate_touches(
        n,
        seed=seed,
        tilt_deg=tilt,
        spin=kind != "narrow",
        tcp_norm_mm=float(rng.uniform(50.0, 350.0)),
        touch_noise_mm=noise,
        outlier_fraction=(1.0 / n + 1e-9) if missed else 0.0,
        outlier_mm=float(rng.uniform(3.0, 5.0)),
    )


def _poses(t: Touches, reading: Reading) -> list[object]:
    units = PoseUnits(reading.length, reading.angle)
    return [
        pose_to_format(reading.format, R, f, units=units) for R, f in zip(t.R, t.f, strict=True)
    ]


def _submit(body: dict[str, object]) -> tuple[str, object]:
    """("accepted" | "out_of_tolerance", result) or ("422 <kind>", error)."""
    request = _REQUEST.validate_python(body)
    try:
        result = solve(request, StatelessContext(None, None)).result
    except InvalidInput as err:
        return f"422 {err.kind}", err
    return result.status, result


def _same(a: Reading, b: Reading) -> bool:
    return a.changes_from(b) == 0 and b.changes_from(a) == 0


def _one_set(seed: int) -> dict[str, object]:
    kind, t = _touches(seed)
    fmt = FORMATS[seed % len(FORMATS)]
    correct, _ = _submit(
        {"method": "xyz_npoint", "format": fmt, "poses": _poses(t, _r(fmt, *_defaults(fmt)))}
    )
    outcomes = []
    for mix in MIX_UPS:
        body: dict[str, object] = {
            "method": "xyz_npoint",
            "format": mix.sent_format,
            "poses": _poses(t, mix.written),
        }
        if mix.sent_units:
            body["units"] = mix.sent_units
        answer, detail = _submit(body)
        detected, within = False, None
        if answer == "422 convention-mismatch":
            assert isinstance(detail, InvalidInput)
            suggestion = detail.members["suggestion"]
            assert isinstance(suggestion, dict)
            units = suggestion["units"]
            detected = _same(_r(suggestion["format"], units["length"], units["angle"]), mix.written)
            resent, result = _submit({**body, **suggestion})
            if resent in ("accepted", "out_of_tolerance"):
                err = np.asarray(result.tcp.position_mm) - t.t  # type: ignore[attr-defined]
                cov = np.asarray(result.quality.tcp_covariance_mm2)  # type: ignore[attr-defined]
                within = bool(err @ np.linalg.solve(cov, err) <= 3.0**2 * 3.0)
        outcomes.append(
            {
                "kind": mix.kind,
                "format": mix.sent_format,
                "answer": answer,
                "detected": detected,
                "within_3_sigma": within,
            }
        )
    return {
        "seed": seed,
        "kind": kind,
        "n": int(t.R.shape[0]),
        "missed": bool(t.outliers.any()),
        "format": fmt,
        "correct": correct,
        "mix_ups": outcomes,
    }


def _defaults(fmt: str) -> tuple[str, str]:
    return ("m", "rad") if fmt == "ur_rotvec" else ("mm", "deg")


def _mix_up_row(kind: str, sets: list[dict[str, object]]) -> dict[str, object]:
    """Detection of one mix-up kind over the sets whose correct reading is accepted."""
    detectable, other = [], []
    for s in sets:
        for o in s["mix_ups"]:  # type: ignore[attr-defined]
            if o["kind"] == kind:
                (detectable if s["correct"] == "accepted" else other).append(o)
    detected = sum(bool(o["detected"]) for o in detectable)
    resent = [o["within_3_sigma"] for o in detectable if o["within_3_sigma"] is not None]
    return {
        "kind": kind,
        "formats": sorted({o["format"] for o in detectable + other}),
        "detectable": len(detectable),
        "detected": detected,
        "rate": detected / max(len(detectable), 1),
        "missed_answers": dict(Counter(o["answer"] for o in detectable if not o["detected"])),
        "undetectable_answers": dict(Counter(o["answer"] for o in other)),
        "resent_within_3_sigma": (sum(resent) / len(resent)) if resent else None,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", type=int, default=1000)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    start = time.perf_counter()
    with ProcessPoolExecutor(args.workers) as pool:
        sets = list(pool.map(_one_set, range(args.sets), chunksize=10))
    elapsed = time.perf_counter() - start

    correct = Counter(str(s["correct"]) for s in sets)
    false_alarms = correct.get("422 convention-mismatch", 0)
    rows = [_mix_up_row(kind, sets) for kind in dict.fromkeys(m.kind for m in MIX_UPS)]
    report = {
        "sets": args.sets,
        "set_kinds": dict(Counter(str(s["kind"]) for s in sets)),
        "correct_answers": dict(correct),
        "false_alarms": false_alarms,
        "false_alarm_rate": false_alarms / args.sets,
        "correct_by_format": dict(Counter(str(s["format"]) for s in sets)),
        "missed_touch_sets": sum(bool(s["missed"]) for s in sets),
        "mix_ups": rows,
        "targets": TARGETS,
        "seconds": round(elapsed, 1),
        "python": platform.python_version(),
    }
    lines = [
        f"Correct sets: {args.sets} ({dict(Counter(str(s['kind']) for s in sets))}; "
        f"{report['missed_touch_sets']} with a missed touch), answered {dict(correct)}. "
        f"False alarms: {false_alarms} (rate {report['false_alarm_rate']:.4f}).",
        "",
        "Detectable: the same numbers read correctly are accepted. Where they are not (too",
        "noisy for the tolerance, too little tilt), no reading fits and none is suggested.",
        "",
        "| mix-up | formats sent | detectable sets | detected | rate | undetectable: answered |"
        " resent: TCP within 3 sigma |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        within = r["resent_within_3_sigma"]
        lines.append(
            f"| {r['kind']} | {', '.join(r['formats'])} | {r['detectable']} | {r['detected']} | "
            f"{r['rate']:.3f} | {r['undetectable_answers'] or '-'} | "
            f"{'-' if within is None else f'{within:.3f}'} |"
        )
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "conventions.json").write_text(json.dumps(report, indent=2) + "\n")
    (RESULTS / "conventions.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    print(f"\n{elapsed:.0f} s; bench/results/conventions.json written")


if __name__ == "__main__":
    main()
