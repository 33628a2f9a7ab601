"""The CUDA backend's checks, run on numba-cuda's simulator in a process of their own
(`python tests/cuda_sim_cases.py CASE` prints one JSON object; tests/test_cuda_backend.py
asserts on it; with IPSPH_CASES_ON_DEVICE=1 they run on a real GPU: scripts/gpu_bench.sh).
NUMBA_ENABLE_CUDASIM must be set before numba-cuda is first imported, so these cannot share the
CPU tests' process.

The scenes are tiny (the simulator interprets every GPU thread in Python).
"""

from __future__ import annotations

import json
import os
import sys

if sys.argv[1:2] != ["ptx"] and not os.environ.get("IPSPH_CASES_ON_DEVICE"):  # scripts/gpu_bench.sh: a real GPU
    os.environ["NUMBA_ENABLE_CUDASIM"] = "1"

import numpy as np  # noqa: E402

from ipsph.backends import Densities, get_backend  # noqa: E402
from ipsph.config import ViscosityConfig  # noqa: E402
from ipsph.methods.viscosity import ViscosityScratch, viscous_solve  # noqa: E402
from ipsph.neighbours import brute_force_neighbours  # noqa: E402
from ipsph.scene import scene_from_dict  # noqa: E402
from ipsph.simulation import Simulation, sample_scene  # noqa: E402


def tank(method: str, r: float = 0.025):
    """A 5^3 = 125 particle column at rest in a closed box (test_physics's tank, coarser)."""
    return scene_from_dict(
        {
            "simulation": {
                "method": method,
                "particle_radius": r,
                "end_time": 1.0,
                "fit_wall_volumes": True,
                "settle": "off",
            },  # the backends compared step by step from the sampled start
            "time_step": {"dt_max": 0.005},
            "fluid": [{"box": {"min": [0.0, 0.0, 0.0], "max": [0.3, 0.3, 0.3]}}],
            "boundary": [{"role": "container", "box": {"min": [0.0, 0.0, 0.0], "max": [0.3, 0.6, 0.3]}}],
        },
        name=f"tank-{method}",
    )


def rel(a, b) -> float:
    """max |a - b| / max |a|: the largest difference, relative to the field's scale."""
    return float(np.max(np.abs(a - b)) / max(float(np.max(np.abs(a))), 1e-300))


def by_id(sim, a):
    """a (a per-particle host array of sim) in the initial numbering: the two backends may sort
    particles that sit on a cell face (the lattice does) into neighbouring cells when a
    coordinate differs in the last bit, so arrays are compared particle by particle."""
    out = np.empty_like(a)
    out[sim.ids] = a
    return out


def iterations(rep) -> list[int]:
    return [rep.pd_passes, rep.divergence_iterations, rep.density_iterations, rep.solver_maxed]


def twins(scene, precision="float64"):
    """The same sampled scene on the CPU backend (float64) and the CUDA backend."""
    fx, fv, bx, _ = sample_scene(scene)
    return (
        Simulation(scene, fx, fv, bx, backend="cpu"),
        Simulation(scene, fx, fv, bx, backend=get_backend("cuda", precision)),
    )


def case_methods(steps: int = 10) -> dict:
    """Per step, CPU against CUDA float64: positions, velocities, densities (relative), ids and
    the solvers' iteration counts, for every method."""
    out = {}
    for method in ("ipsph", "pf", "dfsph"):
        cpu, gpu = twins(tank(method))
        rows = []
        for _ in range(steps):
            dt = cpu.dt_next
            rc, rg = cpu.step(dt), gpu.step(dt)
            rows.append(
                {
                    k: rel(by_id(cpu, getattr(cpu, f)), by_id(gpu, getattr(gpu, f)))
                    for k, f in (("x", "positions"), ("v", "velocities"), ("rho", "densities"))
                }
                | {
                    "same_order": bool(np.array_equal(cpu.ids, gpu.ids)),
                    "it_cpu": iterations(rc),
                    "it_cuda": iterations(rg),
                    "dt_next": [cpu.dt_next, gpu.dt_next],
                }
            )
        out[method] = rows
    return out


