"""`python -m benchmarks sweep`: 4 members on a 2-worker x 1-thread LocalCluster against the same 4 run one after
another with 2 threads each (issue 21).

The members are the default dam break (3,724 fluid particles at r = 0.02, no renders) with
simulation.method in (ipsph, dfsph) x simulation.viscosity in (0.01, 0.02), --end-time simulated seconds.
Per repeat (sweep first, then the sequential runs, so machine noise falls on both):

    sweep wall          `ipsph.sweeps.run_sweep` from call to return: validation, cluster start,
                        shared-folder check, the members, cluster close
    sequential wall     the 4 `ipsph run --threads 2` one after another (each a fresh process, like a member)
    ratio               sequential / sweep (> 1: the sweep is faster)
    overhead / member   (sweep wall - makespan) / 4, where makespan is the busier worker's sum of its
                        members' child-process walls: what the scheduler, the cluster and the bookkeeping
                        cost on top of running the same processes back to back on each worker
    dispatch / member   (members phase - makespan) / 4: the same without cluster start and close

Figures are medians over the repeats; a repeat during which other processes used more than --max-load
cores is flagged (this machine is shared).
"""

from __future__ import annotations

import shutil
import statistics
import tempfile
import time
from pathlib import Path

SWEEP_TOML = """\
# python -m benchmarks sweep: 4 members of the default dam break
scene = "{scene}"
[set]
"simulation.end_time" = {end}
"render.enabled" = false
[grid]
"simulation.method" = ["ipsph", "dfsph"]
"simulation.viscosity" = [0.01, 0.02]
"""


def bench_sweep(end_time: float, repeats: int, max_load: float, timeout: float, log) -> dict:
    from ipsph.bench.machine import LoadSampler, timed_ipsph_run
    from ipsph.scene import default_scene_path
    from ipsph.sweeps import engine, records, spec

    rows = []
    with tempfile.TemporaryDirectory(prefix="ipsph-bench-sweep-") as tmp:
        tmp = Path(tmp)
        f = tmp / "sweep.toml"
        f.write_text(SWEEP_TOML.format(scene=default_scene_path(), end=end_time))
        members = spec.load_sweep(f).members
        for rep in range(repeats):
            out = tmp / f"sweep-{rep}"
            sampler = LoadSampler(0.5).start()
            t0 = time.perf_counter()
            code, recs = engine.run_sweep(
                f,
                engine.SweepOptions(
                    out=out, workers=2, threads_per_worker=1, progress=False, dashboard_address="127.0.0.1:0"
                ),
            )
            wall = time.perf_counter() - t0
            load = sampler.stop()
            if code != 0:
                raise RuntimeError(f"python -m benchmarks sweep: the sweep failed: {[r.get('reason') for r in recs]}")
            timings = records.read_sweep_json(out)["timings_s"]
            per_worker: dict[int, float] = {}
            for r in recs:
                per_worker[r["worker_pid"]] = per_worker.get(r["worker_pid"], 0.0) + r["wall_seconds"]
            makespan = max(per_worker.values())
            row = {
                "repeat": rep,
                "sweep_wall": wall,
                "makespan": makespan,
                "timings": timings,
                "member_walls": {r["name"]: r["wall_seconds"] for r in recs},
                "member_loops": {r["name"]: r["run_wall_seconds"] for r in recs},
                "workers_used": len(per_worker),
                "sweep_others_cores": load.others_busy_mean * load.cpus,
            }
            log(
                f"[{rep + 1}/{repeats}] sweep 2 x 1 thread: {wall:.1f} s (cluster start {timings['cluster_start']:.1f} s, "
                f"members {timings['members']:.1f} s, makespan {makespan:.1f} s), others "
                f"{row['sweep_others_cores']:.2f} cores"
            )
            shutil.rmtree(out, ignore_errors=True)
            seq, seq_load = 0.0, []
            for m in members:
                args = [str(default_scene_path()), "--no-render"] + [a for s in m.set_args() for a in ("--set", s)]
                r = timed_ipsph_run(args, tmp / f"seq-{rep}-{m.name}", 2, timeout)
                if r["exit_code"] != 0:
                    raise RuntimeError(f"python -m benchmarks sweep: ipsph run failed: {r['stderr_tail']}")
                seq += r["seconds"]
                seq_load.append(r["load"].others_busy_mean * r["load"].cpus)
                shutil.rmtree(tmp / f"seq-{rep}-{m.name}", ignore_errors=True)
            row.update(sequential_wall=seq, sequential_others_cores=statistics.mean(seq_load))
            row["ratio"] = seq / wall
            row["overhead_per_member"] = (wall - makespan) / len(members)
            row["dispatch_per_member"] = (timings["members"] - makespan) / len(members)
            row["loaded"] = max(row["sweep_others_cores"], row["sequential_others_cores"]) > max_load
            log(
                f"[{rep + 1}/{repeats}] 4 x ipsph run --threads 2 one after another: {seq:.1f} s, others "
                f"{row['sequential_others_cores']:.2f} cores; ratio {row['ratio']:.2f}"
                + (" LOADED" if row["loaded"] else "")
            )
            rows.append(row)
    return {"end_time": end_time, "members": [m.name for m in members], "rows": rows}


def table(result: dict, markdown: bool, max_load: float) -> str:
    rows = result["rows"]
    clean = [r for r in rows if not r["loaded"]] or rows
    med = lambda k: statistics.median(r[k] for r in clean)  # noqa: E731
    medt = lambda k: statistics.median(r["timings"][k] for r in clean)  # noqa: E731
    figures = [
        ("sweep wall, 2 workers x 1 thread [s]", f"{med('sweep_wall'):.1f}"),
        ("  cluster start [s]", f"{medt('cluster_start'):.2f}"),
        ("  members phase [s]", f"{medt('members'):.1f}"),
        ("  busier worker's member processes (makespan) [s]", f"{med('makespan'):.1f}"),
        ("  cluster close [s]", f"{medt('close'):.2f}"),
        ("sequential wall, 4 x 2 threads [s]", f"{med('sequential_wall'):.1f}"),
        ("ratio sequential / sweep", f"{med('ratio'):.2f}"),
        ("overhead per member, all in [s]", f"{med('overhead_per_member'):.2f}"),
        ("dispatch overhead per member (no cluster start/close) [s]", f"{med('dispatch_per_member'):.2f}"),
        (
            "repeats counted / run",
            f"{sum(not r['loaded'] for r in rows)} / {len(rows)}"
            + ("" if any(not r["loaded"] for r in rows) else " (all loaded: medians over all)"),
        ),
        (
            "others' load (sweep / sequential) [cores]",
            f"{statistics.median(r['sweep_others_cores'] for r in rows):.2f}"
            f" / {statistics.median(r['sequential_others_cores'] for r in rows):.2f}",
        ),
    ]
    head = (
        f"4 members (default dam break, {' '.join(result['members'])}), {result['end_time']} simulated s "
        f"each, no renders; medians; loaded = others used > {max_load} cores"
    )
    if markdown:
        return head + "\n\n| figure | value |\n|---|---|\n" + "\n".join(f"| {a.strip()} | {b} |" for a, b in figures)
    w = max(len(a) for a, _ in figures)
    return head + "\n" + "\n".join(f"{a:<{w}}  {b}" for a, b in figures)
