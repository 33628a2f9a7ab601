"""`ipsph bench --buoyancy`: floating boxes against Archimedes (method.md section 9).

One cube of density rho_b per tank, `n` spacings d across, placed at its Archimedes draft below the
level the tank will settle at; after `end_time` s the submerged volume fraction (the body's volume
below the free surface, from its pose) is averaged over the second half of the run and compared with
rho_b / rho0. The free surface is the median top particle, plus d/2, over the columns of width d that
lie at least 2 d beyond the body's faces; the tank is wide enough (5 d of water around the body) that
the level is flat there.

    ipsph bench --buoyancy                                   # ipsph, 300-900 kg/m^3, 6 and 12 across
    ipsph bench --buoyancy --methods ipsph dfsph pf --buoyancy-models akinci-volume akinci-surface
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..boundary import MODELS
from ..geometry.shapes import scaled_box
from ..params import spacing

PAD_D = 5  # water around the body, in spacings, on every side
DEPTH_BELOW_D = 3  # water under a body at its draft, in spacings
FREEBOARD_LIMIT_D = 1.0  # below one spacing of freeboard a body is awash: the resolution limit
MESH_SIZE_D = 8  # the sphere's and the bunny's largest extent, in spacings
# The body's volume is integrated over a SAMPLES^3 grid in its own frame: the fraction to 1/SAMPLES^3.
SAMPLES = 16
# A fluid particle counts as inside a body when its centre has reached the body's wall layer, the
# model's depth under the surface (0.6 d). Between the surface and the layer a single layer is thinnest
# at convex edges (a quarter of a face's support), and fluid pressed against an edge gets into that band:
# at rest at most 0.24 d (the cubes, the sphere), in 3 m/s impacts 0.27-0.29 d (method.md section 9).
INSIDE_D = MODELS["akinci-volume"].obstacle_depth_d


@dataclass
class Float:
    """One floating run's outcome."""

    method: str
    model: str
    density: float
    n_across: int
    fluid: int
    submerged: float  # mean over the second half
    heave: float  # its standard deviation
    inside: int  # most fluid particles deeper than INSIDE_D d inside the body at any step
    penetration: float  # the deepest any fluid particle got under the surface, in d
    lost: int  # fluid particles lost during the run
    seconds: float

    @property
    def expected(self) -> float:
        return self.density / 1000.0

    @property
    def error(self) -> float:
        """Relative error of the submerged fraction against Archimedes."""
        return self.submerged / self.expected - 1.0

    @property
    def awash(self) -> bool:
        """Freeboard below FREEBOARD_LIMIT_D spacings: the resolution limit (method.md section 9)."""
        return (1.0 - self.expected) * self.n_across < FREEBOARD_LIMIT_D


def scene(
    method: str, density: float, n_across: int, r: float = 0.0125, end_time: float = 3.0, model=None, height=1.0
) -> dict:
    """A tank with one box of `density`, `n_across` d wide and deep and `height` times that tall, at its
    Archimedes draft below the level the water will have (a cube by default)."""
    from ..scene import scene_from_dict
    from ..simulation import sample_scene

    d = spacing(r)
    a = n_across * d
    slot = a + 2 * PAD_D * d
    frac = density / 1000.0
    tall = height * a
    depth = frac * tall + DEPTH_BELOW_D * d + 0.5 * d
    top = depth + tall + 4 * d
    level = depth  # first guess; then the level the sampled water will settle at (twice)
    for _ in range(3):
        bottom = level - frac * tall
        box = {"min": [PAD_D * d, bottom, PAD_D * d], "max": [PAD_D * d + a, bottom + tall, PAD_D * d + a]}
        sim = {"method": method, "particle_radius": r, "end_time": end_time}
        if model is not None:
            sim["boundary_model"] = model
        spec = {
            "simulation": sim,
            "fluid": [{"box": {"min": [0, 0, 0], "max": [slot, depth + d, slot]}}],
            "boundary": [
                {"name": "tank", "box": {"min": [0, 0, 0], "max": [slot, top, slot]}},
                {"name": "cube", "role": "obstacle", "density": float(density), "box": box},
            ],
            "render": {"enabled": False},
        }
        fluid_x = sample_scene(scene_from_dict(spec))[0]
        # the water fills the tank less d/2 at the walls and the floor (its first layer sits d in)
        level = 0.5 * d + (len(fluid_x) * d**3 + frac * a * a * tall) / (slot - d) ** 2
    return spec


