"""Boundary handling in one place: wall models, their particles and the walls that move.

models.py     what a wall model provides; MODELS (simulation.boundary_model)
sampling.py   a boundary's layer of wall particles, at the model's offset behind its surface
particles.py  `Boundary`: positions, Akinci volumes (fitted to the rest lattice), velocities
rigid.py      moving walls: kinematic walls, rigid bodies, the fluid's reaction
contacts.py   a body's contacts with the walls it touches (one spring-damper per pair)
motion.py     prescribed motion;  containers.py: the containers' boxes
field_walls.py   the "field" model's walls as shapes (FieldWalls; method.md section 11)
field.py         the box integral's tables and the calibration;  mesh_field.py, mesh_integral.py: mesh grids
"""

from .models import MODELS, BoundaryModel, model_of
from .particles import Boundary

__all__ = ["MODELS", "Boundary", "BoundaryModel", "model_of"]
