"""The CPU launchers: built from the pass table (`passes.PASSES`), each a `prange` over blocks of
particles, each block with one scratch buffer, calling the pass's body for every particle in it.

Particles are processed in CHUNKS blocks rather than one buffer per thread: reading a thread id
would keep Numba from caching the compiled pass. Each particle is handled by one thread from
start to end and writes index i only, so the results do not depend on the thread count.
`launchers(module, file)` compiles a home module's rows (`Pass.home`: this one or `cpu_field`)
from `passes.source` and binds them there by name, cached on disk like hand-written ones.

Also here: the serial reductions (fixed order: the same bits whatever the thread count) and the
element-wise updates a step needs (one loop each instead of numpy temporaries, whose broadcast of a
(3,) vector over (n, 3) costs more than the arithmetic: docs/performance.md).
"""

import numpy as np
from numba import njit, prange

from . import field_grid, kernels, wall_field
from ._cache import depend_on
from .kernels import FASTMATH as FAST
from .kernels import w
from .passes import PASSES, SOURCES, source, wrapper_source

CHUNKS = 64  # blocks of particles per pass, each with its own scratch buffer

NO_DISPLACEMENT = np.zeros((0, 3))  # xsph(..., disp=NO_DISPLACEMENT): skip the PF displacement
EVERY_PARTICLE = np.zeros(0)  # warm_stiffness(..., rate=EVERY_PARTICLE): no mask

# The pair cache G[i, :, k] = mf grad W_ij (float64, the layout of the fluid lists: (n, 3, K)).
# The pressure solves run at fixed positions, so the pass that last visits the pairs at those
# positions fills it (DFSPH: the density pass; IPSPH: the viscosity pass) and returns it, and the
# solves' residual and correction passes read it instead of gathering x_j and evaluating the
# kernel. A pass given NO_PAIR_CACHE (no rows) neither fills nor reads it.
NO_PAIR_CACHE = np.zeros((0, 3, 0))


@njit(inline="always")
def _buffers(rows, nf, nb):
    """One (rows, K_f + K_b) scratch block per chunk of particles (no thread ids: cacheable)."""
    return np.empty((min(nf.shape[0], CHUNKS), rows, nf.shape[1] + nb.shape[1]))


@njit(inline="always")
def _fluid_buffers(rows, nf):
    """One (rows, K_f) scratch block per chunk, for the passes that see walls through `gb`."""
    return np.empty((min(nf.shape[0], CHUNKS), rows, nf.shape[1]))


@njit(inline="always")
def _chunk(c, n_chunks, n):
    """Particle range [lo, hi) of chunk c."""
    return c * n // n_chunks, (c + 1) * n // n_chunks


# -- the per-particle passes: generated from the pass table ------------------------------------------
_SCRATCH = {
    "fluid": "_fluid_buffers({rows}, nf)",
    "walls": "_fluid_buffers({rows}, nb)",
    "all": "_buffers({rows}, nf, nb)",
}
_LOOPS = {
    "chunks": [
        "for c in prange(bufs.shape[0]):",
        "    lo, hi = _chunk(c, bufs.shape[0], {n})",
        "    for i in range(lo, hi):",
    ],
    "each": ["for i in prange({n}):"],
    "serial": ["for i in range({n}):"],
}
_OPTIONS = {"chunks": {"parallel": True, "fastmath": FAST}, "each": {"parallel": True, "fastmath": FAST}, "serial": {}}
_HELPERS = {
    "np": np,
    "prange": prange,
    "w": w,
    "_chunk": _chunk,
    "_buffers": _buffers,
    "_fluid_buffers": _fluid_buffers,
}


def _compile(text: str, module: str, file: str, names: dict, name: str, options: dict):
    """The @njit(cache=True, **options) function `name` of the source `text`, compiled as if it stood
    in `file` (the module `module`): numba's disk cache keys it there."""
    namespace = {"__name__": module, **_HELPERS, **names}
    exec(compile(text, file, "exec"), namespace)
    return njit(cache=True, **options)(namespace[name])


