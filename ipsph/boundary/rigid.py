"""Moving walls: kinematic walls (prescribed motion, ipsph.boundary.motion) and dynamic rigid bodies two-way
coupled to the fluid (docs/method.md section 9).

`WallDriver` owns every moving [[boundary]] of a scene. The methods call it at two points of a
step (methods/base.py):

* `move(dt)`: put the moving walls where they are at t + dt (positions and velocities of their
  particles in `Boundary.x`, `Boundary.v`); a rigid body first integrates the forces of the last
  `reaction` (symplectic Euler, quaternions). PF and IPSPH move the walls before their neighbour
  search at the inertial target, so the projection sees them at t + dt; DFSPH after advection,
  before its end-of-step search.
* `reaction(...)`: the force and torque the fluid exerts on every moving wall in this step, from
  what the pressure parts applied to the fluid through that wall's particles (Akinci et al. 2012):

      F_b = mf P_i m_b grad W_ib   summed over fluid i,    P_i = K_i + (-Lam_i / (rho0 dt^2))

  with K the total stiffness the DFSPH-type solves applied (k = p / rho^2) and Lam the PF
  multipliers accumulated over the projection (method.md section 9 derives the PF part).
  The sum is a serial scatter over the fluid particles' wall lists (fixed order: reproducible).

Contacts (bodies with static walls and with each other) are one penalty spring-damper per pair
of walls in touch (contacts.py, method.md section 9).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..backends.kernels import grad_w_factor
from ..config import BoundarySpec, Scene
from .contacts import contact_forces
from .motion import Motion, quat_axis_angle, quat_matrix, quat_mul


@njit(cache=True)
def wall_forces(x, xb, mb, groups, nb, cb, coeff, mf, h, fb):
    """fb_b = sum_i mf coeff_i m_b grad W_ib over the fluid particles i that see b, for wall
    particles of moving groups (groups > 0); a serial scatter in a fixed order."""
    fb[:] = 0.0
    for i in range(x.shape[0]):
        ci = coeff[i]
        if ci == 0.0:
            continue
        for k in range(cb[i]):
            b = nb[i, k]
            if groups[b] <= 0:
                continue
            d0 = x[i, 0] - xb[b, 0]
            d1 = x[i, 1] - xb[b, 1]
            d2 = x[i, 2] - xb[b, 2]
            f = mf * ci * mb[b] * grad_w_factor(math.sqrt(d0 * d0 + d1 * d1 + d2 * d2), h)
            fb[b, 0] += f * d0
            fb[b, 1] += f * d1
            fb[b, 2] += f * d2


def mass_properties(spec: BoundarySpec, density: float) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass, centre of mass, inertia tensor about it) of the closed surface at `density`:
    the divergence theorem over the triangles' tetrahedra from the origin."""
    from ..geometry.shapes import boundary_surface

    mesh = boundary_surface(spec).triangulate()
    pts = np.asarray(mesh.points, dtype=np.float64)
    tri = np.asarray(mesh.faces).reshape(-1, 4)[:, 1:]
    a, b, c = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
    vol = np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0
    v_total = float(vol.sum())
    if v_total < 0.0:  # inward normals: the same body
        vol, v_total = -vol, -v_total
    com = (vol[:, None] * (a + b + c)).sum(axis=0) / (4.0 * v_total)
    s = a + b + c
    cov = sum(np.einsum("i,ij,ik->jk", vol, p, p) for p in (a, b, c, s)) / 20.0
    mass = density * v_total
    cov = density * cov - mass * np.outer(com, com)
    inertia = np.trace(cov) * np.eye(3) - cov
    return mass, com, inertia, v_total


