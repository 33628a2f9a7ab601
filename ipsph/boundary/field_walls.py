"""Field walls: every [[boundary]] as a shape the fluid reads through its signed distance and kernel
integral (wall model "field", method.md section 11), no wall particles.

`FieldWalls(scene)` holds one record per wall object, struct-of-arrays over objects, in the layout
`backends.field_bodies` reads (`arrays`): kind (box or ball), sign (+1 obstacle or body, -1
container), the pose (rotation R_k, centre c_k: x = R_k x_l + c_k), the shape's size (half extents
or radius), the cull distance, the velocity u_k and angular velocity omega_k about c_k, and the
quarter-space and octant tables of the box integral. Moving walls update the pose and velocities
in place (`set_pose`); everything else is fixed at construction.

Shapes: a box spec, and a mesh that is an axis-aligned box after its scale (SPlisHSPlasH's
UnitBox.obj) are boxes, exact by inclusion-exclusion. Other closed meshes are grids of (phi, I) in
their body frame (`mesh_field`, built once and cached on disk), read by tricubic interpolation.
"""

from __future__ import annotations

import numpy as np

from ..config import Role, Scene
from ..errors import ConfigError
from ..geometry import meshes
from ..geometry.shapes import mesh_path, prepared_mesh, rigid_part, scaled_box
from . import field
from .mesh_field import field_for_spec

BOX, SPHERE, GRID = 0, 1, 2  # backends.field_bodies' kinds
KINDS = {"box": BOX, "sphere": SPHERE, "grid": GRID}
PHI_MIN_D = 0.1  # the projection keeps every fluid particle this many d outside every surface (brief section 8)


def _box_of(spec) -> tuple[np.ndarray, np.ndarray] | None:
    """(lo, hi) of a box spec, or of a mesh that is an axis-aligned box after its scale; else None."""
    if spec.shape == "box":
        return scaled_box(spec)
    from ..config import Transform

    scaled, _ = prepared_mesh(
        mesh_path(spec), Transform(scale=spec.transform.scale), need_closed=False, allow_open=True
    )
    return meshes.aligned_box(scaled)


def _pool(grids) -> tuple[np.ndarray, np.ndarray]:
    """The grids' header rows (offsets into one pool) and their pool, float32 as built."""
    from ..backends.field_grid import HDR_OFFSET, HEADER

    if not grids:
        return np.zeros((0, HEADER)), np.zeros(2, dtype=np.float32)
    hdr = np.concatenate([g.header for g in grids]).astype(np.float64)
    offset = 0
    for row, g in zip(hdr, grids):
        row[HDR_OFFSET] = offset
        offset += len(g.pool) // 2
    return np.ascontiguousarray(hdr), np.ascontiguousarray(np.concatenate([g.pool for g in grids]))


