"""The hydrostatic seed (method.md section 1, issue 28): fluid at rest standing on walls starts the
warm starts from rho0 g depth, lowered towards free side faces; fluid in free fall gets none."""

import numpy as np

from ipsph.methods.settle import hydrostatic_pressure
from ipsph.scene import scene_from_dict
from ipsph.simulation import Simulation, sample_scene

R = 0.025
D = 2 * R


def _scene(fluid_max, tank_max=None, lift=0.0):
    d = {
        "simulation": {"method": "ipsph", "particle_radius": R, "settle": "off"},
        "fluid": [{"box": {"min": [0.0, lift, 0.0], "max": [fluid_max[0], fluid_max[1] + lift, fluid_max[2]]}}],
    }
    if tank_max is not None:
        d["boundary"] = [{"role": "container", "box": {"min": [0.0, 0.0, 0.0], "max": list(tank_max)}}]
    return scene_from_dict(d, name="seed")


def test_a_pool_gets_rho0_g_depth():
    scene = _scene((0.5, 0.5, 0.5), (0.5, 1.0, 0.5))  # fills the tank: no free side face
    fx, _, bx, _ = sample_scene(scene)
    p = hydrostatic_pressure(scene, fx, bx)
    top = fx[:, 1].max()
    np.testing.assert_allclose(p, 1000.0 * 9.81 * (top - fx[:, 1] + 0.5 * D), rtol=1e-12)


def test_a_free_face_lowers_it_and_free_fall_gets_none():
    scene = _scene((0.5, 0.5, 0.5), (1.5, 1.0, 0.5))  # a dam: free face at x = 0.5
    fx, _, bx, _ = sample_scene(scene)
    p = hydrostatic_pressure(scene, fx, bx)
    hydro = 1000.0 * 9.81 * (fx[:, 1].max() - fx[:, 1] + 0.5 * D)
    face = fx[:, 0] > fx[:, 0].max() - 0.5 * D
    back = fx[:, 0] < 0.5 * D + 0.5 * D
    assert np.all(p <= hydro + 1e-9) and np.all(p >= 0.0)
    assert p[face].max() < 0.1 * hydro.max()  # the face: near zero
    assert np.all(p[back] > 0.5 * hydro[back])  # against the back wall: most of it
    # the same block lifted off the floor (a gap of 2 d) is in free fall: nothing to seed
    lifted = _scene((0.5, 0.5, 0.5), (1.5, 1.0, 0.5), lift=2 * D)
    fx, _, bx, _ = sample_scene(lifted)
    assert not np.any(hydrostatic_pressure(lifted, fx, bx))
    no_walls = _scene((0.5, 0.5, 0.5))
    fx, _, bx, _ = sample_scene(no_walls)
    assert hydrostatic_pressure(no_walls, fx, bx) is None


def test_ipsph_starts_from_the_seed():
    scene = _scene((0.3, 0.6, 0.3), (0.9, 1.0, 0.3))
    sim = Simulation(scene, *sample_scene(scene)[:3])
    assert sim.method.dt_prev == sim.dt_next  # the warm start is on from the first step
    assert np.max(sim.pressures) > 0.25 * 1000.0 * 9.81 * 0.6  # frame 0 carries the seed (a narrow dam: < half)
    plain = Simulation(scene, *sample_scene(scene)[:3], settle=False)  # as a checkpoint restore
    assert plain.method.dt_prev is None and not np.any(plain.pressures)
