"""The pre-pass before t = 0 (`simulation.settle`, method.md section 1, "A start at rest"): when a
scene asks for it, and the pass itself, run on a `Simulation`'s method before its clock starts;
and for fluid at rest that is not settled, the hydrostatic seed of the methods' warm starts.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..config import Role, Scene
from ..errors import ConfigError

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


# The hydrostatic seed (method.md section 1): fluid at rest that stands on walls starts its solvers'
# warm starts from rho0 |g| depth, lowered towards free side faces. Runs of particles along an axis
# are broken by gaps wider than SEED_GAP d; a run's end is walled when a wall particle lies between
# d/2 and SEED_GAP d beyond it (a box fluid's first layer sits 1.1 d from the wall particles).
SEED_GAP = 1.5


def _runs(along: np.ndarray, row: np.ndarray, gap: float):
    """Runs of particles along one axis within rows of cells: (order, run, starts, ends), `order`
    sorting the particles by row then position, `run` each sorted particle's run, `starts` and
    `ends` the sorted indices of each run's first and last particle."""
    order = np.lexsort((along, row))
    a, r = along[order], row[order]
    new = np.ones(len(a), dtype=bool)
    new[1:] = (r[1:] != r[:-1]) | (a[1:] - a[:-1] > gap)
    starts = np.flatnonzero(new)
    ends = np.append(starts[1:], len(a)) - 1
    return order, np.cumsum(new) - 1, starts, ends


def hydrostatic_pressure(scene: Scene, fluid_x: np.ndarray, boundary_x: np.ndarray) -> np.ndarray | None:
    """The seed p_i = rho0 |g| D_i (1 - exp(-pi X_i / (2 H_i))) for fluid standing on walls, 0
    elsewhere; None when there is nothing to seed (no walls, no gravity, gravity not along an axis).

    D_i is the depth below the top of the particle's vertical run (the surface half a spacing above
    its highest particle), H_i that run's height and X_i the distance to the nearest free end of
    its horizontal runs (+inf when walls close them): the leading term of the harmonic correction
    that makes rho0 g D vanish on a free side face, which decays over 2 H / pi (method.md section 1).
    Vertical runs that do not stand on a wall (a falling block, a drop above the water) get none."""
    g = np.asarray(scene.gravity, dtype=np.float64)
    if len(fluid_x) == 0 or len(boundary_x) == 0 or np.count_nonzero(g) != 1:
        return None
    down = int(np.argmax(np.abs(g)))
    d = scene.spacing
    gap = SEED_GAP * d
    y = fluid_x.copy()
    y[:, down] *= -np.sign(g[down])  # heights against gravity
    yb = boundary_x.copy()
    yb[:, down] *= -np.sign(g[down])
    cell = np.floor(y / d).astype(np.int64)
    wall_cell = np.floor(yb / d).astype(np.int64)
    lo = np.minimum(cell.min(axis=0), wall_cell.min(axis=0)) - 3
    span = np.maximum(cell.max(axis=0), wall_cell.max(axis=0)) + 4 - lo

    def key(c):
        c = c - lo
        return (c[:, 0] * span[1] + c[:, 1]) * span[2] + c[:, 2]

    walls = np.unique(key(wall_cell))

    def walled(ends: np.ndarray, axis: int, sign: float) -> np.ndarray:
        """Whether a wall particle lies between d/2 and gap beyond these particles along sign * axis."""
        hit = np.zeros(len(ends), dtype=bool)
        for beyond in (0.5 * d, gap):
            probe = np.floor(y[ends] / d).astype(np.int64)
            probe[:, axis] = np.floor((y[ends, axis] + sign * beyond) / d).astype(np.int64)
            hit |= np.isin(key(probe), walls)
        return hit

    def rows(axis: int) -> np.ndarray:
        """The row of cells along `axis` each particle is in (its key, with that axis's cell fixed)."""
        return key(np.column_stack([np.full(len(y), lo[k]) if k == axis else cell[:, k] for k in range(3)]))

    # vertical runs: depth, height, standing on walls
    order, run, starts, ends = _runs(y[:, down], rows(down), gap)
    top, bottom = y[order[ends], down], y[order[starts], down]
    standing = walled(order[starts], down, -1.0)
    depth = np.empty(len(y))
    height = np.empty(len(y))
    depth[order] = np.where(standing[run], top[run] - y[order, down] + 0.5 * d, 0.0)
    height[order] = top[run] - bottom[run] + d
    # horizontal runs: the distance to the nearest free end
    free = np.full(len(y), np.inf)
    for axis in (k for k in range(3) if k != down):
        order, run, starts, ends = _runs(y[:, axis], rows(axis), gap)
        a = y[order, axis]
        lo_end = np.where(walled(order[starts], axis, -1.0)[run], np.inf, a - y[order[starts], axis][run] + 0.5 * d)
        hi_end = np.where(walled(order[ends], axis, 1.0)[run], np.inf, y[order[ends], axis][run] - a + 0.5 * d)
        free[order] = np.minimum(free[order], np.minimum(lo_end, hi_end))
    return scene.density0 * np.abs(g[down]) * depth * (1.0 - np.exp(-0.5 * np.pi * free / height))
