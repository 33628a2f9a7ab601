"""The implicit viscosity (issue 30, method.md section 10): the operator, its walls, a transient
with a closed form, a thick fluid that holds its shape at the CFL step, Taylor-Couette flow, and
the keys.

Closed forms used:
- spin-down of a free fluid cylinder (no walls, no gravity): u_theta(r, t) = U J1(k r) exp(-nu k^2 t)
  with k R = j_{2,1} (the first zero of J2: the rim is stress-free, r d/dr(u/r) = 0; the flat ends
  are stress-free too, as u does not depend on the axial coordinate);
- Taylor-Couette: u(r) = A r + B / r, A = -Omega R1^2 / (R2^2 - R1^2), B = Omega R1^2 R2^2 / (R2^2 - R1^2).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from test_cli_errors import assert_refused, scene_file

from ipsph.backends import cpu_passes as P
from ipsph.methods.viscosity import full_trace
from ipsph.scene import scene_from_dict
from ipsph.simulation import Simulation

# -- tolerances ---------------------------------------------------------------------------------
# A linear shear u = gamma y next to a flat box wall (no-slip at its surface) is a steady state of
# the continuous equations, so the discrete operator's residual at the first fluid layer must
# vanish: the walls' share s* that cancels it is 1 when the walls complete the neighbourhood
# exactly. Measured 1.0001; a wall term off by a factor of two (mirrored ghosts) or missing reads
# 0.5 or infinity.
FLAT_WALL_SHARE_TOL = 0.02
# The volume-weighted product <a, A b> = sum_i V_i a_i . (A b)_i makes A symmetric: CG needs it.
# Only rounding may break it (sums of ~1e3 terms of size ~1): 1e-10 relative.
SYMMETRY_TOL = 1e-10
# Spin-down: the 5 % on the profile (radial bins of width d), at t = tau/4 and tau/2,
# inside the rim's free-surface layer (r < R - H). The operator decays the mode 6-8 % fast at
# r = 0.005; the outermost kernel support H, where the free surface leaves particles without
# their outer neighbours, reads up to 15 % low there, which takes the whole profile's L2 to
# 6.3 % at tau/2 (4 % at tau/4): measured, not tested. Inside: 1.5 % and 2.1 % (IPSPH and DFSPH).
TRANSIENT_TOL = 0.05
# The thick cube (issue 30): < 10 % height lost in 0.5 s at nu = 10 m^2/s (g L t / nu = 0.05);
# measured 7.4 % at r = 0.00625 (mostly the first steps, where the lattice takes its weight).
CUBE_HEIGHT_LOSS = 0.10
# ... while the inviscid cube collapses: its top falls below half its height (a dam break of a
# 0.1 m column reaches the floor's level in ~0.2 s).
INVISCID_TOP = 0.5
# density error within the IPSPH tolerance (0.05 %, solver.ipsph.density_error_pct) at the end.
DENSITY_TOL = 0.05e-2
# Taylor-Couette: the 5 % is NOT met (method.md section 10, "What is not reached").
# Where the no-slip acts [derived there]: the walls' completion puts the wall's velocity on the
# missing neighbours, about one spacing d beyond the fluid's edge particles. Those rest s* = 1.1 d
# from a wall's particle layer, which sits 0.6 d inside an obstacle's surface (the inner cylinder:
# boundary_model akinci-volume) and on a mesh container's (the outer one, edge particles 1-2 d
# away): no-slip at R1 - 0.5 d and about R2. Measured at r = 0.005 (5 particles across the gap,
# free ends, mid-layers), binned L2 against the analytic profile with the surfaces' radii
# 0.39 (nu = 10) and 0.38 (nu = 0.1 m^2/s), with (R1 - 0.5 d, R2) 0.22 and 0.20; the operator's
# own steady state falls with resolution on both counts (0.39 -> 0.32 and 0.21 -> 0.19 from
# r = 0.005 to 0.0033). These bounds hold what is true today.
TAYLOR_COUETTE_TOL = 0.45  # against R1, R2
TAYLOR_COUETTE_SHIFTED_TOL = 0.25  # against R1 - 0.5 d, R2 (where the completion puts the no-slip)
# A thick planar slump from a SPlisHSPlasH 2.12-2.15 scene (issue 42): the front against Huppert's
# (1982) similarity solution x_N = 1.411 (g A^3 t / (3 nu))^(1/5), A the half-area per unit width,
# valid once the front is well past the block's half-length (1.8 x at 1.5 s). Measured at r = 5 mm,
# nu = 1 m^2/s: -9 %, -2 %, +4 % at 1, 1.5 and 2 s; the scene read with the old numbers (an XSPH
# filter of strength 1) reaches the channel's end, +220 % at 1.5 s.
SLUMP_FRONT_TOL = 0.10


def _cylinder_obj(path, radius, y0, y1, n=96):
    """A closed cylinder about the y axis (outward faces) as an OBJ file."""
    ang = 2 * math.pi * np.arange(n) / n
    ring = np.stack([radius * np.cos(ang), np.zeros(n), radius * np.sin(ang)], 1)
    pts = np.concatenate([ring + [0, y0, 0], ring + [0, y1, 0], [[0, y0, 0], [0, y1, 0]]])
    faces = []
    for k in range(n):
        a, b = k, (k + 1) % n
        faces += [(a, n + a, n + b), (a, n + b, b), (2 * n, a, b), (2 * n + 1, n + b, n + a)]
    with open(path, "w") as f:
        f.writelines(f"v {p[0]} {p[1]} {p[2]}\n" for p in pts)
        f.writelines("f " + " ".join(str(i + 1) for i in t) + "\n" for t in faces)
    return str(path)


def _implicit(nu, **sim):
    return {
        "viscosity": 0.0,
        "viscosity_model": "implicit",
        "kinematic_viscosity_m2s": nu,
        "settle": "off",
        **sim,
    }


def _operator(sim, v, wall_factor):
    """(A v - b) with nu dt = 1 at the simulation's current positions (bodies.viscous_*_at)."""
    m = sim.method
    x, nl, d, w = m.state.x, m.lists, m.data.dens, m.boundary
    n = len(x)
    b, diag, wm, out, pd = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 6)), np.zeros((n, 3)), np.zeros(n)
    full = full_trace(sim.spacing, m.fluid.h)
    args = (nl.fluid, nl.fluid_count, nl.boundary, nl.boundary_count, m.fluid.h, m.fluid.rho0, 1.0, wall_factor)
    P.viscous_setup(x, v, m.fluid.mf, d.rho, w.x, w.m, w.v, *args, full, b, diag, wm)
    P.viscous_apply(x, v, m.fluid.mf, d.rho, nl.fluid, nl.fluid_count, m.fluid.h, 1.0, wm, out, pd)
    return out - b, out, pd


