"""Accuracy of the tool-frame methods against measurement noise, next to their reported 1-sigma.

Laser beam (METHODS 5): trigger noise 0.005 / 0.01 / 0.02 / 0.05 mm on every break, restore
and the descent; errors of the TCP, runout, offset and tool length.
Orientation (METHODS 4): position noise on the flange positions of the translations
(ABB TCP&Z,X, 50 mm moves) and of the KUKA 2-point touches (60 mm / 40 mm levers).

For each case: RMS error, the RMS of the reported 1-sigma (a vector's sigma is the root sum
of squares of its components), their ratio (1 = honest), and the share of component errors
within 1.96 reported sigma (95 % expected).

Run from the repository root: .venv/bin/python -m bench.frame_accuracy [--quick]
Writes bench/results/frame_accuracy.json and .md.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import scipy

from app.solvers.laser import solve_laser
from app.solvers.npoint import solve_npoint
from app.solvers.orientation import (
    orientation_from_touches,
    orientation_from_translations,
    rotation_error_deg,
)
from app.solvers.reference import solve_reference
from testbed.sim.frames import random_rotation, tool_down, translation_directions, two_point_touches
from testbed.sim.laser import DEVICE, HEIGHTS_MM, TOOL_STATES, simulate, tool_down_rotation
from testbed.sim.touches import simulate_touches, touch_rotations

LASER_NOISE_MM = (0.005, 0.01, 0.02, 0.05)
POSITION_NOISE_MM = (0.01, 0.02, 0.05, 0.1)
RESULTS = Path(__file__).parent / "results"


def _summary(errors: np.ndarray, sigmas: np.ndarray) -> dict[str, float]:
    """errors, sigmas: (trials, components)."""
    rms = float(np.sqrt(np.mean(np.sum(errors**2, axis=1))))
    sig = float(np.sqrt(np.mean(np.sum(sigmas**2, axis=1))))
    z = errors / sigmas
    return {
        "rms_error": rms,
        "rms_sigma": sig,
        "ratio": rms / sig if sig > 0 else float("nan"),
        "coverage95": float(np.mean(np.abs(z) < 1.96)),
        "max_abs_error": float(np.abs(errors).max()),
    }


#: Estimated-noise laser cases: (heights, noise mm). Three heights leave 2 degrees of freedom.
LASER_ESTIMATED = ((3, 0.01), (3, 0.05), (4, 0.02), (6, 0.02))


def bench_laser(trials: int, seed: int) -> list[dict[str, Any]]:
    """Laser method, offset+runout tool, tilted flange: noise given (three heights, every
    noise level) and noise estimated from the sweeps (3, 4 and 6 heights)."""
    rows = []
    for level, noise in enumerate(LASER_NOISE_MM):
        rows += _laser_rows(trials, [seed, level], noise, HEIGHTS_MM, given=True)
    for k, (n_heights, noise) in enumerate(LASER_ESTIMATED):
        heights = tuple(float(h) for h in np.linspace(200.0, 240.0, n_heights))
        rows += _laser_rows(trials, [seed, 100 + k], noise, heights, given=False)
    return rows


def _laser_rows(
    trials: int, seed: list[int], noise: float, heights: tuple[float, ...], *, given: bool
) -> list[dict[str, Any]]:
    tool = TOOL_STATES["offset_runout"]
    R0 = tool_down_rotation((0.7, -0.4), spin_deg=30.0)
    u = tool.axis_direction
    true_runout = np.degrees([np.arctan2(-u[1], u[2]), np.arcsin(u[0])])
    method = "laser_beam" if given else f"laser_beam, noise estimated, {len(heights)} heights"
    rows = []
    rng = np.random.default_rng(seed)  # independent draws per case
    parts: dict[str, tuple[list[np.ndarray], list[np.ndarray]]] = {
        k: ([], []) for k in ("tcp_mm", "runout_deg", "offset_mm", "tool_length_mm")
    }
    for _ in range(trials):
        data = simulate(tool, flange_rotation=R0, noise_mm=noise, rng=rng, heights_mm=heights)
        r = solve_laser(
            flange_rotation=data.flange_rotation,
            sweeps=data.sweeps,
            descent_mm=data.descent_mm,
            device=DEVICE,
            trigger_noise_mm=noise if given else None,
        )
        s = r.sigma
        pairs = {
            "tcp_mm": (r.tcp_mm - tool.tcp_mm, s.tcp_mm),
            "runout_deg": (np.array(r.runout_deg) - true_runout, s.runout_deg),
            "offset_mm": (np.array(r.offset_mm) - tool.axis_point_mm[:2], s.offset_mm),
            "tool_length_mm": (
                np.array([r.tool_length_mm - tool.length_mm]),
                (s.tool_length_mm,),
            ),
        }
        for k, (e, sg) in pairs.items():
            parts[k][0].append(np.asarray(e))
            parts[k][1].append(np.asarray(sg))
    for k, (e, sg) in parts.items():
        rows.append(
            {
                "method": method,
                "quantity": k,
                "noise_mm": noise,
                "trials": trials,
                **_summary(np.array(e), np.array(sg)),
            }
        )
    return rows


def _orientation_rows(
    method: str,
    make: Callable[[np.random.Generator, float], tuple[np.ndarray, Any]],
    trials: int,
    seed: int,
) -> list[dict[str, Any]]:
    rows = []
    for level, noise in enumerate(POSITION_NOISE_MM):
        rng = np.random.default_rng([seed, level])
        errors, sigmas = [], []
        for _ in range(trials):
            Q, result = make(rng, noise)
            errors.append(rotation_error_deg(Q, result.rotation))
            sigmas.append(np.array(result.sigma_deg))
        rows.append(
            {
                "method": method,
                "quantity": "rotation_deg",
                "noise_mm": noise,
                "trials": trials,
                **_summary(np.array(errors), np.array(sigmas)),
            }
        )
    return rows


def bench_orientation(trials: int, seed: int) -> list[dict[str, Any]]:
    """Translations (+z, +x, 50 mm) and KUKA 2-point touches, random tools and poses."""
    tcp = np.array([12.0, -7.5, 185.0])

    def translations(rng: np.random.Generator, noise: float) -> tuple[np.ndarray, Any]:
        Q, R = random_rotation(rng, 60.0), tool_down(rng, 35.0)
        dirs = translation_directions(Q, R, length_mm=50.0, noise_mm=noise, rng=rng)
        return Q, orientation_from_translations(dirs, position_noise_mm=noise)

    def touches(rng: np.random.Generator, noise: float) -> tuple[np.ndarray, Any]:
        Q = random_rotation(rng, 60.0)
        rotations, positions = two_point_touches(Q, tcp, noise_mm=noise, rng=rng)
        result = orientation_from_touches(
            tcp_mm=tcp, rotations=rotations, positions_mm=positions, touch_noise_mm=noise
        )
        return Q, result

    return _orientation_rows("tcp_z_x", translations, trials, seed) + _orientation_rows(
        "abc_2point", touches, trials, seed
    )


REFERENCE_NOISE_MM = (0.02, 0.05, 0.1)


def bench_reference(trials: int, seed: int) -> list[dict[str, Any]]:
    """XYZ reference chain as the service runs it: tool A calibrated by 8 N-point touches, its
    pivot kept as the reference point with its covariance, then tool B from one touch of that
    point; the tools' touch noise is configured (one touch has no residual to estimate it)."""
    tool_a, tool_b = np.array([12.0, -4.0, 180.0]), np.array([-30.0, 8.0, 95.0])
    rows = []
    for level, noise in enumerate(REFERENCE_NOISE_MM):
        rng = np.random.default_rng([seed, 200 + level])
        errors, sigmas = [], []
        for _ in range(trials):
            a = simulate_touches(
                8, seed=int(rng.integers(2**31)), touch_noise_mm=noise, tcp_mm=tool_a
            )
            fit = solve_npoint(a.R, a.f, touch_noise_mm=noise)
            R = touch_rotations(rng, 1, tilt_deg=30.0, spin=True).as_matrix()[0]
            f = a.p - R @ tool_b + rng.normal(0.0, noise, 3)
            b = solve_reference(
                reference_mm=fit.pivot_mm,
                reference_covariance_mm2=fit.pivot_covariance_mm2,
                rotation=R,
                position_mm=f,
                touch_noise_mm=noise,
            )
            errors.append(b.tcp_mm - tool_b)
            sigmas.append(np.array(b.quality.tcp_sigma_mm))
        rows.append(
            {
                "method": "xyz_reference",
                "quantity": "tcp_mm",
                "noise_mm": noise,
                "trials": trials,
                **_summary(np.array(errors), np.array(sigmas)),
            }
        )
    return rows


