"""Wall models: where a boundary's particles sit and what they weigh (method.md sections 1 and 9).

A model provides what every pass needs of the walls, so that no method branches on it:

- `samples(spec, r)`: its particles for one `[[boundary]]` (a layer `offset` behind the surface);
- `particles(...)`: the `Boundary` the passes read, positions x_b, masses m_b = rho0 Psi_b and
  velocities v_b, whose state a checkpoint saves (`Boundary.state_dict`);
- the density and the density rate then take the walls as neighbours b (`backends/bodies.py`:
  rho_i += sum_b m_b W_ib, D rho_i/Dt += sum_b m_b (v_i - v_b) . grad W_ib), and the reaction on a
  moving wall is the opposite of what the pressure parts applied to the fluid through it
  (`rigid.wall_forces`).

A particle model is one entry of MODELS. The "field" model is not made of particles: it samples
no wall particles, and `field(scene)` hands the passes every wall as a shape instead
(`field_walls.FieldWalls`; the per-particle bodies are `backends/field_bodies.py`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import BoundarySpec, Role
from ..params import BOUNDARY_MODELS, FIELD_WALLS, spacing
from .particles import Boundary
from .sampling import boundary_positions

# Fluid at rest next to a single flat Akinci layer sits REST_DISTANCE_D d from it (the first layer of a
# half-lattice reads rho0 there: 1.10 d for face grids of 0.6-0.75 d, method.md section 1, "Walls").
REST_DISTANCE_D = 1.1
# A container's layer sits this far outside its surface (d): the fluid blocks' first layer, d inside
# (SPlisHSPlasH's FluidBlocks rule), is then at rest against it.
CONTAINER_OFFSET_D = REST_DISTANCE_D - 1.0


@dataclass(frozen=True)
class BoundaryModel:
    """A particle wall model: the depths of its layers behind the surface, in spacings d."""

    name: str
    summary: str
    container_offset_d: float  # outside a container's surface
    obstacle_depth_d: float  # inside an obstacle's or body's surface
    # the walls' share in the pressure terms, a multiple of the particle's own (Backend.wall_mirror):
    # 1 = once (Akinci), 2 = mirrored onto the wall (method.md section 11)
    pressure_mirror: float = 1.0
    # how far inside its faces a box fluid's first layer starts (d): a spacing for wall particles
    # (the layer's rest distance from theirs, SPlisHSPlasH's FluidBlocks rule), d/2 for field walls
    fluid_inset_d: float = 1.0

    def offset(self, spec: BoundarySpec, r: float) -> float:
        """How far the layer of `spec` sits behind its surface, away from the fluid (m)."""
        depth = self.container_offset_d if spec.role == Role.CONTAINER else self.obstacle_depth_d
        return depth * spacing(r)

    def samples(self, spec: BoundarySpec, r: float, *, cache: bool = True) -> np.ndarray:
        return boundary_positions(spec, r, self.offset(spec, r), cache=cache)

    def depths(self, specs, counts, r: float) -> np.ndarray:
        """Per wall particle, its layer's distance behind its surface (contacts act on surfaces)."""
        parts = [np.full(n, self.offset(spec, r)) for spec, n in zip(specs, counts)]
        return np.concatenate([np.zeros(0)] + parts)

    def particles(self, x, support, rho0, rest_lattice=None, spacing=None, groups=None, depth=None) -> Boundary:
        """The walls' particles with Akinci's volumes (fitted to `rest_lattice` when given)."""
        return Boundary(x, support, rho0, rest_lattice, spacing, groups, depth)

    def field(self, scene):
        """The walls as fields: none, the walls are these particles."""
        return None

    def keep_fluid(self, fluid_x: np.ndarray, scene) -> np.ndarray:
        """Which sampled fluid particles this model keeps beyond the overlap removal: all."""
        return np.ones(len(fluid_x), dtype=bool)


@dataclass(frozen=True)
class FieldModel(BoundaryModel):
    """Walls as shapes (field_walls.FieldWalls): no wall particles; the fluid starts d/2 from
    every surface, where the calibrated field puts the first layer at rest."""

    def samples(self, spec: BoundarySpec, r: float, *, cache: bool = True) -> np.ndarray:
        return np.zeros((0, 3))

    def field(self, scene):
        from .field_walls import FieldWalls

        return FieldWalls(scene)

    def surface_points(self, scene) -> np.ndarray:
        """Points on every wall surface (the domain's bounds, the settle and the hydrostatic seed
        read walls as points; the solver never sees them)."""
        r = scene.particle_radius
        return np.concatenate([np.zeros((0, 3))] + [boundary_positions(spec, r, 0.0) for spec in scene.boundaries])

    def keep_fluid(self, fluid_x: np.ndarray, scene) -> np.ndarray:
        """Fluid particles at least (1/2 - FIELD_START_TOL) d from every wall surface (containers
        and obstacles alike: phi >= d/2, the rest distance of the calibrated field)."""
        if not len(fluid_x) or not scene.boundaries:
            return np.ones(len(fluid_x), dtype=bool)
        return self.field(scene).distance(fluid_x) >= (0.5 - FIELD_START_TOL) * spacing(scene.particle_radius)


# A fluid lattice point this close (in d) under d/2 from a field wall still starts (rounding: a
# container's fluid box whose first layer sits exactly d/2 from the surface keeps it).
FIELD_START_TOL = 1e-6

MODELS = {
    m.name: m
    for m in (
        BoundaryModel(
            "akinci-volume",
            "one Akinci layer (REST_DISTANCE_D - 1/2) d = 0.6 d inside every obstacle and body: the "
            "fluid's volume meets their surface, so bodies displace their own volume (Archimedes)",
            CONTAINER_OFFSET_D,
            REST_DISTANCE_D - 0.5,
        ),
        BoundaryModel(
            "akinci-surface",
            "one Akinci layer 0.1 d behind every surface: the fluid's volume ends d/2 short of "
            "obstacles and bodies, which then float too high (a 500 kg/m^3 box 23-31 % submerged)",
            CONTAINER_OFFSET_D,
            CONTAINER_OFFSET_D,
        ),
        FieldModel(
            FIELD_WALLS,
            "no wall particles: every wall and body is a shape whose signed distance and exact kernel "
            "integral the fluid reads (method.md section 11); the fluid's first layer rests d/2 from the "
            "surfaces",
            0.0,
            0.0,
            pressure_mirror=1.0,
            fluid_inset_d=0.5,
        ),
    )
}
assert tuple(MODELS) == BOUNDARY_MODELS, "params.BOUNDARY_MODELS names the models implemented here"


def model_of(scene) -> BoundaryModel:
    """The wall model a scene selects (simulation.boundary_model)."""
    return MODELS[scene.boundary_model]
