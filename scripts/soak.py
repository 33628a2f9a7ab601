#!/usr/bin/env python
"""Soak test (not in CI): the hydrostatic tank for many steps, watching for slow trouble.

    python scripts/soak.py                      # 100,000 steps of IPSPH (hours on a laptop)
    python scripts/soak.py --steps 5000 --method dfsph --report-every 500

The tank of tests/test_physics.py: a 0.6 m column of 14^3 = 2,744 particles at r = 0.02 m at rest
in a 0.6 x 1.0 x 0.6 m box, dt_max = 5 ms. Every `--report-every` steps one line: simulated time,
particle count, particles outside the tank walls (escaped), mean / max density error of the
step, the worst mean density error so far, resident memory (RSS) and its drift since the first
report (allocations done, caches warm). Ends with a summary line and, with --json, a JSON file.
A numerical failure (NaN, escape past the domain) ends the soak with exit 3.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from ipsph.errors import NumericalFailure  # noqa: E402
from ipsph.scene import scene_from_dict  # noqa: E402
from ipsph.simulation import Simulation, sample_scene  # noqa: E402

TANK_LO = np.array([0.0, 0.0, 0.0])
TANK_HI = np.array([0.6, 1.0, 0.6])


def tank_scene(method: str, r: float):
    return scene_from_dict(
        {
            "simulation": {"method": method, "particle_radius": r, "end_time": 1e6},
            "time_step": {"dt_max": 0.005},
            "fluid": [{"name": "column", "box": {"min": [0, 0, 0], "max": [0.6, 0.6, 0.6]}}],
            "boundary": [
                {"name": "tank", "role": "container", "box": {"min": TANK_LO.tolist(), "max": TANK_HI.tolist()}}
            ],
        },
        name=f"soak-{method}",
    )


def rss_mib() -> float:
    import psutil

    return psutil.Process().memory_info().rss / 2**20


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=100_000)
    ap.add_argument("--method", choices=("ipsph", "pf", "dfsph"), default="ipsph")
    ap.add_argument("--radius", type=float, default=0.02, help="particle radius [m] (default 0.02: 2,744 particles)")
    ap.add_argument("--report-every", type=int, default=1000)
    ap.add_argument("--threads", type=int, help="numba threads (default: all cores)")
    ap.add_argument("--json", type=Path, help="write the reports and the summary to this file")
    args = ap.parse_args(argv)

    import numba

    if args.threads:
        numba.set_num_threads(args.threads)
    scene = tank_scene(args.method, args.radius)
    sim = Simulation(scene, *sample_scene(scene)[:3])
    n0 = sim.n_fluid
    print(
        f"soak: {args.method}, {n0} fluid + {sim.n_boundary} boundary particles, {args.steps} steps, "
        f"{numba.get_num_threads()} threads",
        flush=True,
    )
    print(
        f"{'step':>8} {'t [s]':>9} {'particles':>9} {'escaped':>7} {'err mean %':>10} {'err max %':>9} "
        f"{'worst mean %':>12} {'RSS MiB':>8} {'drift MiB':>9} {'steps/s':>8}",
        flush=True,
    )
    reports = []
    worst_mean = 0.0
    max_escaped = 0
    rss0 = None
    t_wall = time.perf_counter()
    last_wall, last_step = t_wall, 0
    code = 0
    try:
        for k in range(1, args.steps + 1):
            s = sim.step()
            if k > 50:  # the first steps settle the under-dense initial lattice
                worst_mean = max(worst_mean, s.density_error_mean)
            if k % args.report_every == 0 or k == args.steps:
                x = sim.positions
                escaped = int(np.count_nonzero(np.any((x < TANK_LO) | (x > TANK_HI), axis=1)))
                max_escaped = max(max_escaped, escaped)
                rss = rss_mib()
                rss0 = rss if rss0 is None else rss0
                now = time.perf_counter()
                rate = (k - last_step) / max(now - last_wall, 1e-9)
                last_wall, last_step = now, k
                rep = {
                    "step": k,
                    "time": sim.time,
                    "particles": sim.n_fluid,
                    "escaped": escaped,
                    "density_error_mean_pct": 100 * s.density_error_mean,
                    "density_error_max_pct": 100 * s.density_error_max,
                    "worst_mean_pct": 100 * worst_mean,
                    "rss_mib": rss,
                    "rss_drift_mib": rss - rss0,
                    "steps_per_s": rate,
                }
                reports.append(rep)
                print(
                    f"{k:8d} {sim.time:9.3f} {sim.n_fluid:9d} {escaped:7d} {rep['density_error_mean_pct']:10.4f} "
                    f"{rep['density_error_max_pct']:9.3f} {rep['worst_mean_pct']:12.4f} {rss:8.1f} "
                    f"{rss - rss0:9.1f} {rate:8.1f}",
                    flush=True,
                )
    except NumericalFailure as exc:
        print(f"soak: {exc}", file=sys.stderr)
        code = 3
    except KeyboardInterrupt:
        print("soak: interrupted", file=sys.stderr)
        code = 130
    wall = time.perf_counter() - t_wall
    means = np.array([r["density_error_mean_pct"] for r in reports]) if reports else np.zeros(1)
    summary = {
        "method": args.method,
        "radius": args.radius,
        "steps": sim.steps,
        "sim_time": sim.time,
        "wall_seconds": wall,
        "threads": numba.get_num_threads(),
        "particles_start": n0,
        "particles_end": sim.n_fluid,
        "max_escaped": max_escaped,
        "density_error_mean_pct_at_reports_mean": float(means.mean()),
        "worst_step_mean_density_error_pct": 100 * worst_mean,
        "rss_first_report_mib": rss0,
        "rss_end_mib": rss_mib(),
        "rss_drift_mib": (rss_mib() - rss0) if rss0 is not None else None,
        "exit_code": code,
    }
    print(
        "soak: " + ", ".join(f"{k} = {v:.4g}" if isinstance(v, float) else f"{k} = {v}" for k, v in summary.items()),
        flush=True,
    )
    if args.json:
        args.json.write_text(json.dumps({"summary": summary, "reports": reports}, indent=1) + "\n")
    return code


if __name__ == "__main__":
    sys.exit(main())
