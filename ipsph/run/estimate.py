"""Size and time up front: how long a scene will take, said before it starts, and the live ETA.

The estimate is a cost model, not a measurement of this scene: fluid particles x steps per simulated
second x the solver's cost per fluid particle-step. The cost is calibrated on the development
machine (2 cores, docs/performance.md: IPSPH 1.6-1.9 us per particle-step at 100k-1M particles in a
quiet hour, 2.5-3 us in a busy one; we take 2.5 us) and scaled by the thread count. Steps per
simulated second come from the time-step rule at the fastest speed the scene can reach by
falling (sqrt(2 g H), H the height from the lowest wall or fluid to the highest fluid), so the
estimate errs long. The live progress line replaces it with the run's own rate (`eta_seconds`).
"""

from __future__ import annotations

import math

from ..errors import ConfigError

US_PER_PARTICLE_STEP_2_THREADS = 2.5  # calibrated, see above
SAY_ABOVE_S = 600.0  # print the estimate when the run should take longer than this
ASK_ABOVE_S = 3600.0  # and require --yes (when not on a terminal) above this


def steps_per_sim_second(scene) -> float:
    """1 / dt at the fastest fall speed the scene allows (the CFL rule, `Scene.cfl_step`)."""
    import numpy as np

    g = float(np.linalg.norm(scene.gravity))
    lows, highs, v0 = [], [], 0.0
    for f in scene.fluids:
        b = _bounds(f)
        if b is not None:
            lows.append(b[0][1])
            highs.append(b[1][1])
        v0 = max(v0, float(np.linalg.norm(f.velocity)))
    for w in scene.boundaries:
        b = _bounds(w)
        if b is not None:
            lows.append(b[0][1])
    height = max(highs) - min(lows) if highs else 1.0
    v = max(v0 + math.sqrt(2.0 * g * max(height, 0.0)), 1e-6)
    return 1.0 / scene.cfl_step(v)[0]


def _bounds(spec):
    """(min, max) corners of a box or mesh body after its transform, or None when unknown."""
    import numpy as np

    if getattr(spec, "shape", None) == "box" and spec.box_min is not None:
        s = np.asarray(spec.transform.scale)
        lo, hi = np.asarray(spec.box_min) * s, np.asarray(spec.box_max) * s
        t = np.asarray(spec.transform.translate)
        return np.minimum(lo, hi) + t, np.maximum(lo, hi) + t
    try:
        from ..geometry.meshes import load_mesh, transform_mesh

        b = np.asarray(transform_mesh(load_mesh(spec.mesh), spec.transform).bounds).reshape(3, 2)
    except Exception:
        return None
    return b[:, 0], b[:, 1]


def load_factor() -> float:
    """How much slower than quiet this machine is now: other jobs' 1-minute load per core (>= 1)."""
    import os

    try:
        return max(1.0, os.getloadavg()[0] / len(os.sched_getaffinity(0)))
    except (OSError, AttributeError):  # pragma: no cover - not on Linux
        return 1.0


def seconds_per_sim_second(scene, n_fluid: int, threads: int, load: float = 1.0) -> float:
    """Estimated wall seconds per simulated second on this machine kind with `threads` threads,
    `load` times slower than in a quiet hour."""
    per_step = n_fluid * US_PER_PARTICLE_STEP_2_THREADS * 1e-6 * 2.0 / max(min(threads, 64), 1)
    return per_step * steps_per_sim_second(scene) * load


def fmt_duration(s: float) -> str:
    if not math.isfinite(s):
        return "?"
    if s < 90:
        return f"{s:.0f} s"
    if s < 5400:
        return f"{s / 60:.0f} min"
    if s < 48 * 3600:
        return f"{s / 3600:.1f} h"
    return f"{s / 86400:.1f} days"


def announce(scene, n_fluid: int, threads: int, *, yes: bool, interactive: bool, log) -> float:
    """Say how long a large run will take; refuse one over ASK_ABOVE_S without `yes` when nobody
    is at a terminal to see the estimate and press Ctrl-C (exit 2, before anything is written)."""
    load = load_factor()
    per_sim = seconds_per_sim_second(scene, n_fluid, threads, load)
    total = per_sim * scene.end_time
    if total <= SAY_ABOVE_S:
        return total
    busy = f", this machine {load:.1f}x busy" if load > 1.05 else ""
    line = (
        f"about {n_fluid:,} fluid particles: roughly {fmt_duration(per_sim)} per simulated second on "
        f"{threads} thread(s){busy}, {fmt_duration(total)} for end_time {scene.end_time:g} s (an estimate; "
        f"the progress line gives the measured ETA)"
    )
    if total > ASK_ABOVE_S and not interactive and not yes:
        raise ConfigError(
            f"{line}; over {fmt_duration(ASK_ABOVE_S)} and not on a terminal: pass --yes to "
            f"run it anyway, or a larger simulation.particle_radius / shorter --end-time"
        )
    log(f"ipsph: note: {line}")
    return total


def eta_seconds(sim_time: float, end_time: float, sim_start: float, wall_elapsed: float) -> float:
    """Wall seconds left at the run's own rate so far (inf before it has advanced)."""
    done = sim_time - sim_start
    if done <= 0 or wall_elapsed <= 0:
        return math.inf
    return max(end_time - sim_time, 0.0) * wall_elapsed / done
