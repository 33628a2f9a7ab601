"""`ipsph bench`: our three methods against SPlisHSPlasH (when installed), interleaved, on a shared machine.

    ipsph bench                                  # DamBreakModel + DoubleDamBreak, ipsph pf dfsph + peer, 3 repeats
    ipsph bench --repeats 1 --end-time 0.5 --markdown --json bench.json
    ipsph bench --scaling 10000 100000 1000000    # ms/step, us per particle-step, bytes per particle
    ipsph bench --first-frame                    # seconds to the first frame, cold and warm Numba cache
    ipsph bench --render-sizes 100000 1000000    # issue 4: render seconds per 1280x720 frame
    ipsph bench --render-overhead --repeats 5    # issue 4: default scene with / without renders
    ipsph bench --surface-sizes 1000000          # issue 20: seconds per surface of a jittered N lattice
    ipsph bench --surface-overhead --repeats 5   # issue 20: default scene with / without --surface
    ipsph bench --table1                         # issue 5: the paper's Table 1 on pipelines/*.toml
    ipsph bench --figure4 fig4 --end-time 1.5     # issue 5: Figure 4, IPSPH beside PF, and their errors
    ipsph bench --sweep                          # issue 21: a 2-worker sweep against the same 4 runs in a row
    ipsph bench --buoyancy --methods ipsph       # floating cubes against Archimedes (method.md section 9)

Every simulation runs in its own worker process (peak RSS per method) with the same thread count
(NUMBA_NUM_THREADS for ours, OMP_NUM_THREADS for SPlisHSPlasH), in the order
``for repeat: for scene: for method`` so machine noise spreads over all methods alike. A run during
which other processes used more than ``--max-load`` cores is shown as loaded and left out of the medians.
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

from ..errors import ConfigError
from ..params import BACKEND_NAMES, BOUNDARY_MODELS, METHOD_NAMES, PRECISIONS
from . import report
from .scenes import (
    DEFAULT_SCENES,
    PIPELINES,
    pipeline_path,
    resolve_scene,
    scaling_count,
    scaling_dt_max,
    scaling_overrides,
    scaling_peer_scene,
)

OUR_METHODS = METHOD_NAMES
PEER_METHODS = ("dfsph", "pf")
FIRST_FRAME_TARGET_S = {"cold": 25.0, "warm": 3.0}  # issue 22, on 2 cores


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.description = (
        "Benchmark our methods (and SPlisHSPlasH's DFSPH and PF, when pysplishsplash is installed) "
        "on the stock SPlisHSPlasH scenes, interleaved, one process per run."
    )
    p.add_argument(
        "--scenes",
        nargs="+",
        metavar="SCENE",
        default=None,
        help=f"scene files or stock scene names (default: {' '.join(DEFAULT_SCENES)})",
    )
    p.add_argument(
        "--scene-dir",
        type=Path,
        metavar="DIR",
        help="SPlisHSPlasH Scenes folder for scene names (default: $IPSPH_SPLISHSPLASH_SCENES, else "
        "the repository's copy in tests/data/splishsplash/Scenes)",
    )
    p.add_argument(
        "--methods",
        nargs="+",
        choices=OUR_METHODS,
        default=list(OUR_METHODS),
        help="our methods to run (default: ipsph pf dfsph)",
    )
    p.add_argument(
        "--peer",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="also run SPlisHSPlasH's DFSPH and PF (with --scaling: its DFSPH on the same dam breaks; "
        "default: when pysplishsplash imports)",
    )
    p.add_argument("--end-time", type=float, default=1.0, metavar="T", help="simulated seconds per run (default 1.0)")
    p.add_argument("--repeats", type=int, default=3, metavar="R", help="interleaved repeats (default 3)")
    p.add_argument("--threads", type=int, default=2, metavar="N", help="threads for every method (default 2)")
    p.add_argument(
        "--max-load",
        type=float,
        default=0.5,
        metavar="CORES",
        help="flag a run as loaded when other processes used more than this many cores on average "
        "(i.e. mean load > threads + CORES); loaded runs are printed, not counted (default 0.5)",
    )
    p.add_argument(
        "--scaling",
        nargs="*",
        type=int,
        metavar="N",
        default=None,
        help="scaling sweep instead: dam break with ~N fluid particles each (default sizes: 10000 100000 1000000)",
    )
    p.add_argument(
        "--scaling-methods",
        nargs="+",
        choices=OUR_METHODS,
        default=["ipsph"],
        help="methods of the scaling sweep (default: ipsph)",
    )
    p.add_argument(
        "--backend",
        choices=BACKEND_NAMES,
        default="cpu",
        help="with --scaling: run the sweep on this backend (cuda: beside the CPU backend's figures for "
        "the sizes up to --cpu-max-particles)",
    )
    p.add_argument(
        "--precision",
        choices=PRECISIONS,
        default="float64",
        help="with --backend cuda: simulation.precision of the GPU runs (default float64)",
    )
    p.add_argument("--device", type=int, default=0, metavar="N", help="with --backend cuda: the GPU")
    p.add_argument(
        "--cpu-max-particles",
        type=int,
        default=200_000,
        metavar="N",
        help="with --backend cuda: also run the CPU backend at the sizes up to N fluid particles "
        "(default 200000; 0: none)",
    )
    p.add_argument(
        "--scaling-steps",
        type=int,
        default=10,
        metavar="S",
        help="timed steps per size, after 2 warm-up steps (default 10)",
    )
    p.add_argument(
        "--render-sizes",
        nargs="*",
        type=int,
        metavar="N",
        default=None,
        help="per-frame render cost of `ipsph run`'s renderer at N particles, 1280x720 (default sizes: 100000 1000000)",
    )
    p.add_argument(
        "--surface-sizes",
        nargs="*",
        type=int,
        metavar="N",
        default=None,
        help="issue 20: seconds per surface reconstruction of a jittered lattice of N particles on "
        "--threads threads, median of --repeats (default size: 1000000; --set surface.KEY=VALUE)",
    )
    for what, issue in (("renders", 4), ("--surface", 20)):
        p.add_argument(
            f"--{'render' if issue == 4 else 'surface'}-overhead",
            action="store_true",
            help=f"issue {issue}: wall time of `ipsph run` on the default scene with and without "
            f"{what}, --repeats alternating pairs, and the slow-down (target <= 25 %%)",
        )
    p.add_argument(
        "--moving-walls",
        action="store_true",
        help="issue 19: per-step cost of a kinematic wall and of a rigid body against the same scene "
        "with the wall static (interleaved turns, --repeats, --threads; same-run ratios)",
    )
    p.add_argument(
        "--buoyancy",
        action="store_true",
        help="a cube of 300, 500, 700 and 900 kg/m^3, 6 and 12 spacings across, floating in a tank: its "
        "submerged volume fraction against Archimedes, per --methods and --buoyancy-models",
    )
    p.add_argument(
        "--buoyancy-models",
        nargs="+",
        choices=BOUNDARY_MODELS,
        default=[BOUNDARY_MODELS[0]],
        help="wall models for --buoyancy (simulation.boundary_model; default: %(default)s)",
    )
    p.add_argument(
        "--first-frame",
        action="store_true",
        help="time to first frame of `ipsph run` (default scene), with a cold and a warm Numba cache",
    )
    p.add_argument(
        "--table1",
        action="store_true",
        help="issue 5: IPSPH, DFSPH and PF on pipelines/*.toml (and SPlisHSPlasH on its stock scenes), "
        "the paper's Table 1 columns",
    )
    p.add_argument(
        "--figure4",
        type=Path,
        metavar="OUT",
        help="issue 5: the paper's Figure 4 - breaking dam, IPSPH beside PF at the same times, "
        "rendered side by side into OUT, plus their density error against time "
        "(uses --end-time, default here 1.0, and --threads)",
    )
    p.add_argument(
        "--sweep",
        action="store_true",
        help="issue 21: 4 members on a 2-worker x 1-thread LocalCluster against the same 4 `ipsph run "
        "--threads 2` one after another: wall ratio and scheduler overhead per member "
        "(uses --end-time, --repeats)",
    )
    p.add_argument(
        "--pipelines",
        nargs="+",
        choices=sorted(PIPELINES),
        default=None,
        help="with --table1: which pipelines (default: all three)",
    )
    p.add_argument(
        "--dragon-mesh",
        type=Path,
        metavar="OBJ",
        help="with --table1: SPlisHSPlasH's Dragon_50k.obj for both dragons of two_dragons.toml "
        "(default: the pipeline's meshes/Dragon_50k.obj)",
    )
    p.add_argument(
        "--baseline",
        type=Path,
        metavar="DIR",
        help="also run our methods from the ipsph source tree DIR (e.g. `git worktree add ../base main`), "
        "interleaved with this build, and print this / baseline ratios (a change's speed A/B)",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="scene override for all our runs (repeatable), e.g. --set simulation.viscosity=0.02",
    )
    p.add_argument("--markdown", action="store_true", help="print Markdown tables")
    p.add_argument("--json", type=Path, metavar="PATH", help="save every raw result as JSON")
    p.add_argument(
        "--from-json",
        type=Path,
        metavar="PATH",
        help="run nothing: print the tables of a file saved with --json (e.g. again as --markdown)",
    )
    p.add_argument("--timeout", type=float, default=1800.0, metavar="S", help="per-run timeout (default 1800 s)")


# -- helpers ---------------------------------------------------------------------------------------
def _log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def _check_args(args) -> None:
    if args.baseline is not None and not (args.baseline / "ipsph" / "benchmark" / "_ours_worker.py").is_file():
        raise ConfigError(
            f"--baseline {args.baseline} (resolved {args.baseline.resolve()}): not an ipsph source "
            f"tree (no ipsph/benchmark/_ours_worker.py in it)"
        )
    if not args.end_time > 0:
        raise ConfigError(f"--end-time {args.end_time}: must be > 0 simulated seconds")
    if args.repeats < 1:
        raise ConfigError(f"--repeats {args.repeats}: must be >= 1")
    if args.threads < 1:
        raise ConfigError(f"--threads {args.threads}: must be >= 1")
    if not args.max_load >= 0:
        raise ConfigError(f"--max-load {args.max_load}: must be >= 0 cores")
    if args.scaling_steps < 1:
        raise ConfigError(f"--scaling-steps {args.scaling_steps}: must be >= 1")
    if args.backend == "cuda":
        from ..backends._cuda import unavailable

        why = unavailable(args.device)
        if why is not None:
            raise ConfigError(f"--backend cuda: {why}")
    cpus = os.cpu_count() or 1
    if args.threads > cpus:
        _log(f"ipsph bench: warning: --threads {args.threads} is more than the {cpus} logical cores")


def _use_peer(flag: bool | None) -> tuple[bool, str]:
    from .peer import peer_available

    if flag is False:
        return False, "SPlisHSPlasH: off (--no-peer)"
    ok, why = peer_available()
    if flag and not ok:
        raise ConfigError(f"--peer: {why}")
    return ok, (f"SPlisHSPlasH: {why}" if ok else f"SPlisHSPlasH: skipped ({why})")


def _run_one(
    kind: str,
    scene_file: Path,
    method: str,
    args,
    label_scene: str,
    repeat: int,
    work_dir: Path,
    overrides=(),
    end_time: float | None = None,
) -> dict:
    """Run one (ours or peer) simulation; failures become a row with `error`."""
    t = args.end_time if end_time is None else end_time
    t0 = time.perf_counter()
    try:
        if kind in ("ours", "baseline"):
            from .ours import run_ours

            env = {"PYTHONPATH": str(args.baseline.resolve())} if kind == "baseline" else None
            res = run_ours(scene_file, method, t, args.threads, overrides, timeout=args.timeout, env=env)
        else:
            from .peer import run_peer

            res = run_peer(scene_file, method, t, args.threads, timeout=args.timeout, work_dir=work_dir)
        row = report.normalise(res, "ours" if kind == "baseline" else kind, method, label_scene, repeat)
        if kind == "baseline":
            row.update(source=kind, label=row["label"] + report.BASELINE)
        row["raw"] = res
    except (RuntimeError, ConfigError, OSError) as exc:
        label = report.LABELS[("ours" if kind == "baseline" else kind, method)]
        row = {
            "scene": label_scene,
            "source": kind,
            "method": method,
            "repeat": repeat,
            "label": label + (report.BASELINE if kind == "baseline" else ""),
            "error": str(exc),
        }
    row["elapsed_s"] = time.perf_counter() - t0
    return row


def _progress(i: int, n: int, row: dict, max_load: float) -> None:
    head = f"[{i}/{n}] {row['scene']} {row['label']} run {row['repeat'] + 1}: "
    if row.get("error"):
        _log(head + "FAILED: " + row["error"].splitlines()[0])
        return
    flag = " LOADED" if report.is_loaded(row, max_load) else ""
    _log(
        head + f"{row['elapsed_s']:.1f} s, {row['ms_step']:.2f} ms/step, {row['wall_per_sim']:.2f} s/sim s, "
        f"others {row['others_cores']:.2f} cores{flag}"
    )


def _interleaved(jobs: list[tuple], args) -> list[dict]:
    """jobs: (kind, scene_file, method, label_scene, overrides), run `repeats` times interleaved."""
    rows = []
    n = len(jobs) * args.repeats
    with tempfile.TemporaryDirectory(prefix="ipsph-bench-") as tmp:
        for rep in range(args.repeats):
            for kind, scene_file, method, label, overrides in jobs:
                row = _run_one(kind, scene_file, method, args, label, rep, Path(tmp), overrides)
                rows.append(row)
                _progress(len(rows), n, row, args.max_load)
    return rows


# -- modes -----------------------------------------------------------------------------------------
def bench_scenes(args, peer: bool) -> tuple[str, list[dict]]:
    names = args.scenes or list(DEFAULT_SCENES)
    files = [(resolve_scene(s, args.scene_dir), s) for s in names]
    jobs = []
    for f, given in files:
        label = f.stem
        for m in args.methods:
            jobs.append(("ours", f, m, label, tuple(args.set)))
            if args.baseline is not None:
                jobs.append(("baseline", f, m, label, tuple(args.set)))
        if peer:
            if f.suffix.lower() == ".json":
                jobs += [("peer", f, m, label, ()) for m in PEER_METHODS]
            else:
                _log(f"ipsph bench: note: {given} is not a SPlisHSPlasH scene; SPlisHSPlasH skips it")
    rows = _interleaved(jobs, args)
    groups = report.summarise(rows, args.max_load)
    return report.scene_tables(groups, args.markdown, args.max_load), rows


def bench_table1(args, peer: bool) -> tuple[str, list[dict]]:
    jobs = []
    for stem in args.pipelines or list(PIPELINES):
        path = pipeline_path(stem)
        over = tuple(args.set)
        if stem == "two_dragons" and args.dragon_mesh is not None:
            mesh = Path(args.dragon_mesh).expanduser().resolve()
            if not mesh.is_file():
                raise ConfigError(
                    f"--dragon-mesh {args.dragon_mesh} (resolved {mesh}) is not a file: pass "
                    f"SPlisHSPlasH's data/models/Dragon_50k.obj"
                )
            over = (f"boundary.1.mesh={mesh}", f"boundary.2.mesh={mesh}") + over
        jobs += [("ours", path, m, stem, over) for m in ("ipsph", "dfsph", "pf") if m in args.methods]
        if peer:
            stock = resolve_scene(PIPELINES[stem], args.scene_dir)
            jobs += [("peer", stock, m, f"{stem} / {stock.stem}", ()) for m in PEER_METHODS]
    rows = _interleaved(jobs, args)
    groups = report.summarise(rows, args.max_load)
    return report.table1(groups, args.markdown), rows


def bench_scaling(args, peer: bool) -> tuple[str, list[dict]]:
    """Each size: our methods, then (with `peer`) SPlisHSPlasH's DFSPH on the same dam break
    (`scaling_peer_scene`) for as many steps, at its maximum step size, as ours take."""
    from .ours import run_ours
    from .peer import run_peer

    sizes = args.scaling or [10_000, 100_000, 1_000_000]
    rows = []

    def record(row: dict, n: int, t0: float) -> None:
        row.update(target=n, elapsed_s=time.perf_counter() - t0)
        rows.append(row)
        if row.get("error"):
            _log("  FAILED: " + row["error"].splitlines()[0])
        else:
            _log(
                f"  {row['elapsed_s']:.1f} s: {row['ms_step']:.1f} ms/step, "
                f"{row['us_particle_step']:.3f} us/particle-step, others {row['others_cores']:.2f} cores"
            )

    gpu = args.backend == "cuda"
    if gpu:
        from ..backends._cuda import SIMULATOR

        if SIMULATOR:
            _log("scaling: NUMBA_ENABLE_CUDASIM=1: the cuda rows time numba-cuda's CPU simulator, not a GPU")
    placements = (
        [["simulation.backend=cuda", f"simulation.precision={args.precision}", f"simulation.device={args.device}"]]
        if gpu
        else [[]]
    )
    with tempfile.TemporaryDirectory(prefix="ipsph-scaling-") as tmp:
        for n in sizes:
            over = scaling_overrides(n) + list(args.set)
            runs = placements + ([[]] if gpu and scaling_count(n) <= args.cpu_max_particles else [])
            for m in args.scaling_methods:
                for where in runs:
                    t0 = time.perf_counter()
                    _log(
                        f"scaling: {m} ~{scaling_count(n):,} fluid particles"
                        f"{' on ' + ' '.join(w.split('=')[1] for w in where[:2]) if where else ''} ..."
                    )
                    try:
                        res = run_ours(
                            "default",
                            m,
                            None,
                            args.threads,
                            over + where,
                            steps=args.scaling_steps,
                            warmup=2,
                            timeout=args.timeout,
                        )
                        row = report.normalise(res, "ours", m, "scaling", 0)
                        row.update(timed_steps=res.get("timed_steps"), raw=res)
                    except (RuntimeError, ConfigError, OSError) as exc:
                        row = {
                            "label": report.LABELS[("ours", m)],
                            "method": m,
                            "error": str(exc),
                            "backend": "cuda" if where else "cpu",
                        }
                    record(row, n, t0)
            if peer:
                t0 = time.perf_counter()
                _log(f"scaling: SPlisHSPlasH dfsph ~{scaling_count(n):,} fluid particles ...")
                try:
                    scene = scaling_peer_scene(n, Path(tmp))
                    # as many steps as ours (2 + S) at its maximum step (the column starts at rest);
                    # SPlisHSPlasH has no JIT, so its median is over all of them
                    end = (2 + args.scaling_steps) * scaling_dt_max() * (1.0 + 1e-6)
                    res = run_peer(scene, "dfsph", end, args.threads, timeout=args.timeout, work_dir=Path(tmp))
                    row = report.normalise(res, "peer", "dfsph", "scaling", 0)
                    # (no bytes per particle: ours subtract the RSS before sampling; compare peak RSS)
                    row.update(timed_steps=res.get("steps"), raw=res)
                except (RuntimeError, ConfigError, OSError) as exc:
                    row = {"label": report.LABELS[("peer", "dfsph")], "method": "dfsph", "error": str(exc)}
                record(row, n, t0)
    if gpu:
        return report.backend_scaling_table(rows, args.markdown, args.max_load), rows
    return report.scaling_table(rows, args.markdown, args.max_load), rows


def first_frame(threads: int, timeout: float = 900.0, repeats: int = 1) -> list[dict]:
    """Time to first frame: seconds for `ipsph run` (default scene, first frame at t = 0.04 s, no renders) to finish,
    with NUMBA_CACHE_DIR pointed at a fresh folder (cold: everything compiles) and then again (warm);
    `repeats` such pairs, each cold run with its own empty cache."""
    from .machine import timed_ipsph_run

    rows = []
    with tempfile.TemporaryDirectory(prefix="ipsph-first-frame-") as tmp:
        for k in range(repeats):
            env = dict(os.environ, NUMBA_CACHE_DIR=str(Path(tmp) / f"numba-cache-{k}"))
            for cache in ("cold", "warm"):
                out = Path(tmp) / f"out-{cache}-{k}"
                r = timed_ipsph_run(["--end-time", "0.04", "--no-render"], out, threads, timeout, env)
                try:  # run.json splits the time: setup (sampling, output folder), compile, the time loop
                    run_info = json.loads((out / "run.json").read_text())
                except (OSError, json.JSONDecodeError):
                    run_info = {}
                secs, code, frames, load = r["seconds"], r["exit_code"], r["frames"], r["load"]
                split = run_info.get("time_split_seconds") or {}
                rows.append(
                    {
                        "cache": cache,
                        "repeat": k,
                        "seconds": secs,
                        "ok": code == 0 and frames >= 2,
                        "exit_code": code,
                        "frames": frames,
                        "setup_seconds": run_info.get("setup_seconds"),
                        "loop_seconds": run_info.get("wall_seconds"),
                        "split": split,
                        "load": load.as_dict(),
                        "others_cores": load.others_busy_mean * load.cpus,
                        "stderr_tail": r["stderr_tail"],
                        "command": r["command"],
                    }
                )
                _log(
                    f"first frame ({cache} cache, run {k + 1}/{repeats}): {secs:.1f} s, exit {code}, {frames} frames, "
                    f"compile {split.get('compile', math.nan):.1f} s, others {rows[-1]['others_cores']:.2f} cores"
                )
    return rows


def reprint(path: Path, markdown: bool, max_load: float) -> str:
    """The tables of a saved --json file, with this call's --markdown and --max-load."""
    try:
        saved = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ConfigError(f"--from-json {path} (resolved {Path(path).resolve()}): cannot read it: {exc}") from exc
    h = lambda t: f"## {t}\n\n" if markdown else f"== {t} ==\n"  # noqa: E731
    texts = []
    if saved.get("first_frame"):
        texts.append(
            h("time to first frame") + report.first_frame_table(saved["first_frame"], markdown, FIRST_FRAME_TARGET_S)
        )
    if saved.get("scaling"):
        texts.append(h("scaling (dam break)") + report.scaling_table(saved["scaling"], markdown, max_load))
    if saved.get("table1"):
        texts.append(h("Table 1") + report.table1(report.summarise(saved["table1"], max_load), markdown))
    if saved.get("sweep"):
        from .sweep_bench import table as sweep_table

        texts.append(h("sweep on a LocalCluster") + sweep_table(saved["sweep"], markdown, max_load))
    if saved.get("runs"):
        texts.append(report.scene_tables(report.summarise(saved["runs"], max_load), markdown, max_load))
    m = saved.get("machine", {})
    head = (
        f"ipsph bench (saved {saved.get('started', '?')}): {m.get('cpu_model', '?')}, "
        f"{m.get('usable_cores', '?')} usable cores; {saved.get('threads', '?')} threads"
    )
    return ("# " if markdown else "") + head + "\n\n" + "\n\n".join(texts)


