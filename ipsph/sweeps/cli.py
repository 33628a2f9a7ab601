"""`ipsph sweep SWEEP.toml -o OUT`: the command line of ipsph.sweeps."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.description = (
        "Run every member of a sweep file (a base scene, [set], [grid], [zip]) as `ipsph run` on a "
        "Dask cluster: a LocalCluster on this machine's loopback interface, or --scheduler ADDRESS. "
        "Each member writes OUT/<member>/; OUT/sweep.json and OUT/summary.csv record them. "
        "Exit 0: all completed; 1: some member failed; 2: bad input; 130: interrupted."
    )
    p.add_argument("sweep", type=Path, help="sweep file (.toml; docs/sweeps.md)")
    p.add_argument("-o", "--output", type=Path, required=True, help="output folder of the sweep")
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="join this Dask scheduler (tcp://host:8786, tls://...: TLS from Dask's configuration) "
        "instead of starting a LocalCluster",
    )
    p.add_argument("--workers", type=int, metavar="N", help="LocalCluster workers (default: cores / threads)")
    p.add_argument(
        "--threads-per-worker",
        type=int,
        metavar="T",
        help="LocalCluster threads per worker, which is each member's Numba thread count (default 1, "
        "or cores / --workers)",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="one more fixed override for every member (as [set]; repeatable)",
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="run only the members not completed (from their checkpoints where they have one)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace an earlier sweep in the output folder")
    p.add_argument("--no-render", action="store_true", help="members skip their PNG renders")
    p.add_argument("--max-particles", type=int, metavar="N", help="refuse members estimated above N fluid particles")
    p.add_argument(
        "--dashboard-address",
        default="127.0.0.1:8787",
        metavar="HOST:PORT",
        help="LocalCluster dashboard (default 127.0.0.1:8787; another free port if taken)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress lines")


def main(args) -> int:
    from .engine import SweepOptions, run_sweep

    opts = SweepOptions(
        out=args.output,
        scheduler=args.scheduler,
        workers=args.workers,
        threads_per_worker=args.threads_per_worker,
        resume=args.resume,
        overwrite=args.overwrite,
        render=not args.no_render,
        max_particles=args.max_particles,
        progress=not args.quiet,
        dashboard_address=args.dashboard_address,
        extra_set=list(args.set),
    )
    code, _ = run_sweep(args.sweep, opts)
    return code
