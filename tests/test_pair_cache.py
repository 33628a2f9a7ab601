"""The pair cache (mf grad W_ij kept for the pressure solves at fixed positions).

The cached passes must compute what the uncached ones do, from a cache filled by either of its
two filling passes (the density pass for DFSPH, the viscosity pass for IPSPH), and the methods
must hand the solves the cache those passes returned, within `solver.pair_cache_mb`.
"""

import dataclasses

import numpy as np
import pytest

from ipsph.backends.cpu import CPUBackend
from ipsph.backends.cpu_passes import (
    NO_DISPLACEMENT,
    NO_PAIR_CACHE,
    apply_stiffness,
    density_factor_lambda,
    density_residual,
    divergence_residual,
    xsph,
)
from ipsph.backends.kernels import grad_w_factor
from ipsph.scene import default_scene_path, load_scene
from ipsph.simulation import Simulation, sample_scene

# The cached and the uncached passes sum the same float64 products in another association
# (mf (sum f d) against sum (mf f d)): they agree to a few ulps of the largest term, far below
# anything a wrong factor, sign, index or stale cache produces (>= 1e-3 relative).
PASS_RTOL = 1e-12
# Over a few steps the rounding differences above stay at round-off size; a method that read
# a stale or wrongly filled cache moves particles by a visible fraction of a spacing (>= 1e-4 m).
TRAJECTORY_ATOL = 1e-9  # m, and m/s


def _scene(method, cache_mb, end_time=0.3):
    scene = load_scene(
        default_scene_path(),
        [f"simulation.method={method}", f"simulation.end_time={end_time}", "simulation.particle_radius=0.04"],
    )
    return dataclasses.replace(scene, solver=dataclasses.replace(scene.solver, pair_cache_mb=cache_mb))


@pytest.fixture(scope="module")
def splashing():
    """A dam break 0.3 s in: a moving, partly compressed state with walls."""
    scene = _scene("dfsph", 0.0)
    sim = Simulation(scene, *sample_scene(scene)[:3])
    sim.run()
    return sim


def _filled(sim, by):
    st, d, fl, nl, b = sim.state, sim.method.data.dens, sim.method.fluid, sim.search.lists, sim.boundary
    nf, cf = nl.fluid, nl.fluid_count
    n, k = nf.shape
    cache = np.full((n, 3, k), np.nan)
    if by == "density":
        density_factor_lambda(
            st.x,
            fl.mf,
            b.x,
            b.m,
            nf,
            cf,
            nl.boundary,
            nl.boundary_count,
            fl.h,
            fl.rho0,
            d.rho,
            d.alpha,
            d.lam,
            d.err,
            d.n_nbrs,
            d.gb,
            cache,
        )
    else:
        xsph(
            st.x,
            st.v,
            fl.mf,
            d.rho,
            d.gb,
            d.gvb,
            d.lam,
            nf,
            cf,
            fl.h,
            0.01,
            0.0,
            np.empty((n, 3)),
            np.empty(n),
            NO_DISPLACEMENT,
            cache,
            1.0,
        )
    return cache


@pytest.mark.parametrize("by", ["density", "viscosity"])
@pytest.mark.slow
def test_cache_holds_mf_grad_w_of_every_listed_pair(splashing, by):
    fl, x = splashing.method.fluid, splashing.state.x
    nf, cf = splashing.search.lists.fluid, splashing.search.lists.fluid_count
    cache = _filled(splashing, by)
    rows = np.repeat(np.arange(len(x)), cf)
    slots = np.concatenate([np.arange(c) for c in cf])
    j = nf[rows, slots]
    d = x[rows] - x[j]
    r = np.linalg.norm(d, axis=1)
    expected = fl.mf * np.array([grad_w_factor(ri, fl.h) for ri in r])[:, None] * d
    got = cache[rows, :, slots]
    scale = np.abs(expected).max()
    assert np.abs(got - expected).max() <= PASS_RTOL * scale


@pytest.mark.parametrize("by", ["density", "viscosity"])
@pytest.mark.slow
def test_cached_passes_equal_the_uncached_ones(splashing, by):
    fl, st, d = splashing.method.fluid, splashing.state, splashing.method.data.dens
    nf, cf = splashing.search.lists.fluid, splashing.search.lists.fluid_count
    cache = _filled(splashing, by)
    n, dt = st.n, 2e-3
    k = np.abs(np.random.default_rng(1).normal(size=n)) * 1e-3
    out = {}
    for name, pg in (("cached", cache), ("uncached", NO_PAIR_CACHE)):
        v, kt, drho, kk, err = st.v.copy(), np.zeros(n), np.empty(n), np.empty(n), np.empty(n)
        apply_stiffness(st.x, fl.mf, d.gb, d.wm, nf, cf, pg, fl.h, k, dt, v, kt, 1.0)
        divergence_residual(st.x, v, fl.mf, d.gb, d.gvb, nf, cf, pg, fl.h, d.alpha, d.n_nbrs, dt, drho, kk)
        density_residual(st.x, v, fl.mf, d.gb, d.gvb, d.wb, nf, cf, pg, fl.h, d.rho, d.alpha, fl.rho0, dt, err, kk)
        out[name] = v, drho, err
    for a, b in zip(out["cached"], out["uncached"]):
        assert np.abs(a - b).max() <= PASS_RTOL * np.abs(b).max()
    assert np.abs(out["cached"][0] - st.v).max() > 1e-6  # the correction did act


class SolveSpy(CPUBackend):
    """The CPU backend, noting whether each stiffness pass of the solves was handed a filled cache."""

    def __init__(self):
        super().__init__()  # the backend's precision and its empty arrays
        self.calls = []

    def apply_stiffness(self, x, mf, dens, nl, pairs, h, k, dt, v, k_total):
        self.calls.append(pairs.shape[0] == x.shape[0])
        super().apply_stiffness(x, mf, dens, nl, pairs, h, k, dt, v, k_total)


def _steps(method, cache_mb, n):
    scene = _scene(method, cache_mb)
    spy = SolveSpy()
    sim = Simulation(scene, *sample_scene(scene)[:3], backend=spy)
    used = []
    for _ in range(n):
        spy.calls.clear()
        sim.step()
        used += spy.calls
    order = np.argsort(sim.ids)
    return sim, sim.positions[order], sim.velocities[order], used


@pytest.mark.parametrize("method", ["dfsph", "ipsph"])
@pytest.mark.slow
def test_methods_give_the_same_steps_with_and_without_the_cache(method):
    sim, x1, v1, used = _steps(method, 64.0, 12)
    _, x0, v0, unused = _steps(method, 0.0, 12)
    assert used and all(used) and not any(unused)
    assert np.abs(x1 - x0).max() <= TRAJECTORY_ATOL
    assert np.abs(v1 - v0).max() <= TRAJECTORY_ATOL


def test_cache_stays_within_its_budget():
    sim, *_ = _steps("ipsph", 64.0, 1)
    n, k = sim.search.lists.fluid.shape
    need_mb = 24 * n * k / 2**20
    sim_small, *_, used = _steps("ipsph", 0.99 * need_mb, 2)
    assert used and not any(used)
    sim_fit, *_, used = _steps("ipsph", 1.01 * need_mb, 2)
    assert used and all(used)
    assert 0 < sim_fit.method.pair_cache_nbytes <= 1.01 * need_mb * 2**20


def test_pf_neither_fills_nor_reads_it():
    sim, *_, used = _steps("pf", 64.0, 3)
    assert sim.method.pair_cache_nbytes == 0
