"""The CPU launchers of the field walls' passes (`passes.PASSES` rows at home here, built by
`cpu_passes.launchers`), and `min_distance`, the host's query of the walls' distance."""

import numpy as np
from numba import njit, prange

from . import bodies, field_bodies, field_grid, kernels
from . import wall_field as field_maths
from ._cache import depend_on
from .cpu_passes import launchers
from .field_bodies import object_distance
from .kernels import FASTMATH as FAST


@njit(fastmath=FAST, cache=True)
def _distance_one(i, p, h, objects, out):
    best = np.inf
    for k in range(objects[0].shape[0]):
        best = min(best, object_distance(k, p[i, 0], p[i, 1], p[i, 2], objects)[0])
    out[i] = best


@njit(parallel=True, cache=True)
def min_distance(p, h, objects, out):
    """out_i = min over the objects of phi_k(p_i) (host queries: sampling, checks)."""
    for i in prange(p.shape[0]):
        _distance_one(i, p, h, objects, out)


depend_on(
    (min_distance, _distance_one),
    (__file__, field_bodies.__file__, bodies.__file__, field_maths.__file__, field_grid.__file__, kernels.__file__),
)

# the field walls' passes of the table (wall_field, wall_pressure, wall_project, the field density pass)
globals().update(launchers(__name__, __file__))