def main(args) -> int:
    from .machine import machine_info

    if args.from_json is not None:
        print(reprint(args.from_json, args.markdown, args.max_load))
        return 0
    _check_args(args)
    if args.figure4 is not None:
        from .figure4 import figure4, print_summary

        print_summary(figure4(args.figure4, args.end_time, args.threads, args.set))
        return 0
    if args.buoyancy:
        from .buoyancy import run as float_cubes

        float_cubes(args.methods, (300.0, 500.0, 700.0, 900.0), (6, 12), args.buoyancy_models)
        return 0
    info = machine_info()
    out: dict = {
        "machine": info,
        "threads": args.threads,
        "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "args": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items() if k not in ("func",)},
    }
    header = (
        f"ipsph bench: {info['cpu_model']}, {info['usable_cores']} usable cores, {info['memory_gb']} GB; "
        f"{args.threads} threads; loadavg at start {os.getloadavg()[0]:.2f}"
    )
    texts: list[str] = []
    failed = False
    if args.first_frame:
        rows = first_frame(args.threads, timeout=min(args.timeout, 900.0), repeats=args.repeats)
        out["first_frame"] = rows
        texts.append(
            ("## Time to first frame\n\n" if args.markdown else "== time to first frame ==\n")
            + report.first_frame_table(rows, args.markdown, FIRST_FRAME_TARGET_S)
        )
        failed |= not all(r["ok"] for r in rows)
    if args.moving_walls:
        from .moving_cost import moving_cost, table as moving_table

        rows = moving_cost(repeats=args.repeats, threads=args.threads, log=_log)
        out["moving_walls"] = rows
        texts.append(
            ("## Moving walls and bodies per step\n\n" if args.markdown else "== moving walls per step ==\n")
            + moving_table(rows, args.markdown)
        )
    if args.render_sizes is not None:
        from .render_cost import render_cost, table

        rows = [render_cost(n) for n in (args.render_sizes or [100_000, 1_000_000])]
        out["render_cost"] = rows
        texts.append(
            ("## Render cost per frame\n\n" if args.markdown else "== render cost per frame ==\n")
            + table(rows, args.markdown)
        )
    if args.sweep:
        from .sweep_bench import bench_sweep, table as sweep_table

        result = bench_sweep(args.end_time, args.repeats, args.max_load, min(args.timeout, 900.0), _log)
        out["sweep"] = result
        texts.append(
            ("## Sweep on a LocalCluster\n\n" if args.markdown else "== sweep on a LocalCluster ==\n")
            + sweep_table(result, args.markdown, args.max_load)
        )
    if args.surface_sizes is not None:
        from .surface_cost import sizes_table, surface_seconds

        over = [o for o in args.set if o.startswith("surface.")]
        rows = [
            surface_seconds(n, args.threads, args.repeats, over, timeout=min(args.timeout, 900.0), log=_log)
            for n in (args.surface_sizes or [1_000_000])
        ]
        out["surface_sizes"] = rows
        texts.append(
            ("## Surface reconstruction per frame\n\n" if args.markdown else "== surface reconstruction per frame ==\n")
            + sizes_table(rows, args.markdown)
        )
        failed |= any(r["particles"] is None for r in rows)
    for flag, module, title in (
        ("render_overhead", "render_cost", "Render overhead (default scene)"),
        ("surface_overhead", "surface_cost", "Surface overhead (default scene)"),
    ):
        if getattr(args, flag):  # the default scene's run without and with a side process
            mod = importlib.import_module(f"{__package__}.{module}")
            summary = getattr(mod, flag)(
                args.repeats, args.threads, args.max_load, timeout=min(args.timeout, 900.0), log=_log
            )
            out[flag] = summary
            texts.append(
                (f"## {title}\n\n" if args.markdown else f"== {title.lower()} ==\n")
                + mod.overhead_table(summary, args.markdown)
            )
            failed |= not summary["ok"]
    if args.scaling is not None:
        peer, why = _use_peer(args.peer)
        header += f"; scaling: {why}"
        text, rows = bench_scaling(args, peer)
        out["scaling"] = rows
        texts.append(("## Scaling (dam break)\n\n" if args.markdown else "== scaling (dam break) ==\n") + text)
        failed |= any(r.get("error") for r in rows)
    if args.table1 or not (
        args.first_frame
        or args.scaling is not None
        or args.render_sizes is not None
        or args.render_overhead
        or args.surface_sizes is not None
        or args.surface_overhead
        or args.sweep
        or args.moving_walls
    ):
        peer, why = _use_peer(args.peer)
        header += f"; {why}"
        _log(header)
        if args.table1:
            text, rows = bench_table1(args, peer)
            out["table1"] = rows
            texts.append(("## Table 1\n\n" if args.markdown else "== Table 1 ==\n") + text)
        else:
            text, rows = bench_scenes(args, peer)
            out["runs"] = rows
            texts.append(text)
        failed |= any(r.get("error") for r in rows)
    else:
        _log(header)
    print(("# " if args.markdown else "") + header + "\n")
    print("\n\n".join(texts))
    if args.json:
        out["finished"] = time.strftime("%Y-%m-%dT%H:%M:%S%z")
        path = Path(args.json)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(out, indent=1, default=_jsonable, allow_nan=True))
        _log(f"ipsph bench: raw results in {path}")
    return 1 if failed else 0


def _jsonable(o):
    if isinstance(o, Path):
        return str(o)
    if isinstance(o, float) and math.isnan(o):
        return None
    return str(o)