def submerged_fraction(body, lo: np.ndarray, hi: np.ndarray, level: float) -> float:
    """The part of the box [lo, hi] (its placement at t = 0) below `level`, at the body's pose."""
    u = (np.arange(SAMPLES) + 0.5) / SAMPLES
    g = np.stack(np.meshgrid(u, u, u, indexing="ij"), axis=-1).reshape(-1, 3)
    local = lo + g * (hi - lo) - body.c0
    world = local @ body.rotation().T + body.c
    return float((world[:, 1] < level).mean())


def free_surface(x: np.ndarray, centre: np.ndarray, half: float, d: float) -> float:
    """Median top particle + d/2 over the columns of width d beyond `half` + 2 d from the body's axis."""
    far = np.max(np.abs(x[:, [0, 2]] - centre[[0, 2]]), axis=1) > half + 2.0 * d
    cols = np.floor(x[far][:, [0, 2]] / d).astype(np.int64)
    _, inv = np.unique(cols, axis=0, return_inverse=True)
    top = np.full(int(inv.max()) + 1, -np.inf)
    np.maximum.at(top, inv.ravel(), x[far][:, 1])
    return float(np.median(top)) + 0.5 * d


def penetration(x: np.ndarray, body, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """How far each fluid particle's centre lies under the body's box surface (0 outside it)."""
    local = (x - body.c) @ body.rotation() + body.c0
    depth = np.minimum(local - lo, hi - local).min(axis=1)
    return np.maximum(depth, 0.0)


def float_one(
    method: str, density: float, n_across: int, r: float = 0.0125, end_time: float = 3.0, model=None, height=1.0
):
    """Run one floating box (`scene`) and measure it (`Float`)."""
    from ..scene import scene_from_dict
    from ..simulation import Simulation

    spec = scene_from_dict(scene(method, density, n_across, r, end_time, model, height))
    t0 = time.perf_counter()
    sim = Simulation.from_scene(spec)
    body = sim.walls.bodies[0]
    lo, hi = scaled_box(spec.boundaries[1])
    d = spacing(r)

    def depth(x):
        return penetration(x, body, lo, hi) / d

    def fraction(x):
        return submerged_fraction(body, lo, hi, free_surface(x, body.c, 0.5 * (hi[0] - lo[0]), d))

    return _measure(sim, end_time, depth, fraction, method, density, n_across, t0)


def _measure(sim, end_time: float, depth, fraction, method: str, density: float, n_across: int, t0: float, every=1):
    """Run `sim` to its end; every `every` steps the deepest fluid particle under the body's surface
    (`depth(x)`, in d), and over the second half the submerged fraction (`fraction(x)`)."""
    n0 = sim.n_fluid
    fractions, inside, deepest = [], [0], [0.0]

    def on_step(_):
        x = sim.positions
        if sim.steps % every == 0:
            dd = depth(x)
            if len(dd):
                inside[0] = max(inside[0], int((dd > INSIDE_D).sum()))
                deepest[0] = max(deepest[0], float(dd.max()))
        if sim.time >= 0.5 * end_time:
            fractions.append(fraction(x))

    sim.run(on_step=on_step)
    f = np.asarray(fractions)
    return Float(
        method,
        sim.scene.boundary_model,
        density,
        n_across,
        n0,
        float(f.mean()),
        float(f.std()),
        inside[0],
        deepest[0],
        n0 - sim.n_fluid,
        time.perf_counter() - t0,
    )


def _row(f: Float, label: str) -> str:
    return (
        f"{f.method:7} {label:15} {f.n_across:3d} {f.density:6.0f} {f.fluid:6d} "
        f"{100 * f.expected:7.1f}% {100 * f.submerged:6.1f}% {100 * f.error:+6.1f}% "
        f"{100 * f.heave:5.1f}% {f.inside:6d} {f.penetration:6.3f}d {f.lost:4d} {f.seconds:6.1f}"
    )


def run(methods, densities, sizes, models=(None,), r: float = 0.0125, end_time: float = 3.0, out=print) -> list:
    """Every combination, one line each, then the worst error per method and model."""
    out("# buoyancy: a cube at rest in a tank, submerged volume fraction against Archimedes (rho_b / rho0)")
    out(
        f"{'method':7} {'model':15} {'n':>3} {'rho_b':>6} {'fluid':>6} {'expected':>8} {'ours':>7} "
        f"{'error':>7} {'heave':>6} {'inside':>6} {'deepest':>7} {'lost':>4} {'s':>6}"
    )
    rows = []
    for model in models:
        for method in methods:
            for n in sizes:
                for rho in densities:
                    f = float_one(method, rho, n, r, end_time, model)
                    rows.append(f)
                    note = "  awash: freeboard < 1 d (resolution limit)" if f.awash else ""
                    out(_row(f, f.model) + note)
    import tempfile
    from pathlib import Path

    import pyvista as pv

    bunny = Path(__file__).resolve().parents[2] / "meshes" / "bunny.obj"
    with tempfile.TemporaryDirectory(prefix="ipsph-buoyancy-") as tmp:
        sphere = Path(tmp) / "sphere.vtp"
        pv.Sphere(radius=0.5, theta_resolution=40, phi_resolution=40).save(sphere)
        for name, path in (("sphere", sphere), ("bunny", bunny)):
            if not path.exists():
                out(f"# {name}: {path} not found (meshes/ ships with a clone of the repository)")
                continue
            for method in methods:
                f = float_mesh(method, 500.0, str(path), MESH_SIZE_D * spacing(r), r, end_time)
                rows.append(f)
                out(_row(f, name))
    out(
        "# SPlisHSPlasH 2.19 (pysplishsplash), a 0.16 m box at r = 0.0125 (6.4 d), DFSPH, measured for issue 27: "
        "500/700/900 kg/m^3 -> 30.7/40.2/52.5 % (volume maps), 42.4/56.7/70.8 % (density maps)"
    )
    return rows


def float_mesh(method: str, density: float, mesh: str, size: float, r: float = 0.0125, end_time: float = 3.0):
    """A closed mesh body of `density`, scaled so that its largest extent is `size`, dropped in with its
    centre at the water's level: its submerged volume fraction and how deep fluid got into it."""
    import pyvista as pv

    from ..geometry.inside import inside_mesh
    from ..geometry.meshes import load_mesh
    from ..scene import scene_from_dict
    from ..simulation import Simulation

    d = spacing(r)
    raw = load_mesh(mesh)
    lo0, hi0 = np.array(raw.bounds[0::2]), np.array(raw.bounds[1::2])
    scale = size / float((hi0 - lo0).max())
    ext = (hi0 - lo0) * scale
    slot = float(ext[[0, 2]].max()) + 2 * PAD_D * d
    depth = float(ext[1]) + DEPTH_BELOW_D * d
    centre = np.array([0.5 * slot, depth, 0.5 * slot])
    shift = centre - 0.5 * (lo0 + hi0) * scale
    spec = {
        "simulation": {"method": method, "particle_radius": r, "end_time": end_time},
        "fluid": [{"box": {"min": [0, 0, 0], "max": [slot, depth + 0.5 * d, slot]}}],
        "boundary": [
            {"name": "tank", "box": {"min": [0, 0, 0], "max": [slot, depth + float(ext[1]) + 4 * d, slot]}},
            {
                "name": "body",
                "role": "obstacle",
                "density": float(density),
                "mesh": str(mesh),
                "scale": [scale] * 3,
                "translate": shift.tolist(),
            },
        ],
        "render": {"enabled": False},
    }
    scene = scene_from_dict(spec)
    t0 = time.perf_counter()
    sim = Simulation.from_scene(scene)
    body = sim.walls.bodies[0]
    placed = raw.scale(scale, inplace=False).translate(shift, inplace=False)
    lo, hi = np.array(placed.bounds[0::2]), np.array(placed.bounds[1::2])
    u = [(np.arange(SAMPLES * 2) + 0.5) / (SAMPLES * 2) for _ in range(3)]
    grid = np.stack(np.meshgrid(*u, indexing="ij"), axis=-1).reshape(-1, 3) * (hi - lo) + lo
    interior = grid[inside_mesh(grid, placed, d / 4)]

    def depth(x):
        local = (x - body.c) @ body.rotation() + body.c0
        near = np.all((local > lo - d) & (local < hi + d), axis=1)
        if not near.any():
            return np.zeros(0)
        dist = pv.PolyData(local[near]).compute_implicit_distance(placed)["implicit_distance"]
        return np.maximum(-np.asarray(dist), 0.0) / d

    def fraction(x):
        level = free_surface(x, body.c, 0.5 * float(ext[[0, 2]].max()), d)
        world = (interior - body.c0) @ body.rotation().T + body.c
        return float((world[:, 1] < level).mean())

    return _measure(sim, end_time, depth, fraction, method, density, int(round(size / d)), t0, every=5)
