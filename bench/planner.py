"""Planned touch sets against random ones, and the planner's prediction against what happens.

For each N and cone, the planner's A-optimal set (app.solvers.planning) is compared with
random sets of the same N in the same cone (tilt uniform over the cap, |spin| <= max_spin):

- predicted: sqrt(trace Cov(t)) for the touch noise, the RMS TCP error the design promises;
  the ratio planned / median(random) says how much planning buys;
- achieved: 200 simulated sessions per design, each with its own TCP (|t| 50-300 mm), point
  and Gaussian touch noise, solved by the service's N-point solver with the noise configured
  (the default robust estimator); the RMS of |t_hat - t| over the sessions, over the
  predicted figure, should be ~1 (0.85-1.2 is the issue's band).

Run from the repository root: `.venv/bin/python -m bench.planner [--sessions N]`.
Writes bench/results/planner.json and bench/results/planner.md.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from app.kinematics.touchsets import cone_rotations, flange_positions, random_cone_rotations
from app.solvers.npoint import solve_npoint
from app.solvers.planning import Cone, plan_touches, unit_covariance

RESULTS = Path(__file__).resolve().parent / "results"
TOOL_DOWN = Rotation.from_euler("x", 180.0, degrees=True)
NOISE_MM = 0.05
CASES = [  # (N, max tilt, max spin)
    (4, 40.0, 90.0),
    (6, 40.0, 90.0),
    (6, 25.0, 45.0),
    (8, 40.0, 90.0),
    (12, 40.0, 90.0),
    (6, 60.0, 180.0),
]
TARGETS = {"ratio_6_40_90": 0.8, "achieved_over_predicted": (0.85, 1.2)}


def achieved_rms(rotations: Rotation, rng: np.random.Generator, sessions: int) -> float:
    """RMS TCP error over simulated sessions touching with these orientations."""
    errors = []
    for _ in range(sessions):
        direction = rng.normal(size=3) * [0.3, 0.3, 1.0]
        tcp = rng.uniform(50.0, 300.0) * direction / np.linalg.norm(direction)
        point = np.array([800.0, 0.0, 250.0]) + rng.normal(0.0, 80.0, 3)
        flanges = flange_positions(rotations, tcp, point) + rng.normal(
            0.0, NOISE_MM, (len(rotations), 3)
        )
        result = solve_npoint(rotations.as_matrix(), flanges, touch_noise_mm=NOISE_MM)
        errors.append(float(np.sum((result.tcp_mm - tcp) ** 2)))
    return float(np.sqrt(np.mean(errors)))


def run_case(
    n: int, tilt: float, spin: float, sessions: int, rng: np.random.Generator
) -> dict[str, float]:
    cone = Cone(tilt, spin)
    started = time.perf_counter()
    plan = plan_touches(n, cone)
    plan_seconds = time.perf_counter() - started
    planned = cone_rotations(TOOL_DOWN, plan.tilt_deg, plan.azimuth_deg, plan.spin_deg)
    predicted = plan.total_sigma_mm(NOISE_MM)
    random_predicted = []
    for _ in range(1000):
        r = random_cone_rotations(rng, n, TOOL_DOWN, max_tilt_deg=tilt, max_spin_deg=spin)
        cov = unit_covariance(r.as_matrix())
        random_predicted.append(
            NOISE_MM * float(np.sqrt(np.trace(cov))) if np.all(np.isfinite(cov)) else np.inf
        )
    median_random = float(np.median(random_predicted))
    achieved = achieved_rms(planned, rng, sessions)
    one_random = random_cone_rotations(rng, n, TOOL_DOWN, max_tilt_deg=tilt, max_spin_deg=spin)
    random_pred_one = NOISE_MM * float(np.sqrt(np.trace(unit_covariance(one_random.as_matrix()))))
    random_achieved = achieved_rms(one_random, rng, sessions)
    return {
        "n": n,
        "max_tilt_deg": tilt,
        "max_spin_deg": spin,
        "predicted_planned_mm": predicted,
        "median_predicted_random_mm": median_random,
        "ratio_planned_to_random": predicted / median_random,
        "achieved_planned_mm": achieved,
        "achieved_over_predicted": achieved / predicted,
        "random_set_achieved_over_predicted": random_achieved / random_pred_one,
        "plan_seconds": plan_seconds,
    }


def markdown(rows: list[dict[str, float]], sessions: int) -> str:
    lines = [
        f"Touch noise {NOISE_MM} mm per axis; random sets: 1000 per row; achieved: {sessions} "
        "simulated sessions per design (robust N-point solver, noise configured).",
        "",
        "| N | tilt | spin | predicted planned (mm) | median random (mm) | planned / random "
        "| achieved planned (mm) | achieved / predicted | same for one random set "
        "| plan time (s) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['n']:.0f} | {r['max_tilt_deg']:.0f} | {r['max_spin_deg']:.0f} "
            f"| {r['predicted_planned_mm']:.4f} | {r['median_predicted_random_mm']:.4f} "
            f"| {r['ratio_planned_to_random']:.2f} | {r['achieved_planned_mm']:.4f} "
            f"| {r['achieved_over_predicted']:.2f} | {r['random_set_achieved_over_predicted']:.2f} "
            f"| {r['plan_seconds']:.2f} |"
        )
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--sessions", type=int, default=200)
    parser.add_argument("--seed", type=int, default=20261123)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    rows = [run_case(n, tilt, spin, args.sessions, rng) for n, tilt, spin in CASES]
    md = markdown(rows, args.sessions)
    print(md)
    meta = {
        "python": platform.python_version(),
        "machine": platform.machine(),
        "seed": args.seed,
        "sessions": args.sessions,
        "noise_mm": NOISE_MM,
    }
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "planner.json").write_text(
        json.dumps({"meta": meta, "rows": rows, "targets": TARGETS}, indent=2) + "\n"
    )
    (RESULTS / "planner.md").write_text(md)


if __name__ == "__main__":
    main()
