"""Worker subprocess: run one SPlisHSPlasH scene headless and print ONE JSON line of measurements.

    python -m ipsph.bench._peer_worker --scene ABS.json --method dfsph|pf --end-time T --threads N
           [--param key:value ...] [--param Fluid:key:value ...] [--work-dir DIR]

Run it through :func:`ipsph.bench.peer.run_peer`, which sets ``LD_PRELOAD`` (the pySPlisHSPlasH
wheel segfaults on import without libGLdispatch on some images) and ``OMP_NUM_THREADS``.

The stock scene is never modified: a rewritten copy (absolute mesh paths, the chosen method, ``stopAt``,
file export off, ``--param`` overrides) is written to ``--work-dir`` or to a temporary directory.
SPlisHSPlasH caches volume maps / boundary samples in ``<scene dir>/Cache``, so a persistent
``--work-dir`` makes repeated runs start faster; init time is reported separately and never counted.

Per step (time-step callback of ``SimulatorBase``) we record the step size, the solver's iteration
count and the mean positive density error ``mean_i max(rho_i / rho0 - 1, 0)`` over the fluid particles,
read from the fluid model's ``density`` field (the density the solver computed in that step).
All SPlisHSPlasH console output goes to stderr so stdout holds only the JSON line.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

# simulationMethod enum of SPlisHSPlasH 2.x and the TimeStep class each one creates
METHODS = {
    "wcsph": (0, "TimeStepWCSPH"),
    "pcisph": (1, "TimeStepPCISPH"),
    "pbf": (2, "TimeStepPBF"),
    "iisph": (3, "TimeStepIISPH"),
    "dfsph": (4, "TimeStepDFSPH"),
    "pf": (5, "TimeStepPF"),
    "icsph": (6, "TimeStepICSPH"),
}
BOUNDARY_METHODS = {0: "Akinci2012 particles", 1: "Koschier2017 density maps", 2: "Bender2019 volume maps"}
# scene keys holding file paths, resolved against the stock scene's folder
_PATH_KEYS = ("geometryFile", "particleFile", "mapFile", "samplesFile", "visMeshFile")
# exporters and state dumps that would put file I/O inside the timed loop
_NO_EXPORT = {
    "enablePartioExport": False,
    "enableVTKExport": False,
    "enableRigidBodyExport": False,
    "enableRigidBodyVTKExport": False,
    "enableStateExport": False,
    "enableAsyncExport": False,
}


def _parse_value(text: str):
    """JSON scalar if it parses (1, 0.5, true), a list for 'a,b,c', else the string itself."""
    if "," in text:
        return [_parse_value(t) for t in text.split(",")]
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text


def parse_params(items: list[str]) -> list[tuple[str | None, str, object]]:
    """``key:value`` (Configuration) or ``materialId:key:value`` (Materials entry), SPlisHSPlasH's syntax."""
    out = []
    for item in items:
        parts = item.split(":")
        if len(parts) == 2:
            out.append((None, parts[0], _parse_value(parts[1])))
        elif len(parts) == 3:
            out.append((parts[0], parts[1], _parse_value(parts[2])))
        else:
            raise SystemExit(f"--param {item!r}: expected key:value or materialId:key:value")
    return out


def _absolutize(node, base: Path):
    if isinstance(node, dict):
        for k, v in node.items():
            if k in _PATH_KEYS and isinstance(v, str) and v and not os.path.isabs(v):
                node[k] = os.path.normpath(str(base / v))
            else:
                _absolutize(v, base)
    elif isinstance(node, list):
        for v in node:
            _absolutize(v, base)


