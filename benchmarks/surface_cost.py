"""What surfaces cost.

    python -m benchmarks surface-sizes 1000000 --repeats 3   # seconds per reconstruction of a jittered N lattice
    python -m benchmarks surface-overhead --repeats 5        # the default scene's `ipsph run`, with and without --surface

Per frame: a cubic lattice of N particles at r = 0.01 m, jittered by up to r/4 per axis (seeded), with a
shear velocity field interpolated onto the vertices, reconstructed by `ipsph.post.surface.reconstruct` with
the default [surface] settings (or --set surface.KEY=VALUE) on --threads threads, in a fresh process
(splashsurf's thread pool is sized once per process); median of --repeats, with the other processes'
load on the machine while it ran.

Overhead: `ipsph run` of the built-in default scene in fresh processes, alternating the plain run and
the run with --surface (the surface process beside the solver), both with their usual renders, R times
each; medians of wall time and their ratio, the figure the target "surfaces add at most 25 %" is about.
A pair during which other processes kept more than --max-load cores busy is shown as loaded and left
out of the medians.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

from ipsph.io import SURFACES_DIR

from . import overhead

SECONDS_TARGET = 10.0  # a 1M-particle frame in at most 10 s on 2 cores

_ONE = r"""
import json, resource, sys, time
import numpy as np
from ipsph.post.surface import reconstruct
from ipsph.params import spacing
from ipsph.scene import surface_config
n, overrides = int(sys.argv[1]), json.loads(sys.argv[2])
r = 0.01
side = max(int(round(n ** (1 / 3))), 2)
g = (np.arange(side) + 1.0) * spacing(r)
x = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
x += np.random.default_rng(20).uniform(-0.25 * r, 0.25 * r, x.shape)
v = np.zeros_like(x)
v[:, 0] = 3.0 * x[:, 1] / (side * spacing(r))
cfg = surface_config({}, overrides)
cpu = lambda: sum(resource.getrusage(resource.RUSAGE_SELF)[:2])
t0, c0 = time.perf_counter(), cpu()
s = reconstruct(x, v, r, 1000.0, cfg)
print(json.dumps({"particles": len(x), "seconds": time.perf_counter() - t0, "cpu_seconds": cpu() - c0,
                  "triangles": len(s.triangles),
                  "vertices": len(s.vertices), "config": cfg.__dict__}))
"""


def surface_seconds(n: int, threads: int, repeats: int, overrides=(), timeout: float = 900.0, log=print) -> dict:
    """Median seconds of `repeats` reconstructions of a jittered ~n lattice, each in a fresh process."""
    from ipsph.bench.machine import LoadSampler

    root = str(Path(__file__).resolve().parents[1])  # the clone: the child imports this ipsph
    env = dict(
        os.environ,
        RAYON_NUM_THREADS=str(threads),
        PYTHONPATH=os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH", "")) if p),
    )
    runs = []
    for k in range(repeats):
        sampler = LoadSampler(0.5).start()
        try:
            proc = subprocess.run(
                [sys.executable, "-c", _ONE, str(n), json.dumps(list(overrides))],
                env=env,
                capture_output=True,
                text=True,
                timeout=timeout,
            )
        except subprocess.TimeoutExpired:
            sampler.stop()
            runs.append({"error": f"timed out after {timeout} s"})
            continue
        load = sampler.stop()
        if proc.returncode != 0:
            runs.append({"error": (proc.stderr or "").strip().splitlines()[-1:] or [f"exit {proc.returncode}"]})
            continue
        row = json.loads(proc.stdout.strip().splitlines()[-1])
        row["others_cores"] = load.others_busy_mean * load.cpus
        row["loadavg"] = os.getloadavg()[0]
        runs.append(row)
        log(
            f"surface of {row['particles']:,} particles {k + 1}/{repeats}: {row['seconds']:.2f} s on {threads} "
            f"threads ({row['cpu_seconds']:.2f} CPU s), {row['triangles']:,} triangles, others "
            f"{row['others_cores']:.2f} cores"
        )
    good = [r for r in runs if "seconds" in r]
    return {
        "target": n,
        "threads": threads,
        "runs": runs,
        "particles": good[0]["particles"] if good else None,
        "triangles": good[0]["triangles"] if good else None,
        "seconds_median": statistics.median(r["seconds"] for r in good) if good else float("nan"),
        "cpu_seconds_median": statistics.median(r["cpu_seconds"] for r in good) if good else float("nan"),
        "others_cores_median": statistics.median(r["others_cores"] for r in good) if good else float("nan"),
    }


def sizes_table(rows: list[dict], markdown: bool) -> str:
    head = ["particles", "threads", "s / frame (median)", "CPU s / frame", "triangles", "others' cores", "1M target"]
    lines = (
        ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        if markdown
        else ["  ".join(f"{h:>18s}" for h in head)]
    )
    for r in rows:
        ok = ""
        if r["particles"] and r["particles"] >= 900_000:
            ok = "met" if r["seconds_median"] <= SECONDS_TARGET else "NOT met"
            ok = f"<= {SECONDS_TARGET:.0f} s: {ok}"
        cells = [
            f"{r['particles'] or r['target']:,}",
            str(r["threads"]),
            f"{r['seconds_median']:.2f}",
            f"{r['cpu_seconds_median']:.2f}",
            f"{r['triangles'] or 0:,}",
            f"{r['others_cores_median']:.2f}",
            ok,
        ]
        lines.append(("| " + " | ".join(cells) + " |") if markdown else "  ".join(f"{c:>18s}" for c in cells))
    return "\n".join(lines)


def _surfaces(out: Path) -> int:
    return len(list((out / SURFACES_DIR).glob("*.vtp"))) if (out / SURFACES_DIR).is_dir() else 0


def _one_run(surface: bool, threads: int, tmp: Path, k: int, timeout: float) -> dict:
    out = tmp / f"out-{'surface' if surface else 'plain'}-{k}"
    row = overhead.default_run(
        ["--surface"] if surface else [],
        out,
        threads,
        timeout,
        lambda r, o: _surfaces(o) == r["frames"] if surface else True,
    )
    return {"surface": surface, "surfaces": _surfaces(out), **row}


def surface_overhead(repeats: int, threads: int, max_load: float, timeout: float = 900.0, log=print) -> dict:
    """`ipsph run` (default scene) without and with --surface, alternating, `repeats` pairs."""
    return overhead.alternating_pairs(
        lambda on, tmp, k: _one_run(on, threads, tmp, k, timeout),
        "surface",
        repeats,
        max_load,
        lambda r: f"surfaces, {r['surfaces']}/{r['frames']}",
        log,
    )


def overhead_table(s: dict, markdown: bool) -> str:
    return overhead.table(s, "surface", "without surfaces", "with --surface", markdown)
