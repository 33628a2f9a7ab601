"""python -m benchmarks STUDY [options]: one of our studies (see benchmarks/__init__.py).

python -m benchmarks table1 [--pipelines ...] [--dragon-mesh OBJ]
python -m benchmarks figure4 OUT --end-time 1.5
python -m benchmarks render-sizes 100000 1000000
python -m benchmarks render-overhead --repeats 5
python -m benchmarks surface-sizes 1000000 --repeats 3
python -m benchmarks surface-overhead --repeats 5
python -m benchmarks gauge-overhead --repeats 5
python -m benchmarks sweep
python -m benchmarks moving-walls --repeats 5
python -m benchmarks baseline ../base --methods ipsph --end-time 0.3
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ipsph.bench.cli import add_arguments, check_args, finish
from ipsph.bench.machine import machine_info
from ipsph.bench.runs import log, use_peer
from ipsph.bench.scenes import PIPELINES
from ipsph.errors import IpsphError

STUDIES = (
    "table1",
    "figure4",
    "render-sizes",
    "render-overhead",
    "surface-sizes",
    "surface-overhead",
    "gauge-overhead",
    "sweep",
    "moving-walls",
    "baseline",
)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m benchmarks")
    add_arguments(p)
    p.description, p.epilog = __doc__.splitlines()[0], None
    p.add_argument("study", choices=STUDIES, help="which study")
    p.add_argument(
        "values",
        nargs="*",
        help="figure4: the output folder; render-sizes, surface-sizes: the particle counts; "
        "baseline: the other ipsph source tree",
    )
    p.add_argument("--pipelines", nargs="+", choices=sorted(PIPELINES), default=None, help="table1: which pipelines")
    p.add_argument(
        "--dragon-mesh",
        type=Path,
        metavar="OBJ",
        help="table1: SPlisHSPlasH's Dragon_50k.obj for both dragons of two_dragons.toml",
    )
    return p


def run(args) -> int:
    title = (lambda t: f"## {t}\n\n") if args.markdown else (lambda t: f"== {t.lower()} ==\n")
    out: dict = {"machine": machine_info(), "threads": args.threads, "study": args.study}
    header = f"benchmarks {args.study}: {out['machine']['cpu_model']}; {args.threads} threads"
    texts, failed = [], False
    check_args(args)
    if args.study == "figure4":
        from .figure4 import figure4, print_summary

        if len(args.values) != 1:
            raise SystemExit("figure4 takes one output folder")
        print_summary(figure4(Path(args.values[0]), args.end_time, args.threads, args.set))
        return 0
    if args.study == "table1":
        from .table1 import bench_table1

        peer, why = use_peer(args.peer)
        header += f"; {why}"
        log(header)
        text, rows = bench_table1(args, peer)
        out["table1"] = rows
        texts.append(title("Table 1") + text)
        failed |= any(r.get("error") for r in rows)
    elif args.study == "render-sizes":
        from .render_cost import render_cost, table

        rows = [render_cost(int(n)) for n in (args.values or [100_000, 1_000_000])]
        out["render_cost"] = rows
        texts.append(title("Render cost per frame") + table(rows, args.markdown))
    elif args.study == "render-overhead":
        from .render_cost import overhead_table, render_overhead

        s = render_overhead(args.repeats, args.threads, args.max_load, timeout=min(args.timeout, 900.0), log=log)
        out["render_overhead"] = s
        texts.append(title("Render overhead (default scene)") + overhead_table(s, args.markdown))
        failed |= not s["ok"]
    elif args.study == "surface-sizes":
        from .surface_cost import sizes_table, surface_seconds

        over = [o for o in args.set if o.startswith("surface.")]
        timeout = min(args.timeout, 900.0)
        rows = [
            surface_seconds(int(n), args.threads, args.repeats, over, timeout=timeout, log=log)
            for n in (args.values or [1_000_000])
        ]
        out["surface_sizes"] = rows
        texts.append(title("Surface reconstruction per frame") + sizes_table(rows, args.markdown))
        failed |= any(r["particles"] is None for r in rows)
    elif args.study == "surface-overhead":  # the default scene's run without and with the surface process
        from .surface_cost import overhead_table, surface_overhead

        s = surface_overhead(args.repeats, args.threads, args.max_load, timeout=min(args.timeout, 900.0), log=log)
        out["surface_overhead"] = s
        texts.append(title("Surface overhead (default scene)") + overhead_table(s, args.markdown))
        failed |= not s["ok"]
    elif args.study == "gauge-overhead":  # the default scene's run without and with ten every-step gauges
        from .gauge_cost import gauge_overhead, overhead_table

        s = gauge_overhead(args.repeats, args.threads, args.max_load, timeout=min(args.timeout, 900.0), log=log)
        out["gauge_overhead"] = s
        texts.append(title("Gauge overhead (default scene)") + overhead_table(s, args.markdown))
        failed |= not s["ok"]
    elif args.study == "baseline":
        from .baseline import bench_baseline

        if len(args.values) != 1:
            raise SystemExit("baseline takes one source tree (e.g. `git worktree add ../base main`)")
        log(header)
        text, rows = bench_baseline(Path(args.values[0]), args)
        out["runs"] = rows
        texts.append(text)
        failed |= any(r.get("error") for r in rows)
    elif args.study == "sweep":
        from .sweep_bench import bench_sweep, table

        result = bench_sweep(args.end_time, args.repeats, args.max_load, min(args.timeout, 900.0), log)
        out["sweep"] = result
        texts.append(title("Sweep on a LocalCluster") + table(result, args.markdown, args.max_load))
    else:
        from .moving_cost import moving_cost, table

        rows = moving_cost(repeats=args.repeats, threads=args.threads, log=log)
        out["moving_walls"] = rows
        texts.append(title("Moving walls and bodies per step") + table(rows, args.markdown))
    return finish(args, out, header, texts, failed)


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    try:
        return run(args)
    except IpsphError as exc:
        print(f"benchmarks: error: {exc}", file=sys.stderr)
        return exc.exit_code


if __name__ == "__main__":
    sys.exit(main())
