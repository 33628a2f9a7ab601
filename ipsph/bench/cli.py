"""`ipsph bench`: our three methods against SPlisHSPlasH (when installed), interleaved, on a shared machine.

    ipsph bench                                  # DamBreakModel + DoubleDamBreak, ipsph pf dfsph + peer, 3 repeats
    ipsph bench --methods ipsph dfsph --repeats 5 --end-time 1.0 --markdown --json bench.json
    ipsph bench --scaling 10000 100000 1000000    # ms/step, us per particle-step, bytes per particle
    ipsph bench --scaling 1000000 --backend cuda  # the same on a GPU, beside the CPU up to --cpu-max-particles
    ipsph bench --first-frame                    # seconds to the first frame, cold and warm Numba cache
    ipsph bench --buoyancy --methods ipsph       # floating cubes against Archimedes (method.md section 9)

Every simulation runs in its own worker process (peak RSS per method) with the same thread count
(NUMBA_NUM_THREADS for ours, OMP_NUM_THREADS for SPlisHSPlasH), in the order
``for repeat: for scene: for method`` so machine noise spreads over all methods alike. A run during
which other processes used more than ``--max-load`` cores is shown as loaded and left out of the medians.

The modes live beside this file: runs.py (the interleaved comparison), scaling.py, first_frame.py,
buoyancy.py. Studies of our own (the paper's Table 1 and Figure 4, what renders, surfaces, sweeps
and moving walls cost, another build against this one) are in the repository's benchmarks/ folder
(`python -m benchmarks --help`); they take these options too.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from pathlib import Path

from ..errors import ConfigError
from ..params import BACKEND_NAMES, BOUNDARY_MODELS, PRECISIONS
from . import report
from .first_frame import FIRST_FRAME_TARGET_S, first_frame, first_frame_table
from .runs import OUR_METHODS, bench_scenes, log, use_peer
from .scaling import bench_scaling, scaling_table
from .scenes import DEFAULT_SCENES


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.description = (
        "Benchmark our methods (and SPlisHSPlasH's DFSPH and PF, when pysplishsplash is installed) "
        "on the stock SPlisHSPlasH scenes, interleaved, one process per run."
    )
    p.epilog = (
        "Our own studies (the paper's Table 1 and Figure 4, what renders, surfaces, sweeps and moving walls "
        "cost, another build against this one) run from a clone: python -m benchmarks --help."
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
    _number(p, "--end-time", 1.0, "T", "simulated seconds per run (default 1.0)")
    _number(p, "--repeats", 3, "R", "interleaved repeats (default 3)")
    _number(p, "--threads", 2, "N", "threads for every method (default 2)")
    _number(
        p, "--max-load", 0.5, "CORES",
        "flag a run as loaded when other processes used more than this many cores on average "
        "(i.e. mean load > threads + CORES); loaded runs are printed, not counted (default 0.5)",
    )  # fmt: skip
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
    _number(p, "--device", 0, "N", "with --backend cuda: the GPU")
    _number(
        p, "--cpu-max-particles", 200_000, "N",
        "with --backend cuda: also run the CPU backend at the sizes up to N fluid particles (default 200000; 0: none)",
    )  # fmt: skip
    _number(p, "--scaling-steps", 10, "S", "timed steps per size, after 2 warm-up steps (default 10)")
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
    _number(p, "--timeout", 1800.0, "S", "per-run timeout (default 1800 s)")


def _number(p: argparse.ArgumentParser, flag: str, default: int | float, metavar: str, help: str) -> None:
    """Add an option that takes one number, parsed as its default's type (int or float)."""
    p.add_argument(flag, type=type(default), default=default, metavar=metavar, help=help)


def check_args(args) -> None:
    """The options' values (exit 2 on a bad one), before anything runs."""
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
        log(f"ipsph bench: warning: --threads {args.threads} is more than the {cpus} logical cores")


def reprint(path: Path, markdown: bool, max_load: float) -> str:
    """The tables of a saved --json file, with this call's --markdown and --max-load."""
    try:
        saved = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ConfigError(f"--from-json {path} (resolved {Path(path).resolve()}): cannot read it: {exc}") from exc
    h = lambda t: f"## {t}\n\n" if markdown else f"== {t} ==\n"  # noqa: E731
    texts = []
    if saved.get("first_frame"):
        texts.append(h("time to first frame") + first_frame_table(saved["first_frame"], markdown, FIRST_FRAME_TARGET_S))
    if saved.get("scaling"):
        texts.append(h("scaling (dam break)") + scaling_table(saved["scaling"], markdown, max_load))
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
    check_args(args)
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
    title = (lambda t: f"## {t}\n\n") if args.markdown else (lambda t: f"== {t.lower()} ==\n")
    texts: list[str] = []
    failed = False
    if args.first_frame:
        rows = first_frame(args.threads, timeout=min(args.timeout, 900.0), repeats=args.repeats)
        out["first_frame"] = rows
        texts.append(title("Time to first frame") + first_frame_table(rows, args.markdown, FIRST_FRAME_TARGET_S))
        failed |= not all(r["ok"] for r in rows)
    if args.scaling is not None:
        peer, why = use_peer(args.peer)
        header += f"; scaling: {why}"
        text, rows = bench_scaling(args, peer)
        out["scaling"] = rows
        texts.append(title("Scaling (dam break)") + text)
        failed |= any(r.get("error") for r in rows)
    if not (args.first_frame or args.scaling is not None):
        peer, why = use_peer(args.peer)
        header += f"; {why}"
        log(header)
        text, rows = bench_scenes(args, peer)
        out["runs"] = rows
        texts.append(text)
        failed |= any(r.get("error") for r in rows)
    else:
        log(header)
    return finish(args, out, header, texts, failed)


def finish(args, out: dict, header: str, texts: list[str], failed: bool) -> int:
    """Print the tables, save --json; exit 1 when a run failed or a target was missed."""
    print(("# " if args.markdown else "") + header + "\n")
    print("\n\n".join(texts))
    if args.json:
        out["finished"] = time.strftime("%Y-%m-%dT%H:%M:%S%z")
        path = Path(args.json)
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(out, indent=1, default=_jsonable, allow_nan=True))
        log(f"ipsph bench: raw results in {path}")
    return 1 if failed else 0


def _jsonable(o):
    if isinstance(o, Path):
        return str(o)
    if isinstance(o, float) and math.isnan(o):
        return None
    return str(o)
