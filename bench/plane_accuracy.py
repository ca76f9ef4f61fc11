"""Monte Carlo accuracy of xyz_plane (METHODS 7) against its Cramer-Rao bound.

For each scenario (seeded plane touches from testbed/sim/planes.py): RMS TCP error over the
trials / sqrt(mean trace CRB_tt), the bound sigma^2 (J^T J)^-1 of the signed-distance model
at the true TCP and planes (J as the solver's, in t, each normal's two tangent coordinates
and its offset); coverage of the reported 95 % ellipsoid; and the share of axes whose error is
within 1.96 reported sigma. Part of `python -m bench.accuracy` (suite `plane`), which keeps
its rows in bench/results/accuracy.json and .md.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import asdict, dataclass

import numpy as np

from app.errors import InvalidInput
from app.solvers.plane import cramer_rao_tcp, solve_plane
from testbed.sim.planes import simulate_plane_touches

TARGETS = {"ratio": 1.05, "coverage": (0.93, 0.97)}
#: Sets whose TCP the bound itself puts beyond this 1-sigma (mm, largest direction) are the
#: ones the service refuses as insufficient-spread at the default max_rms_mm (0.5 mm): they
#: are counted apart, chosen by the true geometry (never by the estimate), so that the ratio
#: is over the sets a cell would get a TCP from.
MAX_BOUND_SIGMA_MM = 0.5


@dataclass(frozen=True)
class PlaneScenario:
    n: int = 8
    planes: int = 1
    tilt_deg: float = 45.0
    touch_noise_mm: float = 0.05
    tcp_norm_mm: float = 150.0
    configured: bool = False

    @property
    def label(self) -> str:
        parts = [
            f"N={self.n}",
            f"{self.planes} plane{'s' if self.planes > 1 else ''}",
            f"cone {self.tilt_deg:g}+spin",
            f"sp {self.touch_noise_mm:g}",
            f"|t| {self.tcp_norm_mm:g}",
        ]
        if self.configured:
            parts.append("sigma given")
        return ", ".join(parts)


def scenarios() -> list[PlaneScenario]:
    base = PlaneScenario()
    return [
        base,
        PlaneScenario(configured=True),
        PlaneScenario(n=12),
        PlaneScenario(n=20, tilt_deg=30.0),
        PlaneScenario(n=16, planes=2),
        PlaneScenario(n=18, planes=3, configured=True),
    ]


def run_scenario(sc: PlaneScenario, trials: int, seed0: int) -> dict[str, object]:
    err2, bounds = [], []
    ellipsoid = axes = 0
    refused: Counter[str] = Counter()
    for k in range(trials):
        sim = simulate_plane_touches(
            sc.n,
            seed=seed0 + k,
            planes=sc.planes,
            tilt_deg=sc.tilt_deg,
            touch_noise_mm=sc.touch_noise_mm,
            tcp_norm_mm=sc.tcp_norm_mm,
        )
        bound = cramer_rao_tcp(
            sim.R,
            sim.f,
            tcp_mm=sim.t,
            normals=sim.normals,
            touch_noise_mm=sc.touch_noise_mm,
            planes=sim.labels,
        )
        if float(np.sqrt(np.linalg.eigvalsh(bound)[-1])) > MAX_BOUND_SIGMA_MM:
            refused["weak (bound sigma > 0.5 mm)"] += 1
            continue
        bounds.append(float(np.trace(bound)))
        try:
            res = solve_plane(
                sim.R,
                sim.f,
                planes=sim.labels,
                touch_noise_mm=sc.touch_noise_mm if sc.configured else None,
            )
        except InvalidInput as exc:
            refused[exc.kind] += 1
            continue
        e = res.tcp_mm - sim.t
        err2.append(float(e @ e))
        cov = np.asarray(res.quality.tcp_covariance_mm2)
        ellipsoid += int(float(e @ np.linalg.solve(cov, e)) <= res.quality.ellipsoid95_scale**2)
        axes += int(np.sum(np.abs(e) <= 1.96 * np.asarray(res.quality.tcp_sigma_mm)))
    solved = len(err2)
    bound = float(np.sqrt(np.mean(bounds))) if bounds else float("nan")
    rms = float(np.sqrt(np.mean(err2))) if solved else float("nan")
    return {
        "scenario": asdict(sc),
        "label": sc.label,
        "trials": trials,
        "solved": solved,
        "refused": dict(refused),
        "bound_rms_mm": bound,
        "rms_error_mm": rms,
        "ratio_to_bound": rms / bound if solved else None,
        "coverage95": ellipsoid / solved if solved else None,
        "axis_coverage95": axes / (3 * solved) if solved else None,
    }


def check(row: dict[str, object]) -> bool:
    lo, hi = TARGETS["coverage"]  # type: ignore[misc]
    ratio, cov, axis = row["ratio_to_bound"], row["coverage95"], row["axis_coverage95"]
    return (
        ratio is not None
        and ratio <= TARGETS["ratio"]  # type: ignore[operator]
        and lo <= cov <= hi  # type: ignore[operator]
        and lo <= axis <= hi  # type: ignore[operator]
    )


def markdown(rows: list[dict[str, object]]) -> str:
    lines = [
        "## xyz_plane (plane touches) against its Cramer-Rao bound",
        "",
        "RMS TCP error / bound; coverage of the reported 95 % ellipsoid; share of axes within "
        "1.96 reported sigma (the noise estimated on N - 3 - 3K degrees of freedom, sigma "
        "widened by Student's t, unless 'sigma given'). Sets whose bound exceeds 0.5 mm "
        "(1 sigma, what the service refuses as too little tilt at the default tolerance) are "
        "counted apart. Targets: ratio <= "
        f"{TARGETS['ratio']}, coverage 93-97 %.",
        "",
        "| scenario | bound mm | RMS error mm | ratio | ellipsoid 95 % | axes 95 % "
        "| refused | ok |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        refused = ", ".join(f"{k} {v}" for k, v in r["refused"].items()) or "-"  # type: ignore[attr-defined]
        lines.append(
            f"| {r['label']} | {r['bound_rms_mm']:.4f} | {r['rms_error_mm']:.4f} | "
            f"{r['ratio_to_bound']:.3f} | {100 * r['coverage95']:.1f} % | "  # type: ignore[operator]
            f"{100 * r['axis_coverage95']:.1f} % | {refused} | "  # type: ignore[operator]
            f"{'yes' if check(r) else 'NO'} |"
        )
    return "\n".join(lines) + "\n"