def _box_sim():
    return Simulation.from_scene(
        scene_from_dict(
            {
                "simulation": _implicit(1.0, method="dfsph", particle_radius=0.01),
                "fluid": [{"box": {"min": [0, 0, 0], "max": [0.3, 0.2, 0.3]}}],
                "boundary": [{"name": "box", "box": {"min": [0, 0, 0], "max": [0.3, 0.4, 0.3]}}],
            },
            name="box",
        )
    )


def test_linear_shear_next_to_a_flat_wall_is_a_steady_state():
    sim = _box_sim()
    x = sim.method.state.x
    v = np.zeros_like(x)
    v[:, 0] = x[:, 1]  # u = y: no-slip at the floor's surface y = 0, shear 1/s
    free, _, _ = _operator(sim, v, 0.0)
    walled, _, _ = _operator(sim, v, 1.0)
    mid = (np.abs(x[:, 0] - 0.15) < 0.05) & (np.abs(x[:, 2] - 0.15) < 0.05)
    first = mid & (np.abs(x[:, 1] - sim.spacing) < 1e-9)
    f, w = free[first, 0].mean(), walled[first, 0].mean() - free[first, 0].mean()
    assert abs(-f / w - 1.0) < FLAT_WALL_SHARE_TOL, -f / w
    second = mid & (np.abs(x[:, 1] - 3 * sim.spacing) < 1e-9)  # the interior: no wall, no residual
    assert np.abs(walled[second, 0]).max() < 1e-6 * np.abs(f)


