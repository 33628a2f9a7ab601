"""The top-level, [simulation], [time_step] and [solver.*] keys."""

from __future__ import annotations

from .facts import (
    AUTO_DT_MAX,
    BACKEND_NAMES,
    BOUNDARY_MODELS,
    METHOD_NAMES,
    PRECISIONS,
    SETTLE_MODES,
    VISCOSITY_MODELS,
    VISCOSITY_WALLS,
)
from .schema import _P, Param, _limits

KEYS: tuple[Param, ...] = (
    # -- top level ------------------------------------------------------------------------------
    _P(
        "name",
        "str",
        None,
        "",
        "Scene name used in outputs and logs. Default: the scene file's name without extension.",
    ),
    _P(
        "source",
        "str",
        None,
        "",
        "The scene file this scene was resolved from; written by "
        "ipsph into saved scenes (run.json), not normally set by hand.",
        optional=True,
    ),
    # -- [simulation] ---------------------------------------------------------------------------
    _P(
        "simulation.method",
        "choice",
        "ipsph",
        "",
        "Pressure solver: ipsph (the paper's method), pf (Projective Fluids) or dfsph (Divergence-Free SPH).",
        "method",
        choices=METHOD_NAMES,
    ),
    _P(
        "simulation.backend",
        "choice",
        "cpu",
        "",
        "Where the solver runs: cpu (Numba threads) or "
        "cuda (an NVIDIA GPU through numba-cuda: pip install 'ipsph[cuda]'; docs/method.md, "
        '"Backends and precision"). The same methods and outputs on both.',
        "backend",
        choices=BACKEND_NAMES,
    ),
    _P(
        "simulation.precision",
        "choice",
        "float64",
        "",
        "Storage type of the per-particle real "
        "arrays: float64, or float32 (half the memory and bandwidth; the passes still compute and sum "
        'in float64; docs/method.md, "Backends and precision").',
        "precision",
        choices=PRECISIONS,
    ),
    _P(
        "simulation.device",
        "int",
        0,
        "",
        "With backend cuda: the number of the GPU to run on.",
        "device",
        lo=0,
        hi=1023,
    ),
    _P(
        "simulation.particle_radius",
        "float",
        0.025,
        "m",
        "Particle radius r; lattice spacing d = 2r, kernel support H = 4r.",
        "particle_radius",
        lo=0.0,
        hi=1.0,
        lo_open=True,
    ),
    _P(
        "simulation.density0", "float", 1000.0, "kg/m^3", "Rest density rho0.", "density0", lo=0.0, hi=1e5, lo_open=True
    ),
    _P(
        "simulation.gravity",
        "vec3",
        (0.0, -9.81, 0.0),
        "m/s^2",
        "Gravitational acceleration (y is up).",
        "gravity",
        lo=-1e3,
        hi=1e3,
    ),
    _P(
        "simulation.end_time",
        "float",
        2.0,
        "s",
        "Simulated time at which the run stops.",
        "end_time",
        lo=0.0,
        hi=1e6,
        lo_open=True,
    ),
    _P(
        "simulation.viscosity",
        "float",
        0.01,
        "",
        "XSPH smoothing coefficient zeta (dimensionless, not a viscosity: 0.01-0.03 typical; 0 "
        "disables it). It applies with every viscosity_model; a physical viscosity is "
        "kinematic_viscosity_m2s.",
        "viscosity",
        lo=0.0,
        hi=1.0,
    ),
    _P(
        "simulation.viscosity_model",
        "choice",
        "xsph",
        "",
        "How the kinematic viscosity nu acts (docs/method.md section 10): xsph (none: only the "
        "XSPH filter), standard (SPlisHSPlasH's explicit Standard model; it limits the step to "
        "H^2 / (60 nu)) or implicit (a backward-Euler solve, Weiler et al. 2018's operator: the "
        "CFL step at any nu; tolerance and cap in [solver.viscosity]).",
        "viscosity_model",
        choices=VISCOSITY_MODELS,
    ),
    _P(
        "simulation.kinematic_viscosity_m2s",
        "float",
        0.0,
        "m^2/s",
        "Kinematic viscosity nu = mu / rho0 in m^2/s (water 1e-6, honey 5e-3, thick lava 1 and "
        "more), used by viscosity_model standard or implicit (SPlisHSPlasH's Materials viscosity "
        "is this nu).",
        "kinematic_viscosity_m2s",
        lo=0.0,
        hi=1e4,
    ),
    _P(
        "simulation.viscosity_walls",
        "choice",
        "no-slip",
        "",
        "Wall friction of the implicit viscosity: no-slip (the fluid is dragged towards the wall "
        "particles' velocities, moving walls included) or free-slip (walls take no part in the "
        "viscous operator).",
        "viscosity_walls",
        choices=VISCOSITY_WALLS,
    ),
    _P(
        "simulation.boundary_model",
        "choice",
        "akinci-volume",
        "",
        'How walls are made (docs/method.md section 9, "Where the fluid\'s volume ends"). akinci-volume: '
        "one layer of Akinci particles 0.6 d inside every obstacle and body, so that the fluid's "
        "volume meets their surface and a floating body displaces its own volume (Archimedes); "
        "akinci-surface: the layer 0.1 d behind every surface, where bodies float too high by about "
        "d/2. Containers are the same in both (their layer 0.1 d outside). field (experimental, CPU, "
        "static walls): no wall particles, every wall a shape whose signed distance and exact kernel "
        "integral the fluid reads (docs/method.md section 11); fluid at rest does not yet stay at rest "
        "against it, so it is not for production runs.",
        "boundary_model",
        choices=BOUNDARY_MODELS,
    ),
    _P(
        "simulation.fit_wall_volumes",
        "bool",
        False,
        "",
        "Fit the Akinci wall volumes (by least "
        "squares, within 1.05 x Akinci's) so that fluid at rest on the lattice reads rho0 to 1e-5 "
        "next to walls, edges and corners (docs/method.md section 1). Box walls already read it "
        "within 0.15 % without the fit; it costs a few seconds of setup on large walls. Only static "
        "walls are fitted: moving walls and rigid bodies keep Akinci's volumes.",
        "fit_wall_volumes",
    ),
    _P(
        "simulation.settle",
        "choice",
        "auto",
        "",
        "Settle the fluid under gravity before t = 0 "
        '(docs/method.md section 1, "A start at rest"): the solver\'s own steps with the '
        "velocities damped, until a step from rest moves nothing, so a pool starts in its discrete "
        "equilibrium with its hydrostatic pressure. auto: only fluid at rest that spans its "
        "container's floor (a tank, a pool), never a column that is meant to fall or flow.",
        "settle",
        choices=SETTLE_MODES,
    ),
    # -- [time_step] ----------------------------------------------------------------------------
    _P(
        "time_step.cfl_factor",
        "float",
        1.0,
        "",
        "CFL factor lambda in dt = lambda * 0.4 * d / max|v|.",
        lo=0.0,
        hi=2.5,
        lo_open=True,
    ),
    _P(
        "time_step.dt_min",
        "float",
        1e-4,
        "s",
        "Smallest time step; steps the CFL rule would make shorter are counted and reported.",
        lo=0.0,
        hi=1.0,
        lo_open=True,
    ),
    _P(
        "time_step.dt_max",
        "float",
        None,
        "s",
        f"Largest time step. auto: {AUTO_DT_MAX}.",
        lo=0.0,
        hi=1.0,
        lo_open=True,
        optional=True,
    ),
    _P(
        "time_step.dt_initial",
        "float",
        None,
        "s",
        "First time step. auto: the CFL value of the initial velocities.",
        lo=0.0,
        hi=1.0,
        lo_open=True,
        optional=True,
    ),
    # -- [solver] -------------------------------------------------------------------------------
    _P(
        "solver.pair_cache_mb",
        "float",
        64.0,
        "MiB",
        "Memory the pressure solves (DFSPH's, IPSPH's "
        "divergence solve) may use to keep each fluid pair's kernel gradient instead of evaluating "
        "it in every iteration: 24 bytes per neighbour-list slot, about 1.5 KB per particle. Over it "
        "(about 40k fluid particles), or at 0, they evaluate the kernel again: the same results up "
        "to the order of floating-point additions.",
        lo=0.0,
        hi=1e6,
    ),
    # -- [solver.divergence] ---------------------------------------------------------------------
    _P(
        "solver.divergence.enabled",
        "bool",
        True,
        "",
        "Run the divergence solve (DFSPH's, and IPSPH's Algorithm 1; false turns both off, for experiments).",
    ),
    _P(
        "solver.divergence.error_pct",
        "float",
        0.1,
        "%",
        "Divergence solve (DFSPH and IPSPH): stop when mean Drho/Dt <= this * rho0 / dt.",
        lo=0.0,
        hi=100.0,
        lo_open=True,
    ),
    *_limits("solver.divergence", "iterations", 1, 100, "Divergence solve"),
    # -- [solver.dfsph] -------------------------------------------------------------------------
    _P(
        "solver.dfsph.density_error_pct",
        "float",
        0.01,
        "%",
        "DFSPH density solve: stop when the mean density error is below this.",
        lo=0.0,
        hi=100.0,
        lo_open=True,
    ),
    *_limits("solver.dfsph", "iterations", 2, 100, "DFSPH density solve", stem="density_"),
    # -- [solver.pf] ----------------------------------------------------------------------------
    _P(
        "solver.pf.stiffness",
        "float",
        50_000.0,
        "",
        "Projective Fluids constraint stiffness k_s (PF and IPSPH).",
        lo=0.0,
        hi=1e12,
        lo_open=True,
    ),
    _P(
        "solver.pf.passes",
        "int",
        3,
        "",
        "Local/global passes per step of plain PF (SPlisHSPlasH runs 3).",
        lo=1,
        hi=10_000,
    ),
    # -- [solver.ipsph] -------------------------------------------------------------------------
    _P(
        "solver.ipsph.density_error_pct",
        "float",
        0.05,
        "%",
        "IPSPH average-density loop: stop when mean max(rho/rho0 - 1, 0) is below this.",
        lo=0.0,
        hi=100.0,
        lo_open=True,
    ),
    *_limits("solver.ipsph", "passes", 2, 100, "IPSPH: PF passes per step", least=1),
    _P(
        "solver.ipsph.warm_start",
        "float",
        0.8,
        "",
        "IPSPH: fraction of the last step's PF multipliers to start from (0 = off).",
        lo=0.0,
        hi=1.0,
    ),
    # -- [solver.viscosity] ----------------------------------------------------------------------
    _P(
        "solver.viscosity.error_pct",
        "float",
        0.1,
        "%",
        "Implicit viscosity solve: stop when the residual's norm is below this fraction of the "
        "right-hand side's (mass-weighted 2-norms; SPlisHSPlasH's Weiler 2018 maxError is 1 %).",
        lo=0.0,
        hi=100.0,
        lo_open=True,
    ),
    *_limits("solver.viscosity", "iterations", 0, 100, "Implicit viscosity solve (conjugate gradients)"),
)
