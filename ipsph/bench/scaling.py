"""`ipsph bench --scaling N ...`: the dam break at growing sizes, ms per step, microseconds per
particle-step and bytes per particle (ours, and SPlisHSPlasH's DFSPH on the same dam breaks), on
the CPU or beside a GPU (`--backend cuda`); and its tables.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from ..errors import ConfigError
from . import report
from .report import PHASE_SHORT, fmt_int, fmt_num, format_table, is_loaded
from .runs import log
from .scenes import scaling_count, scaling_dt_max, scaling_overrides, scaling_peer_scene


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
            log("  FAILED: " + row["error"].splitlines()[0])
        else:
            log(
                f"  {row['elapsed_s']:.1f} s: {row['ms_step']:.1f} ms/step, "
                f"{row['us_particle_step']:.3f} us/particle-step, others {row['others_cores']:.2f} cores"
            )

    gpu = args.backend == "cuda"
    if gpu:
        from ..backends._cuda import SIMULATOR

        if SIMULATOR:
            log("scaling: NUMBA_ENABLE_CUDASIM=1: the cuda rows time numba-cuda's CPU simulator, not a GPU")
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
                    log(
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
                log(f"scaling: SPlisHSPlasH dfsph ~{scaling_count(n):,} fluid particles ...")
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
        return backend_scaling_table(rows, args.markdown, args.max_load), rows
    return scaling_table(rows, args.markdown, args.max_load), rows


SCALING_HEADERS = [
    "method",
    "fluid",
    "boundary",
    "timed steps",
    "ms/step (median)",
    "us / fluid particle-step",
    "iterations (pressure / divergence)",
    "density err mean %",
    "bytes / particle (RSS)",
    "bytes / particle (solver arrays)",
    "of which pair cache",
    "peak RSS MB",
    "setup s",
    "load (others' cores)",
]


def scaling_table(rows: list[dict], markdown: bool, max_load: float) -> str:
    body = []
    for r in rows:
        if r.get("error"):
            body.append(
                [r["label"], fmt_int(r.get("target")), "—", "—", "failed: " + r["error"].splitlines()[0]]
                + ["—"] * (len(SCALING_HEADERS) - 5)
            )
            continue
        label = r["label"] + (" [loaded]" if is_loaded(r, max_load) else "")
        body.append(
            [
                label,
                fmt_int(r.get("fluid")),
                fmt_int(r.get("boundary")),
                fmt_int(r.get("timed_steps")),
                fmt_num(r.get("ms_step")),
                fmt_num(r.get("us_particle_step"), "{:.3f}"),
                f"{fmt_num(r.get('iters_mean'), '{:.1f}')} / {fmt_num(r.get('div_iters_mean'), '{:.1f}')}",
                fmt_num(r.get("err_mean"), "{:.2g}"),
                fmt_num(r.get("bytes_rss"), "{:.0f}"),
                fmt_num(r.get("bytes_solver"), "{:.0f}"),
                fmt_num(r.get("bytes_pair_cache"), "{:.0f}"),
                fmt_num(r.get("rss_mb"), "{:.0f}"),
                fmt_num(r.get("setup_s"), "{:.1f}"),
                fmt_num(r.get("others_cores")),
            ]
        )
    return format_table(SCALING_HEADERS, body, markdown)


def backend_scaling_table(rows: list[dict], markdown: bool, max_load: float) -> str:
    """`ipsph bench --backend cuda --scaling ...`: each size on the GPU and (where it can) the CPU:
    ms per step and per phase, ns per fluid particle-step, bytes per fluid particle (the solver's
    arrays: device arrays for cuda; and what the device's free memory dropped by), wall seconds per
    simulated second, the density error."""
    phases = [p for p in PHASE_SHORT if any(p in (r.get("phases") or {}) for r in rows if not r.get("error"))]
    headers = (
        ["backend", "method", "fluid", "timed steps", "ms/step (median)"]
        + [f"ms {PHASE_SHORT[p]}" for p in phases]
        + [
            "ns / fluid particle-step",
            "bytes / particle (arrays)",
            "bytes / particle (device used)",
            "wall s / simulated s",
            "density err mean %",
            "load (others' cores)",
        ]
    )
    body = []
    for r in rows:
        where = f"{r.get('backend', '?')} {r.get('precision', '')}".strip()
        if r.get("error"):
            body.append(
                [where, r["label"], fmt_int(r.get("target")), "—", "failed: " + r["error"].splitlines()[0]]
                + ["—"] * (len(headers) - 5)
            )
            continue
        label = r["label"] + (" [loaded]" if is_loaded(r, max_load) else "")
        ph = r.get("phases") or {}
        body.append(
            [where, label, fmt_int(r.get("fluid")), fmt_int(r.get("timed_steps")), fmt_num(r.get("ms_step"))]
            + [fmt_num(ph.get(p)) for p in phases]
            + [
                fmt_num(r.get("ns_particle_step"), "{:.1f}"),
                fmt_num(r.get("bytes_solver"), "{:.0f}"),
                fmt_num(r.get("bytes_device_used"), "{:.0f}"),
                fmt_num(r.get("wall_per_sim"), "{:.1f}"),
                fmt_num(r.get("err_mean"), "{:.2g}"),
                fmt_num(r.get("others_cores")),
            ]
        )
    return format_table(headers, body, markdown)