class FieldWalls:
    """The wall objects of a scene as fields (module docstring)."""

    def __init__(self, scene: Scene):
        if scene.backend != "cpu":
            raise ConfigError(
                f'simulation.boundary_model = "field" runs on the CPU backend only so far (method.md section 11), '
                f'not simulation.backend = "{scene.backend}"'
            )
        h = scene.support
        self.h = h
        self.names = [spec.name for spec in scene.boundaries]
        n = len(scene.boundaries)
        self.kind = np.zeros(n, dtype=np.int32)
        self.sign = np.ones(n)
        self.rot = np.tile(np.eye(3), (n, 1, 1))
        self.pos = np.zeros((n, 3))
        self.size = np.zeros((n, 3))
        self.reach = np.full(n, h)  # I_k = 0 beyond one support from the shape
        self.vel = np.zeros((n, 3))
        self.omega = np.zeros((n, 3))
        self.moving = np.array([spec.moving for spec in scene.boundaries], dtype=bool)
        grids = []
        for k, spec in enumerate(scene.boundaries):
            if spec.moving:
                raise ConfigError(
                    f"boundary '{spec.name}' moves: simulation.boundary_model = \"field\" has static walls only so far "
                    f'(method.md section 11); use simulation.boundary_model = "akinci-volume" for moving walls and bodies'
                )
            rigid = rigid_part(spec.transform)
            r = meshes.rotation_matrix(rigid.rotate_axis, rigid.rotate_deg)
            self.rot[k] = r
            self.sign[k] = -1.0 if spec.role == Role.CONTAINER else 1.0
            box = _box_of(spec)
            if box is None:  # a general closed mesh: its grid, in the frame of its scaled vertices
                grid = field_for_spec(spec, h)
                self.kind[k] = GRID
                self.size[k, 0] = len(grids)
                self.pos[k] = np.asarray(rigid.translate, float)
                grids.append(grid)
                continue
            lo, hi = np.asarray(box[0], float), np.asarray(box[1], float)
            self.pos[k] = r @ (0.5 * (lo + hi)) + np.asarray(rigid.translate, float)
            self.size[k] = 0.5 * (hi - lo)
        self.hdr, self.pool = _pool(grids)
        self.pos0, self.rot0 = self.pos.copy(), self.rot.copy()  # the placement at t = 0
        self.qtab, self.otab = field.tables()
        self.wall = field.wall_profile()
        self.phi_min = PHI_MIN_D * scene.spacing

    @property
    def n(self) -> int:
        return len(self.kind)

    @property
    def any_moving(self) -> bool:
        return bool(self.moving.any())

    def arrays(self) -> tuple:
        """The objects as `backends.field_bodies` takes them (host arrays)."""
        return (
            self.kind,
            self.sign,
            self.rot,
            self.pos,
            self.size,
            self.reach,
            self.vel,
            self.omega,
            self.qtab,
            self.otab,
            self.hdr,
            self.pool,
        )

    def set_pose(self, k: int, rot: np.ndarray, pos: np.ndarray, vel: np.ndarray, omega: np.ndarray) -> None:
        """Object k's pose (x = rot x_l + pos) and velocities (omega about pos) now."""
        self.rot[k] = rot
        self.pos[k] = pos
        self.vel[k] = vel
        self.omega[k] = omega

    def state_dict(self) -> dict[str, np.ndarray]:
        return {"rot": self.rot.copy(), "pos": self.pos.copy(), "vel": self.vel.copy(), "omega": self.omega.copy()}

    def load_state_dict(self, d: dict[str, np.ndarray]) -> None:
        for key in ("rot", "pos", "vel", "omega"):
            getattr(self, key)[...] = d[key]

    # -- host queries (sampling, checks) -----------------------------------------------------------
    def distance(self, points: np.ndarray) -> np.ndarray:
        """The smallest signed distance phi over the objects at each point (positive in the fluid)."""
        from ..backends.cpu_field import min_distance

        p = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 3))
        out = np.full(len(p), np.inf)
        if len(p) and self.n:
            min_distance(p, self.h, self.arrays(), out)
        return out

    def reading(self, points: np.ndarray, rho0: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """(rho_b, gb) the walls add at each point: rho0 Lambda(I) and its gradient."""
        wb, gw, _ = self._fields(points, rho0)
        return wb, gw

    def support(self, points: np.ndarray) -> np.ndarray:
        """The walls' support along their faces at each point, (n, 6): xx, yy, zz, xy, xz, yz of
        M = sum_f c_f (I - n_f n_f) (method.md section 11)."""
        return self._fields(points, 1.0)[2]

    def _fields(self, points, rho0):
        from ..backends.base import Densities
        from ..backends.cpu_field import wall_field

        p = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 3))
        shapes = {**Densities.FIELD, "gvb": ()}
        wb, gw, gvb, ws, wm = (np.zeros((len(p), *shapes[name])) for name in ("wb", "gw", "gvb", "ws", "wm"))
        if len(p) and self.n:
            wall_field(p, self.h, rho0, self.wall, self.arrays(), wb, gw, gvb, ws, wm)
        return wb, gw, wm
