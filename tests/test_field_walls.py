"""The "field" wall model in the solver (method.md section 11): walls read as shapes through the
density pass, no wall particles, the lattice at rest reading rho0, the position projection, and
what the model refuses. The maths of the field itself is tests/test_wall_field.py."""

from dataclasses import replace

import numpy as np
import pytest

from ipsph import Simulation
from ipsph.backends.cpu import CPUBackend
from ipsph.boundary.field_walls import PHI_MIN_D, FieldWalls
from ipsph.errors import ConfigError
from ipsph.sampling.scene import sample_scene
from ipsph.scene import scene_from_dict

R = 0.04
D = 2 * R
# The calibrated field makes the first layer of a half-lattice against a flat face read rho0 exactly
# (test_wall_field); through the solver's density pass the floor's lattice reads it to rounding.
FLOOR_TOL = 1e-6
# Edges and corners of a box tank: the calibrated exact integral over-reads a concave edge by
# +0.9 % and a concave corner by +1.7 % at rest lattice points (brief section 3, recomputed in
# test_wall_field); the bound is 2 %.
EDGE_CORNER_TOL = 0.02


def tank(method="dfsph", width=0.56, **sim):
    """A 7^3 lattice whose outer layers sit d/2 from a box tank's faces (the field's rest distance)."""
    keys = {"method": method, "particle_radius": R, "end_time": 1.0, "boundary_model": "field", "settle": "off"}
    keys.update(sim)
    return scene_from_dict(
        {
            "simulation": keys,
            "time_step": {"dt_max": 0.005},
            # filling the tank: the field model starts a box fluid's layers d/2 inside its faces
            "fluid": [{"name": "c", "box": {"min": [0, 0, 0], "max": [width, 0.56, width]}}],
            "boundary": [
                {"name": "t", "role": "container", "box": {"min": [0, 0, 0], "max": [width, 1.0, width]}},
            ],
        },
        name="field-tank",
    )


@pytest.mark.slow  # compiles the field passes
def test_a_field_tank_has_no_wall_particles_and_its_lattice_reads_rho0():
    scene = tank()
    fluid_x, fluid_v, boundary_x = sample_scene(scene)[:3]
    assert len(boundary_x) == 0
    assert len(fluid_x) == 7**3, "the lattice d/2 from every face is kept whole"
    sim = Simulation(scene, fluid_x, fluid_v, boundary_x, settle=False)
    assert sim.n_boundary == 0 and sim.search.lists.boundary.shape[1] == 0
    dens = sim.method.data.dens
    x = sim.be.to_host(sim.method.state.x)
    rho = dens.rho / scene.density0
    h = scene.support
    near = x < h  # within a support of the faces at 0 (x, y, z)
    far = x[:, [0, 2]] > 0.56 - h
    walls = near.sum(axis=1) + far.sum(axis=1)
    floor_only = (x[:, 1] < D) & (walls == 1)  # the first layer, beyond the support of the side walls
    assert np.all(np.abs(rho[floor_only] - 1.0) <= FLOOR_TOL), rho[floor_only]
    deep = x[:, 1] < 0.56 - 2 * D  # below the free surface's support
    edges_corners = deep & (walls >= 2)
    assert edges_corners.sum() >= 4 * 5 + 4  # the vertical edges, the floor's edges and corners, their neighbours
    assert np.all(np.abs(rho[edges_corners] - 1.0) <= EDGE_CORNER_TOL), rho[edges_corners].max()
    interior = deep & (walls == 0) & (x[:, 1] > 2 * D)
    assert np.all(np.abs(rho[interior] - 1.0) <= 1e-3)  # the full lattice sum itself (1.0000)
    assert np.all(dens.gb[floor_only, 1] < 0.0), "the walls' gradient points into the floor"


