"""The pair cache (sph_passes: mf grad W_ij kept for the pressure solves at fixed positions).

The cached passes must compute what the uncached ones do, from a cache filled by either of its
two filling passes (density_factor_lambda for DFSPH, the viscosity pass for IPSPH), and the
methods must use it only while it is valid and within `solver.pair_cache_mb`.
"""
import dataclasses

import numpy as np
import pytest

from ipsph.kernels import grad_w_factor
from ipsph.methods.sph_passes import (NO_DISPLACEMENT, NO_PAIR_CACHE, apply_stiffness, density_factor_lambda,
                                      density_residual, divergence_residual, xsph)
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
    scene = load_scene(default_scene_path(), [f"simulation.method={method}", f"simulation.end_time={end_time}",
                                              "simulation.particle_radius=0.04"])
    return dataclasses.replace(scene, solver=dataclasses.replace(scene.solver, pair_cache_mb=cache_mb))


@pytest.fixture(scope="module")
def splashing():
    """A dam break 0.3 s in: a moving, partly compressed state with walls."""
    scene = _scene("dfsph", 0.0)
    sim = Simulation(scene, *sample_scene(scene)[:3])
    sim.run()
    return sim


def _filled(sim, by):
    m, st = sim.method, sim.state
    xb, mb, nf, cf, nb, cb = m.lists()
    n, k = nf.shape
    cache = np.full((n, 3, k), np.nan)
    if by == "density":
        density_factor_lambda(st.x, m.mf, xb, mb, nf, cf, nb, cb, m.h, m.rho0, m.rho, m.alpha, m.lam, m.err,
                              m.n_nbrs, m.gb, cache)
    else:
        xsph(st.x, st.v, m.mf, m.rho, m.gb, m.lam, nf, cf, m.h, 0.01, 0.0, np.empty((n, 3)), np.empty(n),
             NO_DISPLACEMENT, cache)
    return cache


@pytest.mark.parametrize("by", ["density", "viscosity"])
def test_cache_holds_mf_grad_w_of_every_listed_pair(splashing, by):
    m, x = splashing.method, splashing.state.x
    _, _, nf, cf, _, _ = m.lists()
    cache = _filled(splashing, by)
    rows = np.repeat(np.arange(len(x)), cf)
    slots = np.concatenate([np.arange(c) for c in cf])
    j = nf[rows, slots]
    d = x[rows] - x[j]
    r = np.linalg.norm(d, axis=1)
    expected = m.mf * np.array([grad_w_factor(ri, m.h) for ri in r])[:, None] * d
    got = cache[rows, :, slots]
    scale = np.abs(expected).max()
    assert np.abs(got - expected).max() <= PASS_RTOL * scale


@pytest.mark.parametrize("by", ["density", "viscosity"])
def test_cached_passes_equal_the_uncached_ones(splashing, by):
    m, st = splashing.method, splashing.state
    _, _, nf, cf, _, _ = m.lists()
    cache = _filled(splashing, by)
    n, dt = st.n, 2e-3
    k = np.abs(np.random.default_rng(1).normal(size=n)) * 1e-3
    out = {}
    for name, pg in (("cached", cache), ("uncached", NO_PAIR_CACHE)):
        v, kt, drho, kk, err = st.v.copy(), np.zeros(n), np.empty(n), np.empty(n), np.empty(n)
        apply_stiffness(st.x, m.mf, m.gb, nf, cf, pg, m.h, k, dt, v, kt)
        divergence_residual(st.x, v, m.mf, m.gb, nf, cf, pg, m.h, m.alpha, m.n_nbrs, dt, drho, kk)
        density_residual(st.x, v, m.mf, m.gb, nf, cf, pg, m.h, m.rho, m.alpha, m.rho0, dt, err, kk)
        out[name] = v, drho, err
    for a, b in zip(out["cached"], out["uncached"]):
        assert np.abs(a - b).max() <= PASS_RTOL * np.abs(b).max()
    assert np.abs(out["cached"][0] - st.v).max() > 1e-6  # the correction did act


def _steps(method, cache_mb, n):
    scene = _scene(method, cache_mb)
    sim = Simulation(scene, *sample_scene(scene)[:3])
    used = []
    for _ in range(n):
        sim.step()
        used.append(sim.method.pair_grad.shape[0] == sim.n_fluid)
    order = np.argsort(sim.ids)
    return sim, sim.positions[order], sim.velocities[order], used


@pytest.mark.parametrize("method", ["dfsph", "ipsph"])
def test_methods_give_the_same_steps_with_and_without_the_cache(method):
    sim, x1, v1, used = _steps(method, 64.0, 12)
    _, x0, v0, unused = _steps(method, 0.0, 12)
    assert all(used) and not any(unused)
    assert np.abs(x1 - x0).max() <= TRAJECTORY_ATOL
    assert np.abs(v1 - v0).max() <= TRAJECTORY_ATOL
    # valid only until the particles are re-sorted
    sim.method.neighbour_search()
    assert sim.method.pair_grad.shape[0] == 0


def test_cache_stays_within_its_budget():
    sim, *_ = _steps("ipsph", 64.0, 1)
    n, k = sim.method.search.lists.fluid.shape
    need_mb = 24 * n * k / 2**20
    sim_small, *_, used = _steps("ipsph", 0.99 * need_mb, 2)
    assert not any(used)
    sim_fit, *_, used = _steps("ipsph", 1.01 * need_mb, 2)
    assert all(used)
    assert sim_fit.method.pair_grad.nbytes <= 1.01 * need_mb * 2**20


def test_pf_neither_fills_nor_reads_it():
    sim, *_, used = _steps("pf", 64.0, 3)
    assert not any(used) and sim.method._pair_store.shape[0] == 0