def test_operator_is_symmetric_in_the_volume_weighted_product():
    sim = _box_sim()
    rng = np.random.default_rng(3)
    x = sim.method.state.x
    a, b = rng.standard_normal(x.shape), rng.standard_normal(x.shape)
    vol = sim.method.fluid.mf / sim.method.data.dens.rho
    _, ab, _ = _operator(sim, b, 1.0)
    _, aa, pdot = _operator(sim, a, 1.0)
    lhs, rhs = np.sum(vol[:, None] * a * ab), np.sum(vol[:, None] * aa * b)
    assert abs(lhs - rhs) <= SYMMETRY_TOL * abs(lhs)
    assert np.all(pdot.sum() > 0)  # positive definite: <a, A a> > 0
    assert np.isclose(pdot.sum(), np.sum(vol[:, None] * a * aa))


# -- the transient: spin-down of a free fluid cylinder -----------------------------------------
def _bessel(n, z, terms=40):
    z = np.asarray(z, float)
    return sum((-1) ** m * (z / 2) ** (2 * m + n) / (math.factorial(m) * math.factorial(m + n)) for m in range(terms))


def _first_zero_of_j2():
    lo, hi = 5.0, 5.3  # j_{2,1} = 5.1356
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if _bessel(2, lo) * _bessel(2, mid) <= 0 else (mid, hi)
    return 0.5 * (lo + hi)


def _azimuthal(x, v):
    r = np.hypot(x[:, 0], x[:, 2])
    t_hat = np.stack([-x[:, 2], np.zeros_like(r), x[:, 0]], 1) / np.maximum(r, 1e-12)[:, None]
    return r, np.sum(v * t_hat, 1), t_hat


def _binned_l2(r, u, exact, edges):
    """L2 of the radial profile (bin means against the closed form at the bins' mean radii)."""
    num = den = 0.0
    for lo, hi in zip(edges[:-1], edges[1:]):
        k = (r >= lo) & (r < hi)
        if k.sum() >= 3:
            e = exact(r[k].mean())
            num += k.sum() * (u[k].mean() - e) ** 2
            den += k.sum() * e**2
    return math.sqrt(num / den)


@pytest.mark.parametrize("method", ["ipsph", "dfsph"])
@pytest.mark.slow
def test_spin_down_of_a_free_cylinder_follows_the_bessel_mode(tmp_path, method):
    nu, radius, rc, u0 = 0.01, 0.005, 0.1, 0.05
    mesh = _cylinder_obj(tmp_path / "disc.obj", rc, 0.0, 0.06, n=128)
    scene = scene_from_dict(
        {
            "simulation": _implicit(nu, method=method, particle_radius=radius, gravity=[0, 0, 0]),
            "fluid": [{"name": "disc", "mesh": mesh}],
        },
        name="spin",
    )
    sim = Simulation.from_scene(scene)
    x = sim.positions
    r, _, t_hat = _azimuthal(x, np.zeros_like(x))
    k = _first_zero_of_j2() / (r.max() + radius)  # the fluid's edge: half a spacing past its last particles
    peak = float(_bessel(1, 1.8412))  # max of J1
    sim.state.v[:] = (u0 / peak) * _bessel(1, k * r)[:, None] * t_hat
    tau = 1.0 / (nu * k * k)
    edges = np.arange(0.0, rc - sim.support + 1e-9, sim.spacing)  # inside the free surface's layer
    for t in (0.25 * tau, 0.5 * tau):
        sim.run(end_time=t, fps=1.0 / t)
        r, u, _ = _azimuthal(sim.positions, sim.velocities)
        decay = math.exp(-nu * k * k * sim.time)
        err = _binned_l2(r, u, lambda q, d=decay: (u0 / peak) * d * float(_bessel(1, k * q)), edges)
        assert err < TRANSIENT_TOL, (t, err)
        assert np.abs(sim.velocities[:, 1]).max() < 0.05 * u0  # stays in its plane