def _table(rows: list[dict[str, Any]]) -> str:
    head = (
        "| method | quantity | noise mm | RMS error | RMS sigma | ratio | 95% coverage |\n"
        "|---|---|---:|---:|---:|---:|---:|\n"
    )
    body = "".join(
        f"| {r['method']} | {r['quantity']} | {r['noise_mm']:g} | {r['rms_error']:.4g} | "
        f"{r['rms_sigma']:.4g} | {r['ratio']:.3f} | {100 * r['coverage95']:.1f} % |\n"
        for r in rows
    )
    return head + body


def main(argv: list[str] | None = None) -> None:
    """Run the benchmark, print the table, write JSON and Markdown results."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--quick", action="store_true", help="60 trials instead of 400")
    parser.add_argument("--trials", type=int, default=None)
    parser.add_argument("--seed", type=int, default=2026)
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    trials = args.trials or (60 if args.quick else 400)
    start = time.perf_counter()
    rows = (
        bench_laser(trials, args.seed)
        + bench_orientation(trials, args.seed)
        + bench_reference(trials, args.seed)
    )
    elapsed = time.perf_counter() - start
    table = _table(rows)
    print(table)
    print(f"{trials} trials per row, {elapsed:.1f} s")
    meta = {
        "benchmark": "frame_accuracy",
        "trials": trials,
        "seed": args.seed,
        "quick": bool(args.quick),
        "seconds": round(elapsed, 2),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "laser_setup": {
            "tool": "offset_runout (offset (-0.6, 0.9) mm, runout (-0.9, 1.5) deg, r 3 mm, "
            "length 150 mm)",
            "heights_mm": [200.0, 220.0, 240.0],
            "device": {
                "beam_a_y_mm": DEVICE.beam_a_y_mm,
                "beam_b_x_mm": DEVICE.beam_b_x_mm,
                "plane_z_mm": DEVICE.plane_z_mm,
            },
            "noise": "Gaussian per trigger along its sweep and on the descent z",
        },
        "orientation_setup": {
            "tcp_z_x": "one +z and one +x move of 50 mm, noise on every recorded position",
            "abc_2point": "levers 60 mm (axis) and 40 mm (+Y), noise on every touch position",
        },
    }
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "frame_accuracy.json").write_text(
        json.dumps({**meta, "rows": rows}, indent=2) + "\n"
    )
    md = (
        "# Frame accuracy: error against noise, next to the reported 1-sigma\n\n"
        "Generated by `python -m bench.frame_accuracy"
        f"{' --quick' if args.quick else ''}` ({trials} trials per row, seed {args.seed}).\n"
        "ratio = RMS error / RMS reported sigma (1 is honest); coverage: share of component "
        "errors within 1.96 sigma (95 % expected). Units: mm, except *_deg rows (deg).\n\n" + table
    )
    (args.out / "frame_accuracy.md").write_text(md)


if __name__ == "__main__":
    main()
