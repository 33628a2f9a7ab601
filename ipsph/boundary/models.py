"""Wall models: where a boundary's particles sit and what they weigh (method.md sections 1 and 9).

A model provides what every pass needs of the walls, so that no method branches on it:

- `samples(spec, r)`: its particles for one `[[boundary]]` (a layer `offset` behind the surface);
- `particles(...)`: the `Boundary` the passes read, positions x_b, masses m_b = rho0 Psi_b and
  velocities v_b, whose state a checkpoint saves (`Boundary.state_dict`);
- the density and the density rate then take the walls as neighbours b (`backends/bodies.py`:
  rho_i += sum_b m_b W_ib, D rho_i/Dt += sum_b m_b (v_i - v_b) . grad W_ib), and the reaction on a
  moving wall is the opposite of what the pressure parts applied to the fluid through it
  (`rigid.wall_forces`).

A particle model is one entry of MODELS; a model that is not made of particles (a volume or
density map) would add its own per-particle bodies to the backends beside the particles'.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import BoundarySpec, Role
from ..params import BOUNDARY_MODELS, spacing
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
    )
}
assert tuple(MODELS) == BOUNDARY_MODELS, "params.BOUNDARY_MODELS names the models implemented here"


def model_of(scene) -> BoundaryModel:
    """The wall model a scene selects (simulation.boundary_model)."""
    return MODELS[scene.boundary_model]