def launchers(module: str, file: str) -> dict:
    """The CPU launchers of the table's passes that live in `module` (`passes.Pass.home`), by name,
    with the wrappers some call their bodies through (each `Pass.wrapper`)."""
    out = {}
    for p in PASSES.values():
        if f"{__package__}.{p.home}" != module:
            continue
        names = {"body": p.body}
        if p.wrapper:
            one = _compile(wrapper_source(p), module, file, names, p.wrapper, {"fastmath": FAST})
            out[p.wrapper] = names["one"] = one
        scratch = f"bufs = {_SCRATCH[p.stride].format(rows=p.rows)}" if p.rows else ""
        tail = [f"return np.count_nonzero({p.count})"] if p.count else []
        text = source(p, scratch, _LOOPS[p.cpu], "bufs[c]", "one" if p.wrapper else "body", tail)
        out[p.name] = _compile(text, module, file, names, p.name, _OPTIONS[p.cpu])
    # cache=True keys a launcher's cache on its file only: it also depends on the table and the bodies
    depend_on(out.values(), (file, __file__, *SOURCES, *(m.__file__ for m in _INLINED)))
    return out


_INLINED = (kernels, wall_field, field_grid)
globals().update(launchers(__name__, __file__))


# -- serial reductions ------------------------------------------------------------------------------
@njit(cache=True)
def mean(a):
    """Serial sum / n: the same bits whatever the thread count (loop criteria depend on it)."""
    s = 0.0
    for i in range(a.shape[0]):
        s += a[i]
    return s / max(a.shape[0], 1)


@njit(cache=True)
def mean_positive(a):
    """Serial sum of max(a_i, 0) / n (the same bits as mean(np.maximum(a, 0)))."""
    s = 0.0
    for i in range(a.shape[0]):
        s += max(a[i], 0.0)
    return s / max(a.shape[0], 1)


@njit(cache=True)
def speed_energy(v, m):
    """(max_i |v_i|, sum_i m_i |v_i|^2 / 2), serially for thread-count independent bits."""
    vmax2 = 0.0
    ke = 0.0
    for i in range(v.shape[0]):
        s2 = v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1] + v[i, 2] * v[i, 2]
        vmax2 = max(vmax2, s2)
        ke += 0.5 * m[i] * s2
    return np.sqrt(vmax2), ke


@njit(cache=True)
def first_unhealthy(x, v, lo, hi):
    """Index of the first particle with a non-finite position/velocity or outside [lo, hi], else -1."""
    for i in range(x.shape[0]):
        for c in range(3):
            if not (np.isfinite(x[i, c]) and np.isfinite(v[i, c])):
                return i
            if x[i, c] < lo[c] or x[i, c] > hi[c]:
                return i
    return -1


# -- element-wise updates (the same arithmetic, in the same order, as the numpy expressions) --------
@njit(cache=True)
def advance(x, v, dt, a, x_old):
    """x_old = x;  x += dt v + dt^2 a   (the inertial target, a = g)."""
    dt2 = dt * dt
    for i in range(x.shape[0]):
        for c in range(3):
            x_old[i, c] = x[i, c]
            x[i, c] += dt * v[i, c] + dt2 * a[c]


@njit(cache=True)
def displacement_velocity(x, x_old, dt, v):
    """v = (x - x_old) / dt."""
    for i in range(x.shape[0]):
        for c in range(3):
            v[i, c] = (x[i, c] - x_old[i, c]) / dt


@njit(cache=True)
def accelerate(v, dt, a):
    """v += dt a (one acceleration for all particles)."""
    for i in range(v.shape[0]):
        for c in range(3):
            v[i, c] += dt * a[c]


@njit(cache=True)
def warm_stiffness(k_total, scale, rate, n_nbrs, min_nbrs, warm):
    """DFSPH's warm start (method.md section 2): warm_i = 0.5 clamp(k_total_i scale, -0.5, 0.5) where
    rate_i > 0 and n_nbrs_i >= min_nbrs (every particle if `rate` is empty), else 0; then
    k_total = 0, ready to sum what the solve applies. (k_total < 0 only where the density solve is
    two-sided, bodies.TENSION_BAND.)"""
    masked = rate.shape[0] == k_total.shape[0]
    for i in range(k_total.shape[0]):
        on = (rate[i] > 0.0 and n_nbrs[i] >= min_nbrs) if masked else True
        warm[i] = 0.5 * max(min(k_total[i] * scale, 0.5), -0.5) if on else 0.0
        k_total[i] = 0.0
