"""The pass table: every per-particle pass declared once, launched by both backends.

A row names the pass (its launcher's name on every backend), its body (a function of the particle
index first, in `bodies`, `viscous_bodies` or `field_bodies`), the scratch block the body's `buf`
is (rows per neighbour slot and which lists' stride: "fluid", "walls" or "all") and how the CPU
runs it (`cpu`). The launcher's arguments are the body's, by name, less the index, `buf` and the
values the launcher derives (`DERIVED`, or the row's own `derived`), in the body's order; `args`
overrides that where a launcher takes something else (wall_pressure takes g, its body g0, g1, g2).

From a row, `cpu_passes.launchers` and `cuda_passes` build the launchers (Python source compiled
by Numba: `source`), and `base.Backend.run_pass` binds the arguments by name. Adding a pass is
a body and a row here, and a `Backend` method that calls `run_pass` (docs/architecture.md).
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass, field
from functools import cached_property

from . import bodies as B
from . import field_bodies as FB
from . import viscous_bodies as VB

# What a launcher computes once for its bodies, from its own arguments, when a body takes it.
DERIVED = {
    "w0": "w(0.0, h)",  # the kernel at r = 0
    "fill": "pair_grad.shape[0] == x.shape[0]",  # fill the pair cache (it has a row per particle)
    "cached": "pair_grad.shape[0] == x.shape[0]",  # read the pair cache
    "with_disp": "disp.shape[0] == x.shape[0]",  # the PF displacement (disp has a row per particle)
    "eps": "0.01 * h * h",  # the viscosity's regulariser
    "standard": "nu_dt > 0.0",  # SPlisHSPlasH's Standard viscosity on top of XSPH
    "support": "wm.shape[0] == x.shape[0]",  # the field walls' support along their faces (it has rows)
}


@dataclass(frozen=True)
class Pass:
    name: str
    body: object  # an @njit body: body(index, ...)
    rows: int = 0  # scratch rows per neighbour slot; 0: no scratch block
    stride: str = ""  # the scratch's columns: "fluid" (K_f), "walls" (K_b) or "all" (K_f + K_b)
    cpu: str = "chunks"  # "chunks": prange over CHUNKS blocks, one scratch each; "each": prange over
    # the particles; "serial": one loop (element-wise work too small to share out)
    wrapper: str = ""  # CPU: call the body through a non-inlined @njit function of this name
    # (numba's parallel analysis cannot follow the field walls' tuple arithmetic once inlined)
    home: str = "cpu_passes"  # the CPU module the launcher lives in
    derived: dict = field(default_factory=dict)  # more DERIVED values, this pass only
    args: tuple = ()  # the launcher's arguments, where they are not the body's
    rows_of: str = ""  # the argument whose rows are the work items, where it is not the first
    count: str = ""  # CPU: the launcher returns the number of nonzero entries of this argument (the
    # CUDA backend counts them itself)

    @cached_property
    def params(self) -> tuple[str, ...]:
        """The body's parameters after the index."""
        return tuple(inspect.signature(getattr(self.body, "py_func", self.body)).parameters)[1:]

    @cached_property
    def derives(self) -> dict:
        return {k: v for k, v in {**DERIVED, **self.derived}.items() if k in self.params}

    @cached_property
    def inputs(self) -> tuple[str, ...]:
        """The launcher's arguments, in order."""
        if self.args:
            return self.args
        return tuple(p for p in self.params if p != "buf" and p not in self.derives)

    @cached_property
    def over(self) -> str:
        """The argument whose rows are the work items (the particles): `rows_of`, else the first."""
        return self.rows_of or self.inputs[0]


PASSES = {
    p.name: p
    for p in (
        Pass("density_factor_lambda", B.density_at, B.DENSITY_ROWS, "all"),
        Pass("divergence_residual", B.divergence_residual_at, B.RATE_ROWS, "fluid"),
        Pass(
            "density_residual",
            B.density_residual_at,
            B.RATE_ROWS,
            "fluid",
            derived={"two_sided": "wb.shape[0] == x.shape[0]"},  # field walls (bodies.TENSION_BAND)
        ),
        Pass("apply_stiffness", B.stiffness_at, B.STIFFNESS_ROWS, "fluid"),
        Pass("xsph", VB.viscosity_at, B.VISCOSITY_ROWS, "fluid"),
        Pass("pf_global", B.pf_global_at, B.PF_GLOBAL_ROWS, "fluid"),
        Pass("wall_rate", B.wall_rate_at, B.WALL_RATE_ROWS, "walls"),
        Pass("viscous_setup", VB.viscous_setup_at, B.VISCOUS_SETUP_ROWS, "all"),
        Pass("viscous_apply", VB.viscous_apply_at, B.VISCOUS_APPLY_ROWS, "fluid"),
        Pass("cg_precondition", VB.cg_precondition_at, cpu="serial"),
        # the field walls (wall model "field")
        Pass("field_density_factor_lambda", FB.field_density_at, B.DENSITY_ROWS, "all", home="cpu_field"),
        Pass("wall_field", FB.wall_field_at, cpu="each", wrapper="_field_one", home="cpu_field"),
        Pass(
            "wall_pressure",
            FB.wall_pressure_at,
            cpu="each",
            home="cpu_field",
            derived={"g0": "g[0]", "g1": "g[1]", "g2": "g[2]"},
            args=("gw", "ws", "g", "rho0", "dt", "v"),
            rows_of="v",
        ),
        Pass("wall_project", FB.wall_project_at, cpu="each", wrapper="_project_one", home="cpu_field", count="moved"),
    )
}

# the files a launcher's compiled code depends on (its cache is stamped with them: `_cache.depend_on`)
SOURCES = (__file__, *(m.__file__ for m in (B, VB, FB)))


def source(p: Pass, scratch: str, loop: list[str], buf: str = "buf", callee: str = "body", tail=()) -> str:
    """The launcher of `p` as Python source: derived values, the scratch line `scratch` ("" for
    none), the loop lines `loop` over the work items i (`{n}` stands for their count), inside them
    the call `callee(i, ...)` with `buf` for the body's scratch block, then the lines `tail`. The
    names it uses (`callee`, `w`, ...) are those of the namespace the source runs in."""
    call = ", ".join(buf if a == "buf" else a for a in p.params)
    lines = [f"def {p.name}({', '.join(p.inputs)}):"]
    lines += [f"    {k} = {v}" for k, v in p.derives.items()]
    lines += [f"    {scratch}"] if scratch else []
    lines += ["    " + line.format(n=f"{p.over}.shape[0]") for line in loop]
    depth = len(lines[-1]) - len(lines[-1].lstrip()) + 4
    lines.append(" " * depth + f"{callee}(i, {call})")
    lines += [f"    {line}" for line in tail]
    return "\n".join(lines) + "\n"


def wrapper_source(p: Pass) -> str:
    """The non-inlined function a CPU launcher calls the body through (`Pass.wrapper`)."""
    params = ", ".join(["i", *p.params])
    return f"def {p.wrapper}({params}):\n    body({params})\n"
