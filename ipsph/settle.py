"""The pre-pass before t = 0 (`simulation.settle`, method.md section 1, "A start at rest"): when a
scene asks for it, and the pass itself, run on a `Simulation`'s method before its clock starts.
"""

from __future__ import annotations

import math
import time

import numpy as np

from .errors import ConfigError
from .model import Role, Scene

# The pre-pass before t = 0 (method.md section 1, "A start at rest"): the method's own steps of
# dt_max with the velocities damped by SETTLE_DAMPING after each, until SETTLE_HOLD steps in a row
# end with every particle slower than SETTLE_SPEED (a tenth of the tank's 0.1 m/s acceptance), at
# most SETTLE_MAX_STEPS steps. A hold of one step: waiting for 100 quiet steps cost the tank 2-4x
# the steps and did not keep late rearrangements out of the run (method.md).
SETTLE_DAMPING = 0.9
SETTLE_SPEED = 0.01
SETTLE_HOLD = 1
SETTLE_MAX_STEPS = 4000
# simulation.settle = auto settles (with IPSPH and DFSPH; PF never comes to rest) fluid at rest
# that covers its container's floor: fluid above every d x d cell of the floor farther than
# SETTLE_REACH d from the walls (a box fluid filling a tank has its first layer 1.1 d from the wall
# particles).
SETTLE_REACH = 1.5


def wants_settle(scene: Scene, fluid_x: np.ndarray, fluid_v: np.ndarray, boundary_x: np.ndarray) -> bool:
    """Whether `simulation.settle` asks for the pre-pass: on, or auto and the fluid is a pool at rest."""
    if any(b.moving for b in scene.boundaries) or scene.emitters:
        # the pre-pass steps the method from rest at t = 0: moving walls and bodies would move and
        # emitters would not emit during it, so such scenes start as sampled
        if scene.settle == "on":
            raise ConfigError(
                "simulation.settle: 'on' cannot be combined with moving walls, rigid "
                "bodies or emitters (use 'auto' or 'off')"
            )
        return False
    if scene.settle != "auto":
        return scene.settle == "on"
    if scene.method == "pf":  # PF keeps a noise floor and never comes to rest (method.md section 3)
        return False
    g = np.asarray(scene.gravity, dtype=np.float64)
    if (
        len(fluid_x) == 0
        or len(boundary_x) == 0
        or np.any(fluid_v != 0.0)
        or not np.any(g)
        or not any(b.role == Role.CONTAINER for b in scene.boundaries)
    ):
        return False
    down = int(np.argmax(np.abs(g)))
    if np.count_nonzero(g) != 1:  # gravity along an axis only: "its floor" is a wall plane
        return False
    across = [k for k in range(3) if k != down]
    d = scene.spacing
    reach = SETTLE_REACH * d
    lo, hi = boundary_x.min(axis=0)[across], boundary_x.max(axis=0)[across]
    # floor cells of size d (from the walls' lower corner) that lie inside [lo + reach, hi - reach]
    # must all have fluid above them
    first = math.ceil(reach / d)
    last = np.floor((hi - lo - reach) / d).astype(np.int64) - 1
    if np.any(last < first):
        return False
    cells = np.floor((fluid_x[:, across] - lo) / d).astype(np.int64)
    cells = cells[np.all((cells >= first) & (cells <= last), axis=1)]
    covered = np.zeros(last - first + 1, dtype=bool)
    covered[cells[:, 0] - first, cells[:, 1] - first] = True
    return bool(covered.all())


def settle(sim, max_steps: int = SETTLE_MAX_STEPS) -> dict:
    """The pre-pass before t = 0: run the method's steps of dt_max (at most the viscous limit)
    from rest, damping the velocities (v <- SETTLE_DAMPING v) after each, until SETTLE_HOLD
    steps in a row leave every particle below SETTLE_SPEED (or max_steps). The fluid then
    starts at rest (v = 0) in the solver's discrete equilibrium, and the method keeps its warm starts: the first step starts from the
    hydrostatic pressure instead of loading it up. The clock stays at 0. Returns a report
    (steps, the last step's top speed, how far the particles moved, in r)."""
    be, st, r = sim.be, sim.state, sim.scene.particle_radius
    t0 = time.perf_counter()
    start = be.to_host(st.x)[np.argsort(be.to_host(st.id))]
    dt = sim.scene.rest_dt()  # the CFL rule's bounds at rest
    steps, still, vmax, top = 0, 0, math.inf, 0.0
    while steps < max_steps and still < SETTLE_HOLD:
        sim.method.step(dt)
        steps += 1
        if sim._first_unhealthy() >= 0:
            sim._fail(sim._first_unhealthy(), "while settling before t = 0")
        vmax, _ = be.speed_energy(st.v, st.m)
        still = still + 1 if vmax <= SETTLE_SPEED else 0
        top = max(top, vmax) if still else 0.0  # the fastest particle of the quiet stretch
        be.scale(st.v, SETTLE_DAMPING)
    be.scale(st.v, 0.0)
    sim.method.prepare()
    moved = np.linalg.norm(be.to_host(st.x)[np.argsort(be.to_host(st.id))] - start, axis=1) / r
    return {
        "steps": steps,
        "dt": dt,
        "max_speed": float(top if still else vmax),
        "converged": bool(still >= SETTLE_HOLD),
        "moved_mean_r": float(moved.mean()),
        "moved_max_r": float(moved.max()),
        "seconds": time.perf_counter() - t0,
    }
