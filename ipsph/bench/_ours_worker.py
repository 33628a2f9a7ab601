"""Worker subprocess: run ONE ipsph simulation and print ONE JSON line of measurements.

    python -m ipsph.bench._ours_worker --scene PATH|default --method ipsph|pf|dfsph --threads N
           (--end-time T | --steps S [--warmup W]) [--set KEY=VALUE ...]

Run it through :func:`ipsph.bench.ours.run_ours`, which sets ``NUMBA_NUM_THREADS`` and samples
the machine's load around it. One process per run, so ``peak_rss_mb`` belongs to one method and a
crash never takes the caller down. No VTU output, no renders: `Simulation` is driven directly.

Timing rules (docs/performance.md):
* ``setup_seconds``: scene load + particle sampling + Simulation construction (not in the loop).
* ``first_step_seconds``: step 1, which holds the JIT compile / Numba cache load; it is left out of
  ``wall_seconds`` and out of every per-step statistic.
* ``wall_seconds``: the time loop from the end of step 1 to the end of the run (perf_counter);
  ``wall_seconds_per_sim_second`` divides it by the simulated time those steps covered.
* ``ms_per_step_median`` and ``phases_ms``: medians over steps 2..n of ``StepStats.timings``
  (``phases_ms_mean``: means, the paper's Table 1 reports averages).
* density errors in percent: ``density_error_mean_pct`` is the run mean of the per-step mean
  positive error, ``density_error_worst_pct`` the worst per-step mean, ``density_error_max_pct`` the
  largest single-particle error of any step. Step 1 is included here (it is physics, not timing).
* ``bytes_per_particle_rss``: (peak RSS - RSS before sampling) / fluid particles (includes the
  sampler's temporaries); ``bytes_per_particle_solver``: the solver's own arrays (particle state,
  neighbour lists and grid, boundary, method scratch) / fluid particles;
  ``bytes_per_particle_pair_cache``: the part of it held by the pressure solves' pair cache
  (``solver.pair_cache_mb``; 0 where it does not fit).

``--steps S --warmup W`` (the scaling sweep) runs W + S CFL steps with ``Simulation.step`` instead of
running to an end time; the per-step statistics then cover the last S steps only.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import sys
import time


def _rss_bytes() -> int:
    """Current resident set size of this process."""
    try:
        with open("/proc/self/statm", encoding="ascii") as fh:
            return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except OSError:  # pragma: no cover - non-Linux
        import psutil

        return int(psutil.Process().memory_info().rss)


def _peak_rss_bytes() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # KiB on Linux


def _arrays_nbytes(*objects) -> int:
    """Bytes of the numpy arrays held as attributes of `objects` (one level, each array once)."""
    import numpy as np

    seen: set[int] = set()
    total = 0

    def add(a):
        nonlocal total
        if isinstance(a, np.ndarray) and id(a) not in seen:
            seen.add(id(a))
            total += a.nbytes

    for obj in objects:
        if obj is None:
            continue
        attrs = dict(vars(obj)) if hasattr(obj, "__dict__") else {}
        for slot in getattr(type(obj), "__slots__", ()):
            if hasattr(obj, slot):
                attrs[slot] = getattr(obj, slot)
        for value in attrs.values():
            if isinstance(value, np.ndarray):
                add(value)
            elif isinstance(value, (list, tuple)):
                for v in value:
                    add(v)
    return total


def solver_nbytes(sim) -> int:
    """The solver's own arrays: state + neighbour lists/grid + boundary + method scratch."""
    search = sim.search
    return (
        _arrays_nbytes(sim.state)
        + _arrays_nbytes(search, getattr(search, "lists", None), getattr(search, "grid", None))
        + _arrays_nbytes(sim.boundary)
        + sim.method.nbytes
    )