def jet(method: str, r: float = 0.025):
    """An emitter (12 particles a layer at 2 m/s, one every 0.025 s) firing across a closed box
    with a 27-particle block on its floor, into a sink 0.12 m downstream, inside a [domain] box:
    the count grows by emission and shrinks by compaction within 14 steps (test_emitters's jet,
    smaller and coarser)."""
    return scene_from_dict(
        {
            "simulation": {"method": method, "particle_radius": r, "end_time": 1.0},
            "time_step": {"dt_max": 0.005},
            "fluid": [{"box": {"min": [0.0, -0.3, -0.1], "max": [0.2, -0.1, 0.1]}}],
            "boundary": [{"name": "tank", "box": {"min": [-0.3, -0.3, -0.3], "max": [0.3, 0.3, 0.3]}}],
            "emitter": [
                {
                    "name": "jet",
                    "position": [-0.2, 0.0, 0.0],
                    "direction": [1, 0, 0],
                    "width": 0.2,
                    "height": 0.15,
                    "velocity": 2.0,
                    "start_time": 0.0,
                    "end_time": 0.2,
                }
            ],
            "sink": [{"name": "drain", "min": [-0.08, -0.1, -0.3], "max": [0.3, 0.3, 0.3]}],
            "domain": {"min": [-0.3, -0.3, -0.3], "max": [0.3, 0.3, 0.3]},
            "render": {"enabled": False},
        },
        name=f"jet-{method}",
    )


def case_emitters(steps: int = 14) -> dict:
    """Per step, CPU against CUDA float64 with an emitter, a sink and a domain box: the counts
    (active, emitted, removed), the ids, and positions and velocities particle by particle
    (matched by id: the two backends may order particles on a cell face differently)."""
    out = {}
    for method in ("ipsph", "pf", "dfsph"):
        cpu, gpu = twins(jet(method))
        rows = []
        for _ in range(steps):
            dt = cpu.dt_next
            rc, rg = cpu.step(dt), gpu.step(dt)
            ic, ig = cpu.ids, gpu.ids
            oc, og = np.argsort(ic), np.argsort(ig)
            same_ids = bool(len(ic) == len(ig) and np.array_equal(ic[oc], ig[og]))
            row = {
                "n": [cpu.n_fluid, gpu.n_fluid],
                "emitted": [rc.emitted, rg.emitted],
                "removed": [rc.removed, rg.removed],
                "same_ids": same_ids,
                "capacity": [cpu.state.capacity, gpu.state.capacity],
            }
            if same_ids and len(ic):
                row |= {
                    k: rel(getattr(cpu, f)[oc], getattr(gpu, f)[og])
                    for k, f in (("x", "positions"), ("v", "velocities"), ("rho", "densities"))
                }
            rows.append(row)
        out[method] = rows
    return out


def paddle_and_crate(method: str, r: float = 0.04):
    """test_moving_walls's checkpoint scene at r = 0.04 (44 fluid particles) in a tank, a paddle
    on a sinusoid (a kinematic wall: amplitude 0.05 m, period 0.5 s) and a floating crate (a rigid
    body of density 500 driven by the fluid's reaction), set into the fluid off its lattice: a
    crate face on the lattice puts fluid-wall pairs exactly at the support radius, where the two
    backends' last bits decide whether the first touch happens this step or the next."""
    from test_moving_walls import paddle_and_crate as scene

    crate = ([0.213, 0.207, 0.107], [0.413, 0.307, 0.307])
    return scene_from_dict(scene(r, crate, method), name=f"paddle-{method}")


