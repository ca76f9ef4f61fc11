"""Median wall time per N-point solve, per algorithm and N (4, 8, 50, 1000).

Clean touches (touch noise 0.05 mm, 30 deg cone with spin), touch noise not configured
(the HTTP default), plus the robust solver on data with 30 % missed touches.
Targets: robust N = 8 under 1 ms, N = 1000 under 50 ms.

Run from the repository root: `.venv/bin/python -m bench.solver_speed [--quick]`.
Writes bench/results/solver_speed.json and bench/results/solver_speed.md.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from app.solvers.npoint import ALGORITHMS, solve_npoint
from testbed.sim.touches import simulate_touches

RESULTS = Path(__file__).resolve().parent / "results"
SIZES = (4, 8, 50, 1000)
TARGETS_MS = {("robust", 8): 1.0, ("robust", 1000): 50.0}


def median_ms(fn: object, repeats: int) -> float:
    """Median of `repeats` single-call timings, ms, after two warm-up calls."""
    call = fn  # type: ignore[assignment]
    call()  # type: ignore[operator]
    call()  # type: ignore[operator]
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        call()  # type: ignore[operator]
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(times))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description="N-point solver speed")
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args(argv)
    rows = []
    for n in SIZES:
        repeats = (20 if n >= 1000 else 100) if args.quick else (60 if n >= 1000 else 400)
        cases = [(a, 0.0) for a in ALGORITHMS]
        if n >= 8:
            cases.append(("robust", 0.3))
        for algorithm, outliers in cases:
            sim = simulate_touches(n, seed=n, outlier_fraction=outliers)
            ms = median_ms(lambda s=sim, a=algorithm: solve_npoint(s.R, s.f, algorithm=a), repeats)
            target = TARGETS_MS.get((algorithm, n)) if outliers == 0 else None
            rows.append(
                {
                    "algorithm": algorithm,
                    "n": n,
                    "outlier_fraction": outliers,
                    "median_ms": ms,
                    "repeats": repeats,
                    "target_ms": target,
                    "ok": None if target is None else ms < target,
                }
            )
            print(f"{algorithm:9s} N={n:5d} outliers {outliers:.0%}: {ms:8.3f} ms", flush=True)
    meta = {
        "machine": f"{platform.machine()} {platform.python_implementation()} "
        f"{platform.python_version()}, {os.cpu_count()} cpus",
        "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS", "default"),
        "numpy": np.__version__,
        "command": "python -m bench.solver_speed" + (" --quick" if args.quick else ""),
    }
    lines = [
        "# N-point solver speed",
        "",
        f"Median ms per solve; {meta['machine']}; numpy {meta['numpy']}; "
        f"BLAS threads {meta['blas_threads']}; `{meta['command']}`.",
        "",
        "| algorithm | outliers | " + " | ".join(f"N={n}" for n in SIZES) + " |",
        "|---|---|" + "---|" * len(SIZES),
    ]
    for algorithm, outliers in [(a, 0.0) for a in ALGORITHMS] + [("robust", 0.3)]:
        cells = []
        for n in SIZES:
            hit = [
                r
                for r in rows
                if r["algorithm"] == algorithm and r["n"] == n and r["outlier_fraction"] == outliers
            ]
            if not hit:
                cells.append("-")
                continue
            r = hit[0]
            mark = "" if r["target_ms"] is None else (" ok" if r["ok"] else " MISSED")
            target = "" if r["target_ms"] is None else f" (< {r['target_ms']:g})"
            cells.append(f"{r['median_ms']:.3f}{target}{mark}")
        lines.append(f"| {algorithm} | {outliers:.0%} | " + " | ".join(cells) + " |")
    md = "\n".join(lines) + "\n"
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "solver_speed.json").write_text(json.dumps({"meta": meta, "rows": rows}, indent=2))
    (RESULTS / "solver_speed.md").write_text(md)
    print()
    print(md)


if __name__ == "__main__":
    main()