# -- a thick fluid at the CFL step --------------------------------------------------------------
def _cube(model, nu):
    sim = {"method": "ipsph", "particle_radius": 0.00625, "end_time": 0.5, "viscosity": 0.0, "settle": "off"}
    sim.update({"viscosity_model": model, "kinematic_viscosity_m2s": nu})
    return Simulation.from_scene(
        scene_from_dict(
            {
                "simulation": sim,
                "fluid": [{"name": "cube", "box": {"min": [0.2, 0.0, 0.2], "max": [0.3, 0.1, 0.3]}}],
                "boundary": [{"name": "plate", "box": {"min": [0, 0, 0], "max": [0.5, 0.4, 0.5]}}],
            },
            name=f"cube-{model}",
        )
    )


def _top(sim):
    """The top of the cube's middle: the highest particle within 2 cm of its axis."""
    x = sim.positions
    mid = (np.abs(x[:, 0] - 0.25) < 0.02) & (np.abs(x[:, 2] - 0.25) < 0.02)
    return x[mid, 1].max() if mid.any() else 0.0


@pytest.mark.slow
def test_thick_cube_holds_its_shape_at_the_cfl_step_while_an_inviscid_one_collapses():
    thick = _cube("implicit", 10.0)
    h0 = _top(thick)
    dts, errs = [], []
    thick.run(end_time=0.5, fps=10, on_step=lambda s: (dts.append(s.dt), errs.append(s.density_error_mean)))
    assert 1.0 - _top(thick) / h0 < CUBE_HEIGHT_LOSS, _top(thick) / h0
    assert np.all(np.isfinite(thick.velocities)) and np.abs(thick.velocities).max() < 0.1
    assert errs[-1] <= DENSITY_TOL
    # the step is the CFL rule's (here its cap dt_max), 1,900 x the explicit limit H^2 / (60 nu)
    assert min(dts) >= thick.dt_max * (1 - 1e-9) and thick.scene.viscous_dt == math.inf
    water = _cube("xsph", 0.0)
    water.run(end_time=0.5, fps=10)
    assert _top(water) < INVISCID_TOP * h0, _top(water) / h0


def test_only_the_explicit_model_limits_the_step():
    base = {"fluid": [{"box": {"min": [0, 0, 0], "max": [0.2, 0.2, 0.2]}}], "render": {"enabled": False}}
    for model, limited in (("standard", True), ("implicit", False)):
        scene = scene_from_dict({"simulation": _implicit(1.0, viscosity_model=model, particle_radius=0.05), **base})
        assert (scene.viscous_dt < math.inf) is limited


# -- Taylor-Couette --------------------------------------------------------------------------------
R1, R2, OMEGA = 0.05, 0.1, 1.0  # inner radius, outer radius [m], inner cylinder's rate [rad/s]


def _couette(r, r1=R1, r2=R2):
    """u(r) = A r + B / r with u(r1) = OMEGA r1 (the inner wall's speed there) and u(r2) = 0."""
    a = -OMEGA * r1**2 / (r2**2 - r1**2)
    b = OMEGA * r1**2 * r2**2 / (r2**2 - r1**2)
    return a * r + b / r


