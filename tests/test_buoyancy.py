"""Bodies float where Archimedes says (issue 27; ipsph.boundary, method.md section 9).

The wall model `akinci-volume` puts an obstacle's or body's particle layer 0.6 d inside its surface,
where the fluid's volume then meets it; `akinci-surface` (the layer 0.1 d behind the surface) leaves
a fluid-free gap of d/2 around every body, which then displaces a box d larger than itself.
"""

from __future__ import annotations

import numpy as np
import pytest

from ipsph.bench.buoyancy import INSIDE_D, float_one, free_surface, penetration
from ipsph.geometry.shapes import scaled_box
from ipsph.simulation import Simulation

# Archimedes within 5 % (relative) of rho_b / rho0: the bound. Measured (3 s, the second half
# averaged): IPSPH 500 / 700 kg/m^3 at 6 d across -3.0 / +1.4 %, DFSPH -2.8 % and PF -2.4 % at 500; the
# 12 d cubes (500: +0.0 %, 900: +4.2 %) and the sphere (-4.7 %) are `ipsph bench --buoyancy`'s, and the
# earlier 0.1 d layer (-38 % at 500) its `--buoyancy-models akinci-surface` (kept out of the suite: a
# 12 d cube costs two minutes).
# Not asserted (method.md section 9): bodies whose draft is under about 4 d float too high (300 kg/m^3:
# -16 % at 6 d, -11 % at 12 d); the 900 kg/m^3 cube at 12 d is within 5 % (+4.2 %) but fluid gets
# 0.37 d into its top edges; at 6 d its 0.6 d of freeboard is below one spacing and it goes under.
ARCHIMEDES = 0.05


@pytest.mark.slow
@pytest.mark.parametrize(
    "method, n_across, density",
    [("ipsph", 6, 500.0), ("ipsph", 6, 700.0), ("dfsph", 6, 500.0), ("pf", 6, 500.0)],
)
def test_a_cube_floats_with_its_archimedes_draft(method, n_across, density):
    f = float_one(method, density, n_across)
    assert f.inside == 0, f"fluid got into the body ({f.penetration:.3f} d deep)"
    assert f.lost == 0
    assert abs(f.error) < ARCHIMEDES, (f.submerged, f.expected)


def _drop(method: str) -> dict:
    """A 2000 kg/m^3 box dropped from 0.5 m above the water of a tank: it plunges and comes to rest on
    the floor."""
    r = 0.0125
    return {
        "simulation": {"method": method, "particle_radius": r, "end_time": 1.6},
        "fluid": [{"box": {"min": [0, 0, 0], "max": [0.4, 0.15, 0.4]}}],
        "boundary": [
            {"name": "tank", "box": {"min": [0, 0, 0], "max": [0.4, 0.9, 0.4]}},
            {
                "name": "brick",
                "role": "obstacle",
                "density": 2000.0,
                "box": {"min": [0.125, 0.65, 0.125], "max": [0.275, 0.725, 0.275]},
            },
        ],
        "render": {"enabled": False},
    }


@pytest.mark.slow
@pytest.mark.parametrize("method", ["ipsph", "dfsph"])
def test_a_dropped_dense_body_keeps_the_fluid_out_and_rests_on_the_floor(method):
    scene = _drop(method)
    sim = Simulation.from_scene(scene)
    body = sim.walls.bodies[0]
    lo, hi = scaled_box(sim.scene.boundaries[1])
    n0, deepest = sim.n_fluid, [0.0]

    def on_step(_):
        deepest[0] = max(deepest[0], float(penetration(sim.positions, body, lo, hi).max()))

    sim.run(on_step=on_step)
    d = 2 * sim.scene.particle_radius
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    bottom = float(((corners - body.c0) @ body.rotation().T + body.c)[:, 1].min())
    assert deepest[0] < INSIDE_D * d, "fluid got into the body"
    assert sim.n_fluid == n0
    # on the floor through the contact, not on a film: its lowest corner within d/4 of the floor (y = 0)
    assert 0.0 < bottom < d / 4, bottom
    assert np.linalg.norm(body.v) < 0.05


@pytest.mark.slow
def test_a_dam_break_against_a_fixed_obstacle_keeps_out_of_it():
    """The deeper layer lets the fluid come 0.5 d closer to an obstacle's surface: a dam break that
    hits one at 3 m/s still puts no particle inside it."""
    r = 0.0125
    box = {"min": [0.55, 0.0, 0.15], "max": [0.7, 0.2, 0.3]}
    scene = {
        "simulation": {"method": "ipsph", "particle_radius": r, "end_time": 0.8},
        "fluid": [{"box": {"min": [0, 0, 0], "max": [0.3, 0.5, 0.45]}}],
        "boundary": [
            {"name": "tank", "box": {"min": [0, 0, 0], "max": [1.0, 0.7, 0.45]}},
            {"name": "block", "role": "obstacle", "box": box},
        ],
        "render": {"enabled": False},
    }
    sim = Simulation.from_scene(scene)
    lo, hi = np.array(box["min"]), np.array(box["max"])
    deepest, fastest = [0.0], [0.0]

    def on_step(s):
        x = sim.positions
        depth = np.minimum(x - lo, hi - x).min(axis=1)  # > 0 inside the block
        deepest[0] = max(deepest[0], float(depth.max()))
        fastest[0] = max(fastest[0], s.max_speed)

    sim.run(on_step=on_step)
    assert fastest[0] > 2.0, "the front must have hit the block fast"
    assert deepest[0] < INSIDE_D * 2 * r, deepest[0]


def test_free_surface_reads_the_level_of_a_lattice():
    """The measure the buoyancy figures rest on: a lattice whose top layer is at y reads y + d/2."""
    d = 0.025
    g = np.arange(16) * d
    x = np.stack(np.meshgrid(g, g[:8], g, indexing="ij"), axis=-1).reshape(-1, 3)
    assert free_surface(x, np.array([0.2, 0.0, 0.2]), 0.05, d) == pytest.approx(7 * d + d / 2)
