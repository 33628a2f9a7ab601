"""The declared facts that are not scene keys: spacing and support in particle radii, the CFL
constants and the auto dt_max, the memory budget, the names of methods, backends, phases, fields, views and modes."""

from __future__ import annotations

# The lattice spacing d and the kernel support H, in particle radii r (method.md section 1)
SPACING_RADII = 2.0  # d = 2 r
SUPPORT_RADII = 4.0  # H = 4 r


# The CFL rule (method.md section 1): dt = cfl_factor * COURANT * d / max|v|.
COURANT = 0.4
# Explicit Standard viscosity is stable while nu dt lambda_max <= 2, lambda_max the largest
# eigenvalue of its operator: 59.6 / H^2 on the lattice (power iteration, method.md section 1).
# The step keeps half of that margin: dt <= H^2 / (VISCOUS_STEP nu).
VISCOUS_STEP = 60.0
# time_step.dt_max's auto value: 5 ms at r = 0.025 m, in proportion to r (auto_dt_max)
AUTO_DT_MAX = "5 ms * r / 0.025 m"


def spacing(r: float) -> float:
    """The lattice spacing d = 2 r."""
    return SPACING_RADII * r


def support(r: float) -> float:
    """The kernel support H = 4 r."""
    return SUPPORT_RADII * r


def auto_dt_max(r: float) -> float:
    """time_step.dt_max when left auto: AUTO_DT_MAX."""
    return 0.005 * r / 0.025


BYTES_PER_PARTICLE = 1024  # the solver's memory budget per fluid particle (docs/performance.md)

METHOD_NAMES = ("ipsph", "pf", "dfsph")  # simulation.method; ipsph.methods.METHODS implements each
BACKEND_NAMES = ("cpu", "cuda")  # simulation.backend; ipsph.backends.BACKENDS implements each
FIELD_WALLS = "field"  # the wall model without wall particles, whose passes are its own (method.md section 11)
BOUNDARY_MODELS = ("akinci-volume", "akinci-surface", FIELD_WALLS)  # simulation.boundary_model; ipsph.boundary.MODELS
PRECISIONS = ("float64", "float32")  # simulation.precision: the real arrays' type

# A step's timed phases, in report order: timer name -> (short label, what it times). Each method
# reports a subset (`Method.phases`); `Simulation.step` adds "step", the whole step.
PHASES = {
    "neighbourSearch": ("nbr", "cell sort, reordering and neighbour lists"),
    "densities": ("rho", "density pass at the end-of-step positions (DFSPH)"),
    "solvePDConstraints": ("PD", "Projective Fluids local/global passes (PF, IPSPH)"),
    "xsph": ("xsph", "viscosity pass (XSPH, Standard viscosity)"),
    "viscositySolve": ("visc", "implicit viscosity solve (viscosity_model implicit)"),
    "divergenceSolve": ("div", "divergence solve (DFSPH, IPSPH)"),
    "densitySolve": ("dens", "DFSPH density solve"),
}

VISCOSITY_MODELS = ("xsph", "standard", "implicit")  # simulation.viscosity_model (method.md section 10)
VISCOSITY_WALLS = ("no-slip", "free-slip")  # simulation.viscosity_walls: the implicit model's wall friction
SETTLE_MODES = ("auto", "on", "off")  # simulation.settle: the pre-pass before t = 0
BOUNDARY_ROLES = ("container", "obstacle")  # boundary.role: fluid inside the surface, or around it
# boundary.motion.type (ipsph/boundary/motion.py) and the [boundary.motion] keys each type takes besides
# `type`: a scene that gives another is refused, and run.json writes these
MOTION_KEYS: dict[str, tuple[str, ...]] = {
    "static": (),
    "constant": ("velocity", "angular_velocity", "pivot"),
    "sinusoid": ("axis", "amplitude", "angle_amplitude", "period", "phase_deg", "pivot"),
    "keyframes": ("keyframes", "pivot"),
}
MOTION_TYPES = tuple(MOTION_KEYS)
OUTPUT_FIELDS = ("velocity", "density", "pressure", "mass", "id")
# render.view: direction from the focal point to the camera, and the view-up vector (y is up)
RENDER_VIEWS: dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]] = {
    "front": ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),
    "back": ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0)),
    "side": ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    "top": ((0.0, 1.0, 0.0), (0.0, 0.0, -1.0)),
    "iso": ((0.75, 0.55, 1.0), (0.0, 1.0, 0.0)),
}
RENDER_MODES = ("particles", "surface")  # render.mode: lit particle spheres, or the surface mesh
AUTO = "auto"  # an optional value written as "auto" (or left out) means None: computed at run time