@pytest.mark.slow  # compiles the field passes
def test_the_density_pass_adds_the_field_to_the_fluid_sum():
    """wb and gw of the field pass are in rho and gb (and only there: a particle beyond the support
    of every wall reads no wall)."""
    scene = tank()
    sim = Simulation(scene, *sample_scene(scene)[:3], settle=False)
    dens, st = sim.method.data.dens, sim.method.state
    x = sim.be.to_host(st.x)
    wb, gw = FieldWalls(scene).reading(x, scene.density0)
    np.testing.assert_allclose(dens.wb, wb, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(dens.gw, gw, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(dens.gb, gw, rtol=1e-12, atol=1e-9)  # no wall particles: gb is the field's
    away = np.all((x > scene.support) & (x < 0.56 - scene.support), axis=1)
    assert away.any() and np.all(dens.wb[away] == 0.0)


@pytest.mark.slow
@pytest.mark.parametrize("method", ["dfsph", "ipsph"])
def test_nothing_gets_closer_than_phi_min_to_a_wall(method):
    """Two lone particles, one thrown at the floor at 3 m/s from 1.75 d (the wall's density stops
    it near 0.35 d), one started 0.05 d above it moving down: the projection lifts the second to
    PHI_MIN_D d at once (IPSPH; DFSPH's solve lifts it alone), nothing ever gets closer, and the
    projections are counted."""
    scene = scene_from_dict(
        {
            "simulation": {"method": method, "particle_radius": R, "boundary_model": "field", "settle": "off"},
            "time_step": {"dt_max": 0.005},
            "fluid": [{"name": "c", "box": {"min": [0.2, 0.1, 0.2], "max": [0.32, 0.22, 0.32]}}],
            "boundary": [{"name": "t", "role": "container", "box": {"min": [0, 0, 0], "max": [0.56, 1.0, 0.56]}}],
        },
        name="field-drop",
    )
    fx, fv, bx = sample_scene(scene)[:3]
    fx = np.array([fx[0], fx[0] + [2 * D, 0.0, 0.0]])
    fx[1, 1] = 0.05 * D
    fv = np.array([[0.0, -3.0, 0.0], [0.0, -1.0, 0.0]])
    sim = Simulation(scene, fx, fv, bx, settle=False)
    projected, lowest = 0, np.inf
    for _ in range(40):
        s = sim.step()
        projected += s.wall_projections
        lowest = min(lowest, float(sim.positions[:, 1].min()))
    assert lowest >= PHI_MIN_D * D * (1 - 1e-9), f"{method}: reached {lowest / D:.3f} d above the floor"
    assert projected >= (1 if method == "ipsph" else 0)  # DFSPH's solve lifts the second past it alone
    # the projection itself: lifted to PHI_MIN_D d along the floor's normal, its velocity into the
    # floor removed, the one along it kept
    x = np.array([[0.28, 0.05 * D, 0.28]])
    v = np.array([[0.3, -1.0, 0.0]])
    moved = np.zeros(1, dtype=np.int32)
    assert sim.be.wall_project(x, v, sim.boundary.field, moved) == 1 and moved[0] == 1
    np.testing.assert_allclose(x, [[0.28, PHI_MIN_D * D, 0.28]], rtol=1e-12)
    np.testing.assert_allclose(v, [[0.3, 0.0, 0.0]], atol=1e-12)


def test_the_field_model_refuses_what_it_cannot_do_yet(tmp_path):
    base = {
        "simulation": {"particle_radius": R, "boundary_model": "field"},
        "fluid": [{"name": "c", "box": {"min": [0.1, 0.1, 0.1], "max": [0.3, 0.3, 0.3]}}],
    }
    moving = dict(
        base,
        boundary=[
            {
                "name": "p",
                "box": {"min": [0, 0, 0], "max": [0.05, 0.5, 0.5]},
                "motion": {"type": "constant", "velocity": [1, 0, 0]},
            }
        ],
    )
    with pytest.raises(ConfigError, match="moves"):
        FieldWalls(scene_from_dict(moving, name="m"))
    cuda = dict(base, simulation=dict(base["simulation"], backend="cuda"))
    with pytest.raises(ConfigError, match="CPU backend only"):
        FieldWalls(scene_from_dict(cuda, name="c"))


@pytest.mark.slow  # compiles the field passes
def test_a_mesh_obstacle_is_a_grid_in_its_own_frame(tmp_path):
    """A closed mesh that is not a box becomes a (phi, I) grid (boundary.mesh_field), placed by
    the spec's rotation and translation: its distance is negative inside, positive outside."""
    (tmp_path / "tet.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    scene = scene_from_dict(
        {
            "simulation": {"particle_radius": R, "boundary_model": "field"},
            "fluid": [{"name": "c", "box": {"min": [2, 0, 0], "max": [2.3, 0.3, 0.3]}}],
            "boundary": [
                {"name": "rock", "role": "obstacle", "mesh": str(tmp_path / "tet.obj"), "translate": [1, 0, 0]}
            ],
        },
        name="t",
    )
    walls = FieldWalls(scene)
    assert walls.kind[0] == 2 and len(walls.hdr) == 1
    phi = walls.distance(np.array([[1.1, 0.1, 0.1], [0.5, 0.5, 0.5], [1.5, 0.5, 0.5]]))
    assert phi[0] < 0.0 < phi[1] and phi[2] > 0.0
    np.testing.assert_allclose(phi[0], -0.1, atol=0.02)  # 0.1 m inside its three faces at the corner


@pytest.mark.slow  # compiles the field passes
def test_every_wall_model_carries_the_pressure_once():
    """The particle models' walls take the particle's pressure once (bit-identical to the models
    before the field existed); so does the field, whose wall term is then k_i times the gradient of
    the very rho_b its density reads (variational, method.md section 11; a mirrored 2 k_i gb pumped
    energy into a tank at rest)."""
    be = CPUBackend()
    scene = tank()
    Simulation(scene, *sample_scene(scene)[:3], backend=be, settle=False)
    assert be.wall_mirror == 1.0
    akinci = scene_from_dict(
        {
            "simulation": {"particle_radius": R, "settle": "off"},
            "fluid": [{"name": "c", "box": {"min": [0, 0, 0], "max": [0.3, 0.3, 0.3]}}],
            "boundary": [{"name": "t", "role": "container", "box": {"min": [0, 0, 0], "max": [0.56, 1.0, 0.56]}}],
        },
        name="akinci",
    )
    Simulation(akinci, *sample_scene(akinci)[:3], backend=be, settle=False)
    assert be.wall_mirror == 1.0


# The support of a flat face is c = Lambda / (1 - Lambda) = e^mu - 1 across the face's tangent plane
# (method.md section 11); checked to rounding against the reading of the same point.
SUPPORT_TOL = 1e-12


@pytest.mark.slow  # compiles the field passes
def test_the_walls_support_runs_along_their_faces():
    """A container's support is its faces' c_f (I - n_f n_f): on the floor diag(c, 0, c), at an edge
    the two faces' sum; an obstacle's (here a turned box) c (I - n n) with n its distance's gradient;
    nothing beyond the walls' reach."""
    scene = tank()
    walls = FieldWalls(scene)
    floor, edge, far = [0.28, D / 2, 0.28], [D / 2, D / 2, 0.28], [0.28, 0.3, 0.28]
    m = walls.support(np.array([floor, edge, far]))
    lam = walls.reading(np.array([floor]))[0][0]
    c = lam / (1.0 - lam)
    assert 0.1 < c < 0.3  # tau0 / (1 - tau0) = 0.176 at d/2
    np.testing.assert_allclose(m[0], [c, 0, c, 0, 0, 0], atol=SUPPORT_TOL)
    np.testing.assert_allclose(m[1], [c, c, 2 * c, 0, 0, 0], atol=SUPPORT_TOL)  # floor (y) and x = 0 faces
    assert np.all(m[2] == 0.0)
    # the same container turned about its centre: its support turns with it, R M R^T
    t = np.radians(30.0)
    rot = np.array([[np.cos(t), -np.sin(t), 0], [np.sin(t), np.cos(t), 0], [0, 0, 1]])
    centre = walls.pos[0].copy()
    walls.rot[0] = rot
    mt = walls.support((np.array([floor, edge]) - centre) @ rot.T + centre)
    for mi, ti in zip(m[:2], mt):
        full = np.array([[mi[0], mi[3], mi[4]], [mi[3], mi[1], mi[5]], [mi[4], mi[5], mi[2]]])
        turned = rot @ full @ rot.T
        np.testing.assert_allclose(ti, turned[[0, 1, 2, 0, 0, 1], [0, 1, 2, 1, 2, 2]], atol=SUPPORT_TOL)
    # an obstacle reads its one signed distance: a box turned 30 degrees about z, beside its faces
    turned = scene_from_dict(
        {
            "simulation": {"particle_radius": R, "boundary_model": "field"},
            "fluid": [{"name": "c", "box": {"min": [0.6, 0, 0], "max": [0.9, 0.3, 0.3]}}],
            "boundary": [
                {
                    "name": "b",
                    "role": "obstacle",
                    "box": {"min": [-0.2, -0.2, -0.2], "max": [0.2, 0.2, 0.2]},
                }
            ],
        },
        name="turned",
    )
    bw = FieldWalls(turned)
    t = np.radians(30.0)
    rot = np.array([[np.cos(t), -np.sin(t), 0], [np.sin(t), np.cos(t), 0], [0, 0, 1]])
    bw.rot[0] = rot  # (a scene's box is axis-aligned; a turned mesh box is placed the same way)
    normals = rot @ np.eye(3)  # the faces' normals +x, +y, +z in world axes (columns)
    p = (0.2 + D / 2) * normals.T
    lam = bw.reading(p)[0]
    c = lam / (1.0 - lam)
    for mi, ni, ci in zip(bw.support(p), normals.T, c):
        mat = np.array([[mi[0], mi[3], mi[4]], [mi[3], mi[1], mi[5]], [mi[4], mi[5], mi[2]]])
        np.testing.assert_allclose(mat, ci * (np.eye(3) - np.outer(ni, ni)), atol=SUPPORT_TOL)
        assert ci > 0.1


# Momentum of a pressure update: each pair's force is exact and opposite in exact arithmetic, so the
# sum over the fluid is a cancellation of terms of size |dv| (rounding: ~1e-16 relative per term).
MOMENTUM_TOL = 1e-12


@pytest.mark.slow  # compiles the field passes
def test_the_support_in_a_pressure_update_conserves_momentum():
    """v_i -= dt sum_j mf (k_i + k_j) (I + (M_i + M_j)/2) grad W_ij: with the walls' own term gb set
    aside, the fluid's momentum does not change (the pair term is antisymmetric), with the pair cache
    and without; and the support changes the update near the walls only."""
    scene = tank()
    sim = Simulation(scene, *sample_scene(scene)[:3], settle=False)
    be, meth = sim.be, sim.method
    n, mf, h, dt = sim.n_fluid, meth.fluid.mf, meth.fluid.h, 0.004
    x, nl = meth.state.x, meth.lists
    dens = meth.data.dens
    pairs = be.densities(x, mf, sim.boundary, nl, h, meth.fluid.rho0, dens, be.pair_buffer(n, nl.fluid.shape[1]))
    k = np.random.default_rng(1).uniform(0.0, 1.0, n)
    dv = {}
    for support in (True, False):
        d = replace(dens, gb=np.zeros_like(dens.gb), wm=dens.wm if support else np.zeros((0, 6)))
        for name, cache in (("plain", be.NO_PAIRS), ("cached", pairs)):
            v, kt = np.zeros((n, 3)), np.zeros(n)
            be.apply_stiffness(x, mf, d, nl, cache, h, k, dt, v, kt)
            dv[support, name] = v
            scale = np.abs(v).sum(axis=0).max()
            assert np.all(np.abs(v.sum(axis=0)) <= MOMENTUM_TOL * scale), (support, name, v.sum(axis=0))
    np.testing.assert_allclose(dv[True, "cached"], dv[True, "plain"], rtol=1e-9, atol=1e-12)
    changed = np.abs(dv[True, "plain"] - dv[False, "plain"]).max(axis=1) > 1e-12
    xs = be.to_host(x)
    reach = np.minimum(np.minimum(xs, 0.56 - xs)[:, [0, 2]].min(axis=1), xs[:, 1])
    assert changed.any() and np.all(reach[changed] < 2 * scene.support)  # within reach + a support of a face


@pytest.mark.slow  # compiles the field passes
def test_the_density_solve_resists_expansion_near_rest_with_field_walls_only():
    """With field walls the density residual is two-sided near rest density (bodies.TENSION_BAND):
    rho_err = max(rho*, rho0) - rho0 + TENSION_WEIGHT min(rho* - rho0, 0) where rho >= (1 - band) rho0;
    at v = 0 (static walls) rho* = rho. Without field walls it stays BK17's max(rho*, rho0) - rho0."""
    from ipsph.backends.bodies import TENSION_BAND, TENSION_WEIGHT

    scene = tank()
    sim = Simulation(scene, *sample_scene(scene)[:3], settle=False)
    be, meth = sim.be, sim.method
    dens, n, fl = meth.data.dens, sim.n_fluid, meth.fluid
    rho = dens.rho.copy()
    rho[::3] *= 0.97  # some inside the band and below rest density
    rho[1::7] *= 0.9  # some below it
    for field in (True, False):
        d = replace(dens, rho=rho, wb=dens.wb if field else np.zeros(0))
        err, k = np.zeros(n), np.zeros(n)
        be.density_residual(
            meth.state.x, np.zeros((n, 3)), fl.mf, d, meth.lists, be.NO_PAIRS, fl.h, fl.rho0, 0.004, err, k
        )
        want = np.maximum(rho, fl.rho0) - fl.rho0
        if field:
            band = rho >= (1.0 - TENSION_BAND) * fl.rho0
            want = want + np.where(band, TENSION_WEIGHT * np.minimum(rho - fl.rho0, 0.0), 0.0)
            assert (want < 0).sum() >= n // 4
        np.testing.assert_allclose(err, want, rtol=1e-12, atol=1e-9)