def write_scene(src: Path, dst_dir: Path, method: str, end_time: float, params) -> Path:
    """Rewrite the stock scene into ``dst_dir`` (stock file untouched) and return the new path."""
    scene = json.loads(src.read_text())
    _absolutize(scene, src.parent)
    conf = scene.setdefault("Configuration", {})
    conf["simulationMethod"] = METHODS[method][0]
    conf["stopAt"] = float(end_time)
    conf.update(_NO_EXPORT)
    for mat_id, key, value in params:
        if mat_id is None:
            conf[key] = value
            continue
        for mat in scene.setdefault("Materials", []):
            if mat.get("id") == mat_id:
                mat[key] = value
                break
        else:
            raise SystemExit(f"--param {mat_id}:{key}: no material with id {mat_id!r} in {src}")
    dst = dst_dir / f"{src.stem}_peer.json"
    dst.write_text(json.dumps(scene, indent=1))
    return dst


def _median(xs: list[float]) -> float:
    s = sorted(xs)
    n = len(s)
    if n == 0:
        return float("nan")
    return s[n // 2] if n % 2 else 0.5 * (s[n // 2 - 1] + s[n // 2])


def _peer_version() -> str | None:
    from importlib import metadata

    for dist in ("pySPlisHSPlasH", "pysplishsplash"):
        try:
            return metadata.version(dist)
        except metadata.PackageNotFoundError:
            continue
    return None


def _cpu_seconds() -> float:
    import resource

    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def run(scene: Path, method: str, end_time: float, work_dir: Path, params) -> dict:
    import numpy as np
    import pysplishsplash as sph
    import pysplishsplash.Exec as sph_exec
    from pysplishsplash.Utilities import Timing

    scene_file = write_scene(scene, work_dir, method, end_time, params)
    t_init = time.perf_counter()
    base = sph_exec.SimulatorBase()
    base.init(sceneFile=str(scene_file), useGui=False, outputDir=str(work_dir / "output"))
    base.initSimulation()
    sim = sph.Simulation.getCurrent()
    ts = sim.getTimeStep()
    expected = METHODS[method][1]
    if type(ts).__name__ != expected:
        raise RuntimeError(f"SPlisHSPlasH built {type(ts).__name__}, expected {expected} for method {method!r}")
    tm = sph.TimeManager.getCurrent()
    fluid = sim.getFluidModel(0)
    rho0 = fluid.getDensity0()
    has_iters = hasattr(type(ts), "SOLVER_ITERATIONS")
    has_iters_v = hasattr(type(ts), "SOLVER_ITERATIONS_V")

    rec = {"dt": [], "err": [], "iters": [], "iters_v": [], "step_s": []}
    state = {"t_prev_end": None, "t_first": None, "cpu_first": None, "t_last": None, "cpu_last": None, "init_end": None}

    def on_step():
        t = time.perf_counter()
        if state["t_prev_end"] is None:
            state["t_first"], state["cpu_first"] = t, _cpu_seconds()
        else:
            rec["step_s"].append(t - state["t_prev_end"])
        n = fluid.numActiveParticles()
        rho = np.asarray(fluid.getFieldBuffer("density"))[:n]
        rec["err"].append(float(np.maximum(rho / rho0 - 1.0, 0.0).mean()))
        rec["dt"].append(tm.getTimeStepSize())
        if has_iters:
            rec["iters"].append(ts.getValueInt(type(ts).SOLVER_ITERATIONS))
        if has_iters_v:
            rec["iters_v"].append(ts.getValueInt(type(ts).SOLVER_ITERATIONS_V))
        state["t_last"], state["cpu_last"] = time.perf_counter(), _cpu_seconds()
        state["t_prev_end"] = state["t_last"]

    base.setTimeStepCB(on_step)
    base.runSimulation()  # deferred init (volume maps / boundary samples) happens here, before step 1
    t_end = time.perf_counter()

    # boundary description
    bh = int(sim.getValueInt(sph.Simulation.BOUNDARY_HANDLING_METHOD))
    n_boundary = 0
    for i in range(sim.numberOfBoundaryModels()):
        bm = sim.getBoundaryModel(i)
        if hasattr(bm, "numberOfParticles"):
            n_boundary += int(bm.numberOfParticles())

    # where the fluid ended up: a cheap check that nothing leaked through the boundary
    n_fluid = fluid.numActiveParticles()
    x_end = np.asarray(fluid.getFieldBuffer("position")).reshape(-1, 3)[:n_fluid]
    bbox = [x_end.min(axis=0).tolist(), x_end.max(axis=0).tolist()] if n_fluid else None

    phases = {}
    for avg in Timing.m_averageTimes.values():  # keyed by an id; the phase name is avg.name
        if avg.counter > 0:
            phases[str(avg.name)] = {
                "mean_ms": avg.totalTime / avg.counter,
                "count": int(avg.counter),
                "total_s": avg.totalTime / 1e3,
            }
    sim_step = phases.get("SimStep")
    steps = len(rec["dt"])
    wall = sim_step["total_s"] if sim_step else float("nan")
    loop_s = (state["t_last"] - state["t_first"]) if steps > 1 else float("nan")
    loop_cpu = (state["cpu_last"] - state["cpu_first"]) if steps > 1 else float("nan")
    # init = everything before step 1 starts (scene load, sampling, volume maps); step 1 ~ the median step
    init_s = (state["t_first"] - t_init - _median(rec["step_s"])) if steps > 1 else t_end - t_init
    errs = rec["err"]
    finite = [e for e in errs if e == e]

    def _cfg(key_attr, getter="getValueFloat", obj=ts):
        attr = getattr(type(obj), key_attr, None)
        if attr is None:
            return None
        try:
            return getattr(obj, getter)(attr)
        except Exception:  # parameter of another type: report nothing rather than guess
            return None

    solver = {
        "max_error_pct": _cfg("MAX_ERROR"),
        "max_iterations": _cfg("MAX_ITERATIONS", "getValueUInt"),
        "min_iterations": _cfg("MIN_ITERATIONS", "getValueUInt"),
        "max_error_v_pct": _cfg("MAX_ERROR_V"),
        "max_iterations_v": _cfg("MAX_ITERATIONS_V", "getValueUInt"),
        "divergence_solver": _cfg("USE_DIVERGENCE_SOLVER", "getValueBool"),
        "stiffness": _cfg("STIFFNESS"),
        "cfl_factor": _cfg("CFL_FACTOR", obj=sim),
        "cfl_max_dt": _cfg("CFL_MAX_TIMESTEPSIZE", obj=sim),
        "gravity": list(sim.getVec3ValueReal(sph.Simulation.GRAVITATION)),
        "particle_radius": sim.getParticleRadius(),
    }
    solver = {k: v for k, v in solver.items() if v is not None}
    # what the peer smooths and damps with: its viscosity model (None, or the class) and XSPH filter
    model = fluid.getViscosityBase()
    xsph = fluid.getXSPH() if hasattr(fluid, "getXSPH") else None  # 2.12 on: a filter of its own
    solver["viscosity_model"] = type(model).__name__ if model is not None else "None"
    if model is not None:
        solver["viscosity"] = _cfg("VISCOSITY_COEFFICIENT", obj=model)
    if xsph is not None:
        solver["xsph"] = _cfg("FLUID_COEFFICIENT", obj=xsph)

    # friendly names -> SPlisHSPlasH timer names (first one present wins)
    phase_alias = {
        "step_ms": ("SimStep",),
        "pressure_solve_ms": ("pressureSolve", "solvePDConstraints"),
        "divergence_solve_ms": ("divergenceSolve",),
        "neighborhood_search_ms": ("neighborhood_search", "neighborhood search"),
        "boundary_volume_ms": ("computeVolumeAndBoundaryX",),
        "non_pressure_forces_ms": ("computeNonPressureForces",),
    }
    out = {
        "peer": "SPlisHSPlasH",
        "version": _peer_version(),
        "scene": str(scene),
        "method": method,
        "time_step_class": type(ts).__name__,
        "boundary_handling": BOUNDARY_METHODS.get(bh, str(bh)),
        "boundary_handling_method": bh,
        "threads": int(os.environ.get("OMP_NUM_THREADS", "0") or 0),
        "fluid_particles": int(fluid.numActiveParticles()),
        "boundary_particles": n_boundary,
        "steps": steps,
        "end_time": end_time,
        "sim_time": float(tm.getTime()),
        "completed": bool(tm.getTime() >= end_time * (1 - 1e-6)),
        "wall_seconds": wall,
        "wall_seconds_per_sim_second": wall / tm.getTime() if tm.getTime() > 0 else float("nan"),
        "loop_seconds_python": loop_s,
        "loop_cpu_cores": loop_cpu / loop_s if loop_s == loop_s and loop_s > 0 else float("nan"),
        "ms_per_step": 1e3 * _median(rec["step_s"]),
        "ms_per_step_mean": sim_step["mean_ms"] if sim_step else float("nan"),
        "ms_per_step_max": 1e3 * max(rec["step_s"]) if rec["step_s"] else float("nan"),
        "dt_min": min(rec["dt"]) if rec["dt"] else float("nan"),
        "dt_max": max(rec["dt"]) if rec["dt"] else float("nan"),
        "dt_mean": tm.getTime() / steps if steps else float("nan"),
        "iterations_mean": sum(rec["iters"]) / len(rec["iters"]) if rec["iters"] else None,
        "iterations_max": max(rec["iters"]) if rec["iters"] else None,
        "divergence_iterations_mean": sum(rec["iters_v"]) / len(rec["iters_v"]) if rec["iters_v"] else None,
        "density_error_mean_pct": 100.0 * sum(finite) / len(finite) if finite else float("nan"),
        "density_error_worst_pct": 100.0 * max(finite) if finite else float("nan"),
        "density_error_nonfinite_steps": len(errs) - len(finite),
        "init_seconds": init_s,
        "fluid_bbox_end": bbox,
        "solver": solver,
        "phases": phases,
    }
    for alias, names in phase_alias.items():
        key = next((n for n in names if n in phases), None)
        out[alias] = phases[key]["mean_ms"] if key else None
    base.cleanup()
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m ipsph.bench._peer_worker", description=__doc__.split("\n")[0])
    ap.add_argument("--scene", required=True, type=Path, help="SPlisHSPlasH scene JSON (absolute path)")
    ap.add_argument("--method", required=True, choices=sorted(METHODS))
    ap.add_argument("--end-time", required=True, type=float, help="simulated seconds (stopAt)")
    ap.add_argument("--threads", type=int, default=None, help="OpenMP threads (sets OMP_NUM_THREADS)")
    ap.add_argument("--param", action="append", default=[], help="key:value or materialId:key:value")
    ap.add_argument("--work-dir", type=Path, default=None, help="where the rewritten scene and Cache/ go")
    args = ap.parse_args(argv)

    if args.threads is not None:  # before pysplishsplash (and its OpenMP runtime) is loaded
        os.environ["OMP_NUM_THREADS"] = str(args.threads)
    scene = args.scene.resolve()
    if not scene.is_file():
        print(f"peer worker: scene {args.scene} (resolved {scene}) is not a file", file=sys.stderr)
        return 2
    if not args.end_time > 0:
        print(f"peer worker: --end-time must be > 0, got {args.end_time}", file=sys.stderr)
        return 2
    params = parse_params(args.param)

    # SPlisHSPlasH logs to std::cout: point fd 1 at stderr while it runs, keep the real stdout for JSON
    sys.stdout.flush()
    real_stdout = os.dup(1)
    os.dup2(2, 1)
    try:
        if args.work_dir is not None:
            args.work_dir.mkdir(parents=True, exist_ok=True)
            result = run(scene, args.method, args.end_time, args.work_dir.resolve(), params)
        else:
            with tempfile.TemporaryDirectory(prefix="ipsph-peer-") as tmp:
                result = run(scene, args.method, args.end_time, Path(tmp), params)
        import resource

        result["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    finally:
        sys.stdout.flush()
        os.dup2(real_stdout, 1)
        os.close(real_stdout)
    sys.stdout.write(json.dumps(result, allow_nan=True, default=float) + "\n")
    sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