class RigidBody:
    """A dynamic body: centre of mass c, orientation q, velocity v, angular velocity w (world)."""

    def __init__(self, name: str, group: int, spec: BoundarySpec, fluid_density: float):
        self.name = name
        self.group = group
        dens = spec.density
        mass, com, inertia, volume = mass_properties(spec, 1.0)
        if dens is None:
            dens = spec.mass / volume
        self.mass = dens * volume
        self.volume = volume
        self.c0 = com
        self.inertia_body = dens * inertia  # body frame = world frame at t = 0
        self.inv_inertia_body = np.linalg.inv(self.inertia_body)
        self.c = com.copy()
        self.q = np.array([1.0, 0.0, 0.0, 0.0])
        self.v = np.asarray(spec.velocity, dtype=np.float64).copy()
        self.w = np.radians(np.asarray(spec.angular_velocity, dtype=np.float64))
        self.force = np.zeros(3)  # fluid force and torque of the last reaction
        self.torque = np.zeros(3)
        self.contact_force = np.zeros(3)
        self.contact_torque = np.zeros(3)

    def rotation(self) -> np.ndarray:
        return quat_matrix(self.q)

    def inv_inertia(self) -> np.ndarray:
        """The inverse inertia tensor in the world frame, R I_body^-1 R^T."""
        r = self.rotation()
        return r @ self.inv_inertia_body @ r.T

    def integrate(self, dt: float, g: np.ndarray) -> None:
        """Symplectic Euler: velocities from the forces, then the pose from the new velocities."""
        r = self.rotation()
        inv_i = self.inv_inertia()
        i_w = r @ self.inertia_body @ r.T
        f = self.force + self.contact_force
        tau = self.torque + self.contact_torque
        self.v = self.v + dt * (f / self.mass + g)
        self.w = self.w + dt * (inv_i @ (tau - np.cross(self.w, i_w @ self.w)))
        self.c = self.c + dt * self.v
        ang = float(np.linalg.norm(self.w)) * dt
        if ang > 0.0:
            self.q = quat_mul(quat_axis_angle(self.w, ang), self.q)
            self.q /= np.linalg.norm(self.q)

    def correct(self, dt: float, df: np.ndarray, dtau: np.ndarray) -> None:
        """Velocities only: the impulse dt (df, dtau) that the last `integrate` did not know of."""
        self.v = self.v + dt * df / self.mass
        self.w = self.w + dt * (self.inv_inertia() @ dtau)

    def inverse_mass_at(self, point: np.ndarray, direction: np.ndarray) -> float:
        """1 / the mass a unit impulse along `direction` at `point` meets: 1/m + (r x n) . I^-1 (r x n),
        r from the centre of mass (a corner of a flat box: about m/6)."""
        arm = np.cross(point - self.c, direction)
        return 1.0 / self.mass + float(arm @ self.inv_inertia() @ arm)

    def place(self, x0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World positions and velocities of particles placed at x0 at t = 0."""
        rel = (x0 - self.c0) @ self.rotation().T
        return rel + self.c, self.v + np.cross(self.w, rel)

    def state(self) -> dict:
        return {
            k: np.array(getattr(self, k), dtype=np.float64)
            for k in ("c", "q", "v", "w", "force", "torque", "contact_force", "contact_torque")
        }

    def load(self, d: dict) -> None:
        for k, v in d.items():
            setattr(self, k, np.array(v, dtype=np.float64))


class WallDriver:
    """Every moving wall of a scene: its motion or body, `move`, `reaction`, the log rows."""

    def __init__(self, scene: Scene, boundary, support: float, mf: float):
        self.scene = scene
        self.boundary = boundary
        self.h = support
        self.mf = mf
        self.rho0 = scene.density0
        self.g = np.asarray(scene.gravity, dtype=np.float64)
        self.d = 2.0 * scene.particle_radius
        self.t = 0.0
        self.kinematic: list[tuple[int, str, Motion]] = []
        self.bodies: list[RigidBody] = []
        self.force = {}  # group -> (F, tau) of the last reaction, every moving wall
        x0, groups = boundary.x0, boundary.groups
        for k, spec in enumerate(scene.boundaries):
            grp = k + 1
            if not spec.moving:
                continue
            sel = groups == grp
            if spec.dynamic:
                self.bodies.append(RigidBody(spec.name, grp, spec, self.rho0))
            else:
                lo, hi = x0[sel].min(axis=0), x0[sel].max(axis=0)
                pivot = spec.motion.pivot if spec.motion.pivot is not None else 0.5 * (lo + hi)
                self.kinematic.append((grp, spec.name, Motion(spec.motion, pivot)))
            self.force[grp] = (np.zeros(3), np.zeros(3))
        self._fb = np.zeros((boundary.n, 3))
        self._predicted = None  # the forces the last move integrated (the prediction of the next reaction)
        self.surface_cache: dict = {}  # name -> the wall's surface at its placement (io.bodies)
        self.place(0.0)

    # -- the two calls of a step ---------------------------------------------------------------
    def place(self, t: float) -> None:
        """Positions and velocities of every moving wall's particles at time t (bodies: as they are)."""
        b = self.boundary
        self.t_walls = t
        for grp, _, motion in self.kinematic:
            sel = np.flatnonzero(b.groups == grp)
            b.x[sel] = motion.positions(b.x0[sel], t)
            b.v[sel] = motion.velocities(b.x0[sel], t)
        for body in self.bodies:
            sel = np.flatnonzero(b.groups == body.group)
            b.x[sel], b.v[sel] = body.place(b.x0[sel])

    def move(self, dt: float) -> None:
        """To t + dt: bodies integrate the last reaction's forces and their contacts first.

        When this step's reaction comes after the move (PF and IPSPH move the walls before their
        projection), the last reaction is only the prediction of this step's: `reaction` then
        corrects the bodies' velocities by the difference, so each step's impulse is its own
        reaction and fluid plus bodies conserve momentum at every step's end (the pose keeps the
        prediction: the walls do not move after the fluid was projected against them)."""
        if self.bodies:
            contact_forces(self.boundary, self.bodies, self.d, dt)
            for body in self.bodies:
                body.integrate(dt, self.g)
            self._predicted = {body.group: (body.force.copy(), body.torque.copy()) for body in self.bodies}
        self.place(self.t + dt)

    def reaction(self, x, lists, dt: float, lam=None, k=(), after_move: bool = False) -> None:
        """The fluid's force and torque on every moving wall in this step (module docstring)."""
        coeff = np.zeros(len(x))
        if lam is not None:
            coeff -= lam / (self.rho0 * dt * dt)
        for kk in k:
            coeff += kk
        b = self.boundary
        if len(self._fb) != b.n:
            self._fb = np.zeros((b.n, 3))
        wall_forces(x, b.x, b.m, b.groups, lists.boundary, lists.boundary_count, coeff, self.mf, self.h, self._fb)
        for grp in self.force:
            sel = np.flatnonzero(b.groups == grp)
            f = self._fb[sel]
            centre = self._centre(grp)
            self.force[grp] = (f.sum(axis=0), np.cross(b.x[sel] - centre, f).sum(axis=0))
        predicted = self._predicted if after_move else None
        for body in self.bodies:
            body.force, body.torque = self.force[body.group]
            if predicted is not None:  # the move of this step used the last reaction: correct it
                f0, tau0 = predicted[body.group]
                body.correct(dt, body.force - f0, body.torque - tau0)

    def _centre(self, grp: int) -> np.ndarray:
        for body in self.bodies:
            if body.group == grp:
                return body.c
        for g, _, motion in self.kinematic:
            if g == grp:
                r, tr = motion.pose(self.t_walls)
                return motion.pivot + tr
        raise KeyError(grp)

    # -- what the outputs and the clock read -----------------------------------------------------
    def max_speed(self) -> float:
        v = self.boundary.v
        return float(np.sqrt((v * v).sum(axis=1).max())) if len(v) else 0.0

    def rows(self, t: float) -> list[tuple]:
        """One bodies.csv row per moving wall: time, name, centre, quaternion, velocity, force, torque
        (kinematic walls: pivot, orientation and velocity of their motion)."""
        out = []
        for body in self.bodies:
            f, tau = self.force[body.group]
            out.append((t, body.name, *body.c, *body.q, *body.v, *f, *tau))
        for grp, name, motion in self.kinematic:
            r, tr = motion.pose(t)
            c = motion.pivot + tr
            h = 1e-6
            v = ((motion.positions(motion.pivot[None], t + h) - motion.positions(motion.pivot[None], t - h)) / (2 * h))[
                0
            ]
            f, tau = self.force[grp]
            out.append((t, name, *c, *_quat_of(r), *v, *f, *tau))
        return out

    def state_dict(self) -> dict[str, np.ndarray]:
        """Flat {key: array} (a checkpoint stores it as it is): the clock, every body's state, the
        last reaction and the kinematic walls' pivots (their groups and placements are the Boundary's)."""
        d = {"t": np.array(self.t), "t_walls": np.array(self.t_walls)}
        for body in self.bodies:
            d.update({f"body.{body.name}.{k}": v for k, v in body.state().items()})
        d.update({f"force.{g}": np.concatenate(ft) for g, ft in self.force.items()})
        d.update({f"pivot.{name}": m.pivot.copy() for _, name, m in self.kinematic})
        return d

    def load_state_dict(self, d: dict) -> None:
        self.t = float(d["t"])
        for body in self.bodies:
            body.load({k: d[f"body.{body.name}.{k}"] for k in body.state()})
        for g in self.force:
            ft = np.asarray(d[f"force.{g}"], dtype=np.float64)
            self.force[g] = (ft[:3].copy(), ft[3:].copy())
        for _, name, m in self.kinematic:
            m.pivot = np.asarray(d[f"pivot.{name}"], dtype=np.float64).copy()
        self.t_walls = float(d["t_walls"])  # the walls are where the saved step left them (the Boundary's state)


def _quat_of(r: np.ndarray) -> np.ndarray:
    """The unit quaternion (w, x, y, z) of a rotation matrix (w >= 0)."""
    w = math.sqrt(max(0.0, 1.0 + r[0, 0] + r[1, 1] + r[2, 2])) / 2.0
    x = math.copysign(math.sqrt(max(0.0, 1.0 + r[0, 0] - r[1, 1] - r[2, 2])) / 2.0, r[2, 1] - r[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1.0 - r[0, 0] + r[1, 1] - r[2, 2])) / 2.0, r[0, 2] - r[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1.0 - r[0, 0] - r[1, 1] + r[2, 2])) / 2.0, r[1, 0] - r[0, 1])
    return np.array([w, x, y, z])


def boundary_groups(scene: Scene, counts: list[int]) -> np.ndarray | None:
    """Per wall particle: 0 for a static wall, k + 1 for the moving scene.boundaries[k]; None
    when no wall moves (every wall as before: one volume group, no driver)."""
    if not any(b.moving for b in scene.boundaries):
        return None
    return np.concatenate(
        [np.zeros(0, dtype=np.int32)]
        + [
            np.full(n, (k + 1) if spec.moving else 0, dtype=np.int32)
            for k, (spec, n) in enumerate(zip(scene.boundaries, counts))
        ]
    )