def device_nbytes(sim) -> int:
    """The CUDA backend's device arrays: the particle state, the neighbour lists, the search's
    grid, sort scratch and wall candidates, the walls, the method's scratch and pair cache, and
    the reductions' partials (each array once)."""
    be, search = sim.be, sim.search
    arrays = list(sim.state.arrays().values())
    lists = getattr(search, "lists", None)
    arrays += [getattr(lists, k) for k in getattr(type(lists), "__slots__", ())]
    for d in (getattr(search, "_dev", None) or {}, getattr(search, "_scratch", None) or {}):
        arrays += list(d.values())
    for walls in be._walls.values():
        arrays += list(walls[2:])
    arrays += [be.reducer.part, *be.reducer.levels]
    unique = {id(a): a for a in arrays if a is not None}
    return sum(int(a.nbytes) for a in unique.values()) + sim.method.nbytes


def _median(xs):
    s = sorted(xs)
    n = len(s)
    if n == 0:
        return math.nan
    return s[n // 2] if n % 2 else 0.5 * (s[n // 2 - 1] + s[n // 2])


def _mean(xs):
    return sum(xs) / len(xs) if xs else math.nan


def measure(
    scene_path: str,
    method: str,
    end_time: float | None,
    overrides: list[str],
    steps: int | None = None,
    warmup: int = 1,
) -> dict:
    import numba

    from ..scene import default_scene_path, load_scene
    from ..simulation import Simulation, sample_scene

    path = default_scene_path() if scene_path == "default" else scene_path
    over = list(overrides) + [f"simulation.method={method}"]
    if end_time is not None:
        over.append(f"simulation.end_time={end_time!r}")
    rss0 = _rss_bytes()
    t0 = time.perf_counter()
    scene = load_scene(path, over)
    free0 = None
    if scene.backend == "cuda":  # the device's context first, so its own memory is not counted
        from ..backends import get_backend

        mem = get_backend("cuda", scene.precision, scene.device).memory()
        free0 = mem[0] if mem else None
    fluid_x, fluid_v, boundary_x, notes = sample_scene(scene)
    sim = Simulation(scene, fluid_x, fluid_v, boundary_x)
    del fluid_x, fluid_v, boundary_x
    setup = time.perf_counter() - t0

    recs: list = []
    marks: dict = {}

    def collect(s):
        now = time.perf_counter()
        if s.step == 1:
            marks["t1"], marks["sim1"] = now, s.time
        recs.append(s)

    t_loop = time.perf_counter()
    if steps is None:
        # no output, so no frame grid to land on: step freely to the end time (as SPlisHSPlasH
        # does; `ipsph run` shortens the steps before each frame to land on it exactly)
        sim.advance_to(scene.end_time, collect)
    else:
        for _ in range(warmup + steps):
            collect(sim.step())
    t_end = time.perf_counter()
    if not recs:
        raise RuntimeError("the run made no steps (end time 0?)")

    first_step = marks.get("t1", t_end) - t_loop
    skip = warmup if steps is not None else 1
    timed = recs[skip:] if len(recs) > skip else recs[-1:]
    # the loop wall after the skipped steps (with --steps: the sum of the timed steps' own timers)
    if steps is None:
        wall = t_end - marks["t1"] if len(recs) > 1 else math.nan
        covered = sim.time - marks["sim1"]
    else:
        wall = sum(r.timings.get("step", 0.0) for r in timed)
        covered = sum(r.dt for r in timed)
    phases = sorted({k for r in timed for k in r.timings})
    phases_med = {k: 1e3 * _median([r.timings[k] for r in timed if k in r.timings]) for k in phases}
    phases_mean = {k: 1e3 * _mean([r.timings[k] for r in timed if k in r.timings]) for k in phases}
    errs = [r.density_error_mean for r in recs]
    n = sim.n_fluid
    peak = _peak_rss_bytes()
    on_device = sim.be.name == "cuda"
    solver_b = device_nbytes(sim) if on_device else solver_nbytes(sim)
    mem = sim.be.memory() if on_device else None
    used = (free0 - mem[0]) if mem and free0 is not None else None
    return {
        "ours": "ipsph",
        "scene": str(path),
        "scene_name": scene.name,
        "method": method,
        "threads": numba.get_num_threads(),
        "fluid_particles": n,
        "boundary_particles": sim.n_boundary,
        "particle_radius": scene.particle_radius,
        "notes": notes,
        "steps": sim.steps,
        "timed_steps": len(timed),
        "sim_time": sim.time,
        "end_time": end_time,
        "setup_seconds": setup,
        "first_step_seconds": first_step,
        "wall_seconds": wall,
        "wall_seconds_per_sim_second": wall / covered if covered > 0 else math.nan,
        "ms_per_step_median": phases_med.get("step", math.nan),
        "ms_per_step_mean": phases_mean.get("step", math.nan),
        "us_per_particle_step": 1e3 * phases_med.get("step", math.nan) / n if n else math.nan,
        "phases_ms": phases_med,
        "phases_ms_mean": phases_mean,
        "density_error_mean_pct": 100.0 * _mean(errs),
        "density_error_worst_pct": 100.0 * max(errs),
        "density_error_max_pct": 100.0 * max(r.density_error_max for r in recs),
        "divergence_error_mean_pct": 100.0 * _mean([r.divergence_error for r in recs]),
        "pd_passes_mean": _mean([r.pd_passes for r in recs]),
        "pd_passes_max": max(r.pd_passes for r in recs),
        "divergence_iterations_mean": _mean([r.divergence_iterations for r in recs]),
        "divergence_iterations_max": max(r.divergence_iterations for r in recs),
        "density_iterations_mean": _mean([r.density_iterations for r in recs]),
        "density_iterations_max": max(r.density_iterations for r in recs),
        "solver_maxed_steps": sum(1 for r in recs if r.solver_maxed),
        "clamped_steps": sim.clamped_steps,
        "dt_mean": sim.time / sim.steps if sim.steps else math.nan,
        "peak_rss_mb": peak / 2**20,
        "baseline_rss_mb": rss0 / 2**20,
        "bytes_per_particle_rss": (peak - rss0) / n if n else math.nan,
        "bytes_per_particle_solver": solver_b / n if n else math.nan,
        "bytes_per_particle_pair_cache": sim.method.pair_cache_nbytes / n if n else math.nan,
        "solver_mb": solver_b / 2**20,
        "backend": scene.backend,
        "precision": scene.precision,
        "ns_per_particle_step": 1e6 * phases_med.get("step", math.nan) / n if n else math.nan,
        # CUDA: the solver's arrays above are device arrays; this is what the device's free memory
        # dropped by from before the Simulation to after the last step (None on the simulator)
        "device_bytes_per_particle_used": used / n if used is not None and n else None,
        "device_total_mb": mem[1] / 2**20 if mem else None,
    }


def main(argv: list[str] | None = None) -> int:
    from ..params import METHOD_NAMES

    ap = argparse.ArgumentParser(prog="python -m ipsph.bench._ours_worker", description=__doc__.split("\n")[0])
    ap.add_argument("--scene", required=True, help="scene file (.toml or SPlisHSPlasH .json), or 'default'")
    ap.add_argument("--method", required=True, choices=METHOD_NAMES)
    ap.add_argument("--end-time", type=float, default=None, help="simulated seconds")
    ap.add_argument("--steps", type=int, default=None, help="run W + S steps instead of an end time")
    ap.add_argument("--warmup", type=int, default=1, help="steps left out of the statistics with --steps")
    ap.add_argument("--threads", type=int, default=None, help="Numba threads")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="scene override")
    args = ap.parse_args(argv)
    if (args.end_time is None) == (args.steps is None):
        print("ours worker: give exactly one of --end-time and --steps", file=sys.stderr)
        return 2
    if args.end_time is not None and not args.end_time > 0:
        print(f"ours worker: --end-time must be > 0, got {args.end_time}", file=sys.stderr)
        return 2
    if args.steps is not None and not (args.steps >= 1 and args.warmup >= 1):
        print("ours worker: --steps and --warmup must be >= 1", file=sys.stderr)
        return 2
    if args.threads is not None:
        import numba

        numba.set_num_threads(args.threads)
    from ..errors import IpsphError

    try:
        result = measure(args.scene, args.method, args.end_time, args.set, args.steps, args.warmup)
    except IpsphError as exc:
        print(f"ours worker: error: {exc}", file=sys.stderr)
        return exc.exit_code
    sys.stdout.write(json.dumps(result, allow_nan=True, default=float) + "\n")
    sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
