"""The CPU launchers of the field walls' bodies (`field_bodies`): prange over the particles."""

import numpy as np
from numba import njit, prange

from . import bodies, field_bodies, field_grid, kernels
from . import wall_field as field_maths
from ._cache import depend_on
from .bodies import DENSITY_ROWS
from .cpu_passes import _buffers, _chunk
from .field_bodies import field_density_at, object_distance, wall_field_at, wall_pressure_at, wall_project_at
from .kernels import FASTMATH as FAST
from .kernels import w


# The prange loops call the bodies through these non-inlined wrappers: numba's parallel array
# analysis cannot follow the box integral's tuple arithmetic once it is inlined into the loop.
@njit(fastmath=FAST, cache=True)
def _field_one(i, x, h, rho0, wall, objects, wb, gw, gvb, ws):
    wall_field_at(i, x, h, rho0, wall, objects, wb, gw, gvb, ws)


@njit(fastmath=FAST, cache=True)
def _project_one(i, x, v, h, phi_min, objects, moved):
    wall_project_at(i, x, v, h, phi_min, objects, moved)


@njit(fastmath=FAST, cache=True)
def _distance_one(i, p, h, objects, out):
    best = np.inf
    for k in range(objects[0].shape[0]):
        best = min(best, object_distance(k, p[i, 0], p[i, 1], p[i, 2], objects)[0])
    out[i] = best


@njit(parallel=True, fastmath=FAST, cache=True)
def field_density_factor_lambda(
    x, mf, xb, mb, nf, cf, nb, cb, h, rho0, rho, alpha, lam, err, n_nbrs, gb, pair_grad, wb, gw, mirror
):
    """cpu_passes.density_factor_lambda with the field walls' wb, gw added (field_density_at): a launcher
    of its own, so the particle models' density pass compiles and runs exactly as it did."""
    fill = pair_grad.shape[0] == x.shape[0]
    w0 = w(0.0, h)
    bufs = _buffers(DENSITY_ROWS, nf, nb)
    for c in prange(bufs.shape[0]):
        lo, hi = _chunk(c, bufs.shape[0], x.shape[0])
        for i in range(lo, hi):
            field_density_at(
                i,
                x,
                mf,
                xb,
                mb,
                nf,
                cf,
                nb,
                cb,
                h,
                rho0,
                w0,
                fill,
                bufs[c],
                rho,
                alpha,
                lam,
                err,
                n_nbrs,
                gb,
                pair_grad,
                wb,
                gw,
                mirror,
            )


@njit(parallel=True, fastmath=FAST, cache=True)
def wall_field(x, h, rho0, wall, objects, wb, gw, gvb, ws):
    """field_bodies.wall_field_at for every particle."""
    for i in prange(x.shape[0]):
        _field_one(i, x, h, rho0, wall, objects, wb, gw, gvb, ws)


@njit(parallel=True, fastmath=FAST, cache=True)
def wall_pressure(gw, ws, g, rho0, dt, v):
    """field_bodies.wall_pressure_at for every particle."""
    for i in prange(v.shape[0]):
        wall_pressure_at(i, gw, ws, g[0], g[1], g[2], rho0, dt, v)


@njit(parallel=True, fastmath=FAST, cache=True)
def wall_project(x, v, h, phi_min, objects, moved):
    """field_bodies.wall_project_at for every particle; returns how many were moved."""
    for i in prange(x.shape[0]):
        _project_one(i, x, v, h, phi_min, objects, moved)
    return np.count_nonzero(moved)


@njit(parallel=True, cache=True)
def min_distance(p, h, objects, out):
    """out_i = min over the objects of phi_k(p_i) (host queries: sampling, checks)."""
    for i in prange(p.shape[0]):
        _distance_one(i, p, h, objects, out)


depend_on(
    (
        field_density_factor_lambda,
        wall_field,
        wall_pressure,
        wall_project,
        min_distance,
        _field_one,
        _project_one,
        _distance_one,
    ),
    (__file__, field_bodies.__file__, bodies.__file__, field_maths.__file__, field_grid.__file__, kernels.__file__),
)