def case_moving_walls(steps: int = 8) -> dict:
    """Per step, CPU against CUDA float64 with moving walls: the fluid (matched by id), the
    walls' positions (re-sorted on the host each step: the same order on both), the crate's
    centre and velocity (integrated from the fluid's reaction), and the largest moving-wall
    density-rate term gvb (the wall_rate pass) on each backend."""
    out = {}
    for method in ("ipsph", "pf", "dfsph"):
        cpu, gpu = twins(paddle_and_crate(method))
        rows = []
        for _ in range(steps):
            dt = cpu.dt_next
            cpu.step(dt)
            gpu.step(dt)
            oc, og = np.argsort(cpu.ids), np.argsort(gpu.ids)
            bc, bg = cpu.walls.bodies[0], gpu.walls.bodies[0]
            gvb = [float(np.abs(s.be.to_host(s.method.data.dens.gvb)).max()) for s in (cpu, gpu)]
            rows.append(
                {
                    k: rel(getattr(cpu, f)[oc], getattr(gpu, f)[og])
                    for k, f in (("x", "positions"), ("v", "velocities"), ("rho", "densities"))
                }
                | {
                    "same_ids": bool(np.array_equal(cpu.ids[oc], gpu.ids[og])),
                    "walls_x": rel(cpu.boundary.x, gpu.boundary.x),
                    "walls_v": rel(cpu.boundary.v, gpu.boundary.v),
                    "crate_c": rel(bc.c, bg.c),
                    "crate_v": rel(bc.v, bg.v),
                    "gvb": gvb,
                    "walls_speed": float(np.abs(cpu.boundary.v).max()),
                    "crate_speed": float(np.linalg.norm(bc.v)),
                    "crate_force": rel(cpu.walls.force[bc.group][0], gpu.walls.force[bc.group][0]),
                    "crate_force_n": float(np.linalg.norm(cpu.walls.force[bc.group][0])),
                    "dt_next": [cpu.dt_next, gpu.dt_next],
                }
            )
        out[method] = rows
    return out


def case_float32(steps: int = 8) -> dict:
    """IPSPH in float32 on the CUDA backend beside the CPU's float64 and float32, and a float32 free fall."""
    cpu, gpu = twins(tank("ipsph"), "float32")
    cpu32 = Simulation(cpu.scene, *sample_scene(cpu.scene)[:3], backend=get_backend("cpu", "float32"))
    rho0, d = cpu.scene.density0, cpu.spacing
    rows = []
    for _ in range(steps):
        dt = cpu.dt_next
        rc = cpu.step(dt)
        rg = gpu.step(dt)
        r32 = cpu32.step(dt)
        diff = {
            f: np.abs(by_id(cpu, getattr(cpu, f)) - by_id(gpu, getattr(gpu, f))).max()
            for f in ("positions", "velocities", "densities")
        }
        same = {
            f: np.abs(by_id(cpu32, getattr(cpu32, f)) - by_id(gpu, getattr(gpu, f))).max()
            for f in ("positions", "densities")
        }
        rows.append(
            {
                "dx_over_d": float(diff["positions"] / d),
                "drho_over_rho0": float(diff["densities"] / rho0),
                "dv": float(diff["velocities"]),
                "density_error_mean": [rc.density_error_mean, rg.density_error_mean],
                "density_error_max": [rc.density_error_max, rg.density_error_max],
                "dtype": str(gpu.be.to_host(gpu.state.x).dtype),
                # the CPU backend in float32 too (issue 28): the same storage rounding
                "cpu32_dx_over_d": float(same["positions"] / d),
                "cpu32_drho_over_rho0": float(same["densities"] / rho0),
                "cpu32_it": [r32.pd_passes, rg.pd_passes, r32.divergence_iterations, rg.divergence_iterations],
                "cpu32_dtype": str(cpu32.state.x.dtype),
            }
        )
    # free fall: a 3^3 block without walls, 0.3 m/s sideways
    fall = scene_from_dict(
        {
            "simulation": {"method": "ipsph", "particle_radius": 0.025, "end_time": 1.0},
            "time_step": {"dt_max": 0.005},
            "fluid": [{"box": {"min": [0.0, 0.0, 0.0], "max": [0.2, 0.2, 0.2]}, "velocity": [0.3, 0, 0]}],
        },
        name="fall",
    )
    fx, fv, bx, _ = sample_scene(fall)
    sim = Simulation(fall, fx, fv, bx, backend=get_backend("cuda", "float32"))
    t, vy, vx = [], [], []
    for _ in range(6):
        sim.step(0.005)
        t.append(sim.time)
        vy.append(float(sim.velocities[:, 1].mean()))
        vx.append(float(np.abs(sim.velocities[:, 0] - 0.3).max()))
    return {"tank": rows, "fall_slope": float(np.polyfit(t, vy, 1)[0]), "fall_vx_dev": max(vx)}


