"""Command line: `ipsph run | render | surface | gauge | plot | paraview | sweep | bench` (also `python -m ipsph`).

User errors print one line on stderr and exit 2; numerical failures exit 3; interrupts 130.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from ._version import __version__
from .errors import EXIT_INPUT, EXIT_INTERRUPTED, IpsphError
from .params import BACKEND_NAMES, METHOD_NAMES, PRECISIONS, RENDER_MODES, RENDER_VIEWS

# OpenMP threads that finish a parallel loop sleep instead of spinning (unless the user chose):
# between the solver's ~20 parallel loops per step the other core is then free for the render
# process; the Python API and the benchmark's workers keep the default (the trade-off measured:
# docs/performance.md, "Measured design choices").
OMP_POLICY = ("OMP_WAIT_POLICY", "passive")


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="ipsph",
        description="Incompressible Projective SPH: meshes in, particles, VTU/PVD time series and renders out.",
    )
    p.add_argument("--version", action="version", version=f"ipsph {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    from .scene.reference import key_help

    r = sub.add_parser(
        "run",
        help="run a scene (TOML, or a SPlisHSPlasH JSON scene) into an output folder",
        description="Run a scene. Without SCENE, runs the built-in default dam break.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="scene keys for --set KEY=VALUE (docs/scene-reference.md):\n" + key_help(),
    )
    r.add_argument("scene", nargs="?", type=Path, help="scene file (.toml, or SPlisHSPlasH .json)")
    r.add_argument("-o", "--output", type=Path, help="output folder (default: the scene's output.folder)")
    r.add_argument("--method", choices=METHOD_NAMES, help="override simulation.method")
    r.add_argument("--end-time", type=float, metavar="T", help="override simulation.end_time [s]")
    r.add_argument("--backend", choices=BACKEND_NAMES, help="override simulation.backend (cuda: an NVIDIA GPU)")
    r.add_argument("--precision", choices=PRECISIONS, help="override simulation.precision")
    r.add_argument("--device", type=int, metavar="N", help="override simulation.device: the GPU to run on")
    g = r.add_mutually_exclusive_group()
    g.add_argument("--fps", type=float, metavar="F", help="frames per simulated second (default 25)")
    g.add_argument("--every-step", action="store_true", help="write a frame after every step")
    r.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override any scene parameter, e.g. --set solver.pf.stiffness=25000 (repeatable)",
    )
    r.add_argument("--no-render", action="store_true", help="skip the PNG renders")
    r.add_argument(
        "--surface",
        action="store_true",
        help="also write the fluid's surface mesh per frame, surfaces/*.vtp (sets output.surface)",
    )
    r.add_argument("--threads", type=int, metavar="N", help="worker threads (default: all cores)")
    r.add_argument("--overwrite", action="store_true", help="replace an earlier run in the output folder")
    r.add_argument("--resume", action="store_true", help="continue the run in the output folder from its checkpoint")
    r.add_argument(
        "--max-particles",
        type=int,
        metavar="N",
        help="refuse scenes estimated above N fluid particles (default: from available memory)",
    )
    r.add_argument("--quiet", action="store_true", help="no progress line")
    r.add_argument(
        "--yes", action="store_true", help="run a scene estimated to take over an hour even when not on a terminal"
    )

    rd = sub.add_parser("render", help="render PNGs (and a video) of a finished or running output folder")
    rd.add_argument("out", type=Path, help="output folder of `ipsph run`")
    rd.add_argument("--video", choices=("mp4", "gif"), nargs="?", const="mp4", help="also write a video")
    rd.add_argument("--fps", type=float, help="video frames per second (default: the run's)")
    rd.add_argument(
        "--speed-range",
        type=float,
        nargs=2,
        metavar=("LO", "HI"),
        help="colour range in m/s (default: the range the run rendered with, else the run's maximum speed)",
    )
    rd.add_argument(
        "--view", choices=tuple(RENDER_VIEWS), help="named camera view (replaces a camera stored in the run's scene)"
    )
    rd.add_argument("--size", type=int, nargs=2, metavar=("W", "H"), help="image size in pixels")
    rd.add_argument(
        "--mode",
        choices=RENDER_MODES,
        help="draw the particles or the surface meshes (reconstructed first where missing); "
        "default: the run's render.mode",
    )

    sf = sub.add_parser(
        "surface",
        help="surface meshes of a finished or running output folder (skips those written)",
        description="Reconstruct the fluid's surface for every frame of OUT that has none yet, "
        "with the run's [surface] settings; .vtp surfaces are listed in run.pvd.",
    )
    sf.add_argument("out", type=Path, help="output folder of `ipsph run`")
    sf.add_argument(
        "--format",
        choices=("vtp", "obj", "ply"),
        default="vtp",
        help="vtp (ParaView; default), obj or ply (Houdini, Blender: ply keeps normals, velocity, speed)",
    )
    sf.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="surface.KEY=VALUE",
        help="change a [surface] setting, e.g. --set surface.cube_size=0.5 (repeatable)",
    )
    sf.add_argument("--threads", type=int, metavar="N", help="reconstruction threads (default: all cores)")

    ga = sub.add_parser(
        "gauge",
        help="measure gauges on the frames of a finished or running output folder (docs/gauges.md)",
        description="Measure [[gauge]] tables (pressure, velocity, density at a point; water level; force on a "
        "wall or body; flux through a rectangle) on every frame of OUT, with the run's scene from run.json. "
        "At frame times the values agree with the run's own gauges.csv.",
    )
    ga.add_argument("out", type=Path, help="output folder of `ipsph run`")
    ga.add_argument(
        "--scene",
        type=Path,
        metavar="FILE",
        help="TOML file whose [[gauge]] tables to measure (its other tables are ignored); default: the run's gauges",
    )
    ga.add_argument("-o", "--output", type=Path, metavar="CSV", help="CSV to write (default: OUT/gauges_frames.csv)")

    pl = sub.add_parser("plot", help="plot density/divergence error, iterations and timings of one or more runs")
    pl.add_argument("out", type=Path, nargs="+", help="output folders (several are overlaid)")
    pl.add_argument("-o", "--output", type=Path, help="folder for the PNGs (default: the first run's plots/)")

    sw = sub.add_parser("sweep", help="run a sweep of scene variations on a Dask cluster (docs/sweeps.md)")
    from .sweeps.cli import add_arguments as sweep_arguments

    sweep_arguments(sw)
    pv = sub.add_parser(
        "paraview",
        help="write OUT/paraview_view.py: opens the run in ParaView as it was rendered",
        description="Write OUT/paraview_view.py, a ParaView Python script that opens the run "
        "with its settings and a ready SPH line interpolator (ipsph run writes it too).",
    )
    pv.add_argument("out", type=Path, help="output folder of `ipsph run`")

    b = sub.add_parser("bench", help="benchmark the methods (and SPlisHSPlasH, when installed)")
    from .bench.cli import add_arguments

    add_arguments(b)
    return p


def _run(args) -> int:
    os.environ.setdefault(*OMP_POLICY)  # before numba loads its OpenMP layer
    from .run import runner
    from .scene import default_scene_path, load_scene

    overrides = list(args.set)
    if args.method:
        overrides.append(f"simulation.method={args.method}")
    if args.end_time is not None:
        overrides.append(f"simulation.end_time={args.end_time}")
    for key in ("backend", "precision", "device"):
        if getattr(args, key) is not None:
            overrides.append(f"simulation.{key}={getattr(args, key)}")
    if args.fps is not None:
        overrides.append(f"output.fps={args.fps}")
    if args.every_step:
        overrides.append("output.every_step=true")
    if args.surface:
        overrides.append("output.surface=true")
    scene = load_scene(args.scene if args.scene is not None else default_scene_path(), overrides)
    out = args.output if args.output is not None else scene.output.folder
    try:  # the summary's total counts from the process start: interpreter, imports, scene loading
        import time

        import psutil

        started = time.perf_counter() - max(time.time() - psutil.Process().create_time(), 0.0)
    except Exception:  # pragma: no cover - psutil is a dependency
        started = None
    opts = runner.RunOptions(
        out_dir=out,
        render=not args.no_render,
        overwrite=args.overwrite,
        resume=args.resume,
        threads=args.threads,
        max_particles=args.max_particles,
        progress=False if args.quiet else None,
        yes=args.yes,
        started=started,
    )
    return runner.run(scene, opts)


def _render(args) -> int:
    from .errors import InputError
    from .io import RUN_PVD
    from .post.render import gl_available, render_output

    if not (args.out / RUN_PVD).exists():
        raise InputError(
            f"{args.out} (resolved {args.out.resolve()}) holds no run.pvd: give the output folder of `ipsph run`"
        )
    ok, why = gl_available()
    if not ok:
        print(f"ipsph: error: cannot render: {why}", file=sys.stderr)
        return 1
    over = {}
    if args.view:
        over.update(view=args.view, camera_position=None, focal_point=None, view_up=None)
    if args.size:
        over["width"], over["height"] = args.size
    paths = render_output(
        args.out,
        speed_range=tuple(args.speed_range) if args.speed_range else None,
        config_overrides=over or None,
        video=args.video,
        fps=args.fps,
        mode=args.mode,
    )
    print(f"ipsph: wrote {len(paths)} files under {args.out}", file=sys.stderr)
    return 0


def _surface(args) -> int:
    from .post.surface import surface_output

    res = surface_output(args.out, fmt=args.format, overrides=args.set, threads=args.threads)
    print(
        f"ipsph: wrote {len(res['written'])} {args.format} surfaces under {args.out / 'surfaces'} "
        f"({res['skipped']} already there"
        + (
            f", {len(res['failed'])} frames without a surface: {', '.join(str(i) for i in sorted(res['failed']))}"
            if res["failed"]
            else ""
        )
        + ")",
        file=sys.stderr,
    )
    return 0


def _gauge(args) -> int:
    from .gauges.replay import main as gauge_main

    return gauge_main(args.out, args.scene, args.output)


def _plot(args) -> int:
    from .post.plots import plot_runs
    from .sweeps.records import plot_folders

    dirs, target = plot_folders(list(args.out), args.output)  # a sweep folder stands for its members
    for p in plot_runs(dirs, target):
        print(p)
    return 0


def _sweep(args) -> int:
    from .sweeps.cli import main as sweep_main

    return sweep_main(args)


def _paraview(args) -> int:
    from .post.paraview import write_view_script

    path = write_view_script(args.out)
    print(
        f"ipsph: wrote {path}; open it with `pvpython {path}` (headless: `xvfb-run -a pvpython {path} "
        f"--screenshot view.png`) or ParaView's View > Python Shell > Run Script",
        file=sys.stderr,
    )
    return 0


def _bench(args) -> int:
    from .bench.cli import main as bench_main

    return bench_main(args)


_COMMANDS = {
    "run": _run,
    "render": _render,
    "surface": _surface,
    "gauge": _gauge,
    "plot": _plot,
    "sweep": _sweep,
    "paraview": _paraview,
    "bench": _bench,
}


def main(argv: list[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return EXIT_INPUT
    try:
        return _COMMANDS[args.command](args)
    except IpsphError as exc:
        print(f"ipsph: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("\nipsph: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    return EXIT_INPUT


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