@pytest.mark.parametrize("nu, t_end", [(10.0, 0.05), (0.1, 0.1)])
@pytest.mark.slow
def test_taylor_couette_profile(tmp_path, nu, t_end):
    """Fluid between a fixed outer cylinder and an inner one turning at Omega (a kinematic wall),
    no gravity, free ends (a short axis: the flow does not depend on it), from rest to steady
    (t_end = 20 and 4 times the slowest mode's time gap^2 / (pi^2 nu)), dt from the CFL rule."""
    outer = _cylinder_obj(tmp_path / "outer.obj", R2, -0.1, 0.2)
    inner = _cylinder_obj(tmp_path / "inner.obj", R1, -0.15, 0.25)
    spin = {"type": "constant", "angular_velocity": [0.0, -math.degrees(OMEGA), 0.0], "pivot": [0, 0, 0]}
    scene = scene_from_dict(
        {
            "simulation": _implicit(nu, method="ipsph", particle_radius=0.005, gravity=[0, 0, 0]),
            "fluid": [{"name": "gap", "box": {"min": [-R2, 0.0, -R2], "max": [R2, 0.1, R2]}}],
            "boundary": [
                {"name": "outer", "mesh": outer},
                {"name": "inner", "role": "obstacle", "mesh": inner, "motion": spin},
            ],
        },
        name="couette",
    )
    sim = Simulation.from_scene(scene)
    dts = []
    sim.run(end_time=t_end, fps=1.0 / t_end, on_step=lambda s: dts.append(s.dt))
    assert min(dts) >= sim.dt_max * (1 - 1e-9)  # the CFL rule's step, no viscous limit
    x = sim.positions
    mid = (x[:, 1] > 0.03) & (x[:, 1] < 0.075)  # away from the free ends
    r, u, _ = _azimuthal(x[mid], sim.velocities[mid])
    edges = np.linspace(R1, R2, 11)
    err = _binned_l2(r, u, lambda q: float(_couette(q)), edges)
    shifted = _binned_l2(r, u, lambda q: float(_couette(q, R1 - 0.5 * sim.spacing)), edges)
    assert err < TAYLOR_COUETTE_TOL and shifted < TAYLOR_COUETTE_SHIFTED_TOL, (err, shifted)
    means = [u[(r >= lo) & (r < hi)].mean() for lo, hi in zip(edges[:-1], edges[1:]) if ((r >= lo) & (r < hi)).sum()]
    assert all(a >= b for a, b in zip(means, means[1:])) and means[0] <= OMEGA * R1 * 1.01, means


# -- the keys ---------------------------------------------------------------------------------------
def test_a_viscosity_without_a_model_that_uses_it_is_refused(tmp_path, capsys):
    s = scene_file(tmp_path, "[simulation]\nparticle_radius = 0.04\nkinematic_viscosity_m2s = 0.5\n")
    line = assert_refused(capsys, tmp_path / "out", s)
    assert "kinematic_viscosity_m2s" in line and 'viscosity_model = "implicit"' in line, line


def test_the_old_standard_viscosity_key_names_its_replacement(tmp_path, capsys):
    s = scene_file(tmp_path, "[simulation]\nparticle_radius = 0.04\nstandard_viscosity = 0.5\n")
    line = assert_refused(capsys, tmp_path / "out", s)
    assert "simulation.standard_viscosity was replaced" in line and "kinematic_viscosity_m2s" in line, line


@pytest.mark.slow
def test_a_thick_slump_imported_from_splishsplash_2_12_follows_huppert(tmp_path):
    """viscosityMethod 6 with flat keys is Weiler 2018 in SPlisHSPlasH 2.12-2.15 (ipsph's importer
    read it as an XSPH filter until issue 42): a 0.2 x 0.2 m block of nu = 1 m^2/s centred in a
    channel 0.1 m wide and 1.2 m long spreads on its no-slip floor at Huppert's rate."""
    import json

    from ipsph.scene import load_scene

    nu, half_area, t_end = 1.0, 0.1 * 0.2, 1.5
    material = {"viscosityMethod": 6, "viscosity": nu, "viscosityBoundary": nu, "viscoMaxError": 0.01}
    unit_box = Path(__file__).resolve().parents[1] / "meshes" / "UnitBox.obj"
    scene = {
        "Configuration": {"particleRadius": 0.005, "stopAt": t_end},
        "Materials": [{"id": "Fluid", "density0": 1000, **material}],
        "RigidBodies": [
            {"geometryFile": str(unit_box), "translation": [0, 0.3, 0.05], "scale": [1.2, 0.6, 0.1], "isWall": True}
        ],
        "FluidBlocks": [{"start": [-0.1, 0.0, 0.0], "end": [0.1, 0.2, 0.1]}],
    }
    path = tmp_path / "slump.json"
    path.write_text(json.dumps(scene))
    sim = Simulation.from_scene(load_scene(path, ["simulation.method=ipsph"]))
    assert sim.scene.viscosity_model == "implicit"
    sim.run(end_time=t_end, fps=10)
    front = np.percentile(np.abs(sim.positions[:, 0]), 99.5)  # the two fronts, past a stray particle
    huppert = 1.411 * (9.81 * half_area**3 * t_end / (3 * nu)) ** 0.2
    assert abs(front / huppert - 1) < SLUMP_FRONT_TOL, front / huppert