def case_passes() -> dict:
    """The neighbour search (against the brute-force oracle and the CPU's lists) and every pass
    (CUDA against CPU on the same inputs), on a jittered tank."""
    scene = tank("dfsph")
    cpu, gpu = twins(scene)
    rng = np.random.default_rng(7)
    x = cpu.positions + 0.2 * cpu.spacing * rng.standard_normal(cpu.positions.shape)
    n = len(x)
    bc, bg = cpu.be, gpu.be
    pc, pg = cpu.search.update(x.copy()), gpu.search.update(bg.asarray(x))
    res = {"perm_equal": bool(np.array_equal(pc, bg.to_host(pg)))}
    xs = x[pc]
    lc, lg = cpu.search.lists, gpu.search.lists
    host = {k: bg.to_host(getattr(lg, k)) for k in ("fluid", "fluid_count", "boundary", "boundary_count")}
    h = cpu.support
    oracle_f = brute_force_neighbours(xs, xs, h, True)
    oracle_b = brute_force_neighbours(xs, cpu.boundary.x, h, False)
    res["fluid_vs_oracle"] = all(
        np.array_equal(np.sort(host["fluid"][i, : host["fluid_count"][i]]), oracle_f[i]) for i in range(n)
    )
    res["walls_vs_oracle"] = all(
        np.array_equal(np.sort(host["boundary"][i, : host["boundary_count"][i]]), oracle_b[i]) for i in range(n)
    )
    res["rows_as_cpu"] = all(
        np.array_equal(host["fluid"][i, :c], lc.fluid[i, :c])
        and np.array_equal(host["boundary"][i, : lc.boundary_count[i]], lc.boundary[i, : lc.boundary_count[i]])
        for i, c in enumerate(lc.fluid_count)
    )
    res["mean_neighbours"] = float(host["fluid_count"].mean())
    fl = cpu.method.fluid
    dc, dg = Densities.allocate(bc, n), Densities.allocate(bg, n)
    kc, kg = lc.fluid.shape[1], lg.fluid.shape[1]
    cache_c, cache_g = bc.pair_buffer(n, kc), bg.pair_buffer(n, kg)
    bc.densities(xs, fl.mf, cpu.boundary, lc, fl.h, fl.rho0, dc, cache_c)
    xg = bg.asarray(xs)
    bg.densities(xg, fl.mf, gpu.boundary, lg, fl.h, fl.rho0, dg, cache_g)
    diffs = {f"density.{k}": rel(getattr(dc, k), bg.to_host(getattr(dg, k))) for k in ("rho", "alpha", "lam", "gb")}
    diffs["density.n_nbrs"] = float(np.abs(dc.n_nbrs - bg.to_host(dg.n_nbrs)).max())
    cnt = lc.fluid_count
    diffs["pair_cache"] = max(rel(cache_c[i, :, :c], bg.to_host(cache_g)[i, :, :c]) for i, c in enumerate(cnt) if c)
    v = rng.standard_normal(x.shape)
    vg = bg.asarray(v)
    lam = rng.random(n)
    for label, pairs_c, pairs_g in (("kernel", bc.NO_PAIRS, bg.NO_PAIRS), ("cached", cache_c, cache_g)):
        a = [np.zeros(n) for _ in range(2)]
        b = [bg.zeros(n) for _ in range(2)]
        bc.divergence_residual(xs, v, fl.mf, dc, lc, pairs_c, fl.h, 1e-3, *a)
        bg.divergence_residual(xg, vg, fl.mf, dg, lg, pairs_g, fl.h, 1e-3, *b)
        diffs[f"divergence_residual.{label}"] = max(rel(p, bg.to_host(q)) for p, q in zip(a, b))
        bc.density_residual(xs, v, fl.mf, dc, lc, pairs_c, fl.h, fl.rho0, 1e-3, *a)
        bg.density_residual(xg, vg, fl.mf, dg, lg, pairs_g, fl.h, fl.rho0, 1e-3, *b)
        diffs[f"density_residual.{label}"] = max(rel(p, bg.to_host(q)) for p, q in zip(a, b))
        v2c, v2g, ktc, ktg = v.copy(), bg.asarray(v), np.zeros(n), bg.zeros(n)
        k = rng.random(n)
        bc.apply_stiffness(xs, fl.mf, dc, lc, pairs_c, fl.h, k, 1e-3, v2c, ktc)
        bg.apply_stiffness(xg, fl.mf, dg, lg, pairs_g, fl.h, bg.asarray(k), 1e-3, v2g, ktg)
        diffs[f"apply_stiffness.{label}"] = max(rel(v2c, bg.to_host(v2g)), rel(ktc, bg.to_host(ktg)))
    outs_c = [np.zeros((n, 3)), np.zeros(n), np.zeros((n, 3))]
    outs_g = [bg.zeros(n, (3,)), bg.zeros(n), bg.zeros(n, (3,))]
    bc.viscosity(xs, v, fl.mf, dc, lam, lc, fl.h, 0.01, 1e-4, *outs_c, bc.NO_PAIRS)
    bg.viscosity(xg, vg, fl.mf, dg, bg.asarray(lam), lg, fl.h, 0.01, 1e-4, *outs_g, bg.NO_PAIRS)
    diffs["viscosity"] = max(rel(p, bg.to_host(q)) for p, q in zip(outs_c, outs_g))
    # the implicit viscosity's CG solve (issue 30): nu dt = 1e-3 m^2 with no-slip walls, to a tight tolerance
    vcfg = ViscosityConfig(error_pct=1e-4, max_iterations=200)
    vs_c, vs_g = v.copy(), bg.asarray(v)
    r_ = cpu.scene.particle_radius
    it_c = viscous_solve(
        bc, fl, xs, vs_c, dc, cpu.boundary, lc, 1e-3, 1.0, 1.0, vcfg, ViscosityScratch.allocate(bc, n), r_
    )
    it_g = viscous_solve(
        bg, fl, xg, vs_g, dg, gpu.boundary, lg, 1e-3, 1.0, 1.0, vcfg, ViscosityScratch.allocate(bg, n), r_
    )
    diffs["viscous_solve"] = rel(vs_c, bg.to_host(vs_g))
    res["viscous_iterations"] = [it_c[0], it_g[0]]
    s = xs + 1e-3 * rng.standard_normal(xs.shape)
    xo_c, ls_c = np.zeros_like(xs), lam.copy()
    xo_g, ls_g = bg.zeros(n, (3,)), bg.asarray(lam)
    bc.pf_global(xs, s, fl.mf, dc, lc, fl.h, fl.rho0, 1e-3, xo_c, ls_c)
    bg.pf_global(xg, bg.asarray(s), fl.mf, dg, lg, fl.h, fl.rho0, 1e-3, xo_g, ls_g)
    diffs["pf_global"] = max(rel(xo_c, bg.to_host(xo_g)), rel(ls_c, bg.to_host(ls_g)))
    # reductions and permutations
    m = rng.random(n)
    diffs["mean"] = abs(bc.mean(lam) - bg.mean(bg.asarray(lam))) / bc.mean(lam)
    diffs["mean_positive"] = abs(
        bc.mean_positive(lam - 0.5) - bg.mean_positive(bg.asarray(lam - 0.5))
    ) / bc.mean_positive(lam - 0.5)
    se_c, se_g = bc.speed_energy(v, m), bg.speed_energy(vg, bg.asarray(m))
    diffs["speed_energy"] = max(abs(se_c[0] - se_g[0]) / se_c[0], abs(se_c[1] - se_g[1]) / se_c[1])
    res["max_exact"] = bg.max(bg.asarray(lam)) == float(lam.max())
    bad = xs.copy()
    bad[n // 2, 1] = np.nan
    lo, hi = np.full(3, -np.inf), np.full(3, np.inf)
    res["unhealthy"] = [
        bg.first_unhealthy(bg.asarray(bad), vg, lo, hi),
        bc.first_unhealthy(bad, v, lo, hi),
        bg.first_unhealthy(xg, vg, lo, hi),
    ]
    perm = rng.permutation(n)
    taken = bg.take(bg.asarray(v), bg.asarray(perm, dtype="int64"))
    back = bg.take(bg.asarray(v), bg.asarray(perm, dtype="int64"))
    bg.untake(back, bg.asarray(perm, dtype="int64"))
    res["take_untake"] = bool(np.array_equal(bg.to_host(taken), v[perm]) and np.array_equal(bg.to_host(back), v))
    res["diffs"] = diffs
    # the GPU's out-of-memory error becomes one line (exit 2): the driver's error, as numba-cuda raises it
    from numba.cuda.cudadrv.driver import CudaAPIError

    from ipsph.backends import _cuda
    from ipsph.errors import ConfigError

    def exhausted(*a, **k):
        raise CudaAPIError(
            "CUresult.CUDA_ERROR_OUT_OF_MEMORY", "Call to cuMemAlloc results in CUDA_ERROR_OUT_OF_MEMORY"
        )

    real, _cuda.cuda.device_array = _cuda.cuda.device_array, exhausted
    try:
        bg.zeros(10**8, (3,))
        res["oom"] = None
    except ConfigError as exc:
        res["oom"] = str(exc)
    finally:
        _cuda.cuda.device_array = real
    return res


def _type_of(a) -> list:
    """A launch argument as [dtype, ndim] (arrays, C-contiguous views) or [kind] (scalars)."""
    a = getattr(getattr(a, "_item", a), "_ary", a)  # the simulator's array wrappers
    if hasattr(a, "dtype") and getattr(a, "ndim", 0) > 0:
        return [str(a.dtype), a.ndim, bool(a.flags.c_contiguous)]
    return [type(a).__name__ if not isinstance(a, np.generic) else str(a.dtype)]


def case_record() -> dict:
    """Every kernel launch of short runs of the three methods (both precisions) and of the
    checks above, as (kernel, stride of its scratch block, argument types), for case_ptx."""
    from ipsph.backends import cuda_passes

    seen = {}
    plain = cuda_passes.run

    def recording(kernel, blocks, threads, *args):
        fn = getattr(kernel, "fn", None) or kernel.py_func
        key = json.dumps([fn.__module__, fn.__name__, getattr(kernel, "strides", None), [_type_of(a) for a in args]])
        seen[key] = seen.get(key, 0) + 1
        plain(kernel, blocks, threads, *args)

    cuda_passes.run = recording
    for method in ("ipsph", "pf", "dfsph"):
        for precision in ("float64", "float32"):
            scene = tank(method)
            fx, fv, bx, _ = sample_scene(scene)
            sim = Simulation(scene, fx, fv, bx, backend=get_backend("cuda", precision))
            sim.step()
            sim.step()  # the warm starts (they need the previous step)
    for precision in ("float64", "float32"):  # moving walls (the wall_rate pass), an emitter (views, concat)
        for scene in (paddle_and_crate("ipsph"), jet("ipsph")):
            fx, fv, bx, _ = sample_scene(scene)
            Simulation(scene, fx, fv, bx, backend=get_backend("cuda", precision)).step()
    return {"launches": [json.loads(k) for k in seen]}


def case_ptx() -> dict:
    """Compile every recorded kernel for a real GPU (PTX for sm_90 through NVVM, no driver needed):
    the bodies of `bodies` compiled as CUDA device functions, with the argument types the runs used."""
    import importlib
    import subprocess

    from numba import types as nt

    from ipsph.backends import cuda_passes
    from ipsph.backends._cuda import cuda

    rec = subprocess.run([sys.executable, __file__, "record"], capture_output=True, text=True, check=True)
    launches = json.loads(rec.stdout)["launches"]

    def numba_type(t):
        if len(t) == 1:
            return {"float": nt.float64, "int": nt.int64, "bool": nt.boolean}.get(t[0]) or getattr(nt, t[0])
        dtype, ndim, contiguous = t
        return nt.Array(getattr(nt, dtype), ndim, "C" if contiguous else "A")

    compiled, failed, local_bytes = [], [], {}
    for module, name, strides, types in launches:
        if strides is not None:
            kernel = cuda_passes.passes(*strides)[name]
        else:
            kernel = getattr(importlib.import_module(module), name)
        try:
            ptx, _ = cuda.compile_ptx(kernel.py_func, tuple(numba_type(t) for t in types), cc=(9, 0))
        except Exception as exc:
            failed.append([module, name, types, f"{type(exc).__name__}: {str(exc)[-800:]}"])
            continue
        depot = [line for line in ptx.splitlines() if "__local_depot" in line and ".local" in line]
        local_bytes[f"{name}{strides or ''}"] = int(depot[0].split("[")[1].split("]")[0]) if depot else 0
        compiled.append([module, name, len(ptx)])
    return {"compiled": compiled, "failed": failed, "local_bytes": local_bytes}


if __name__ == "__main__":
    print(json.dumps(globals()[f"case_{sys.argv[1]}"]()))
