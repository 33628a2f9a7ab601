"""`ipsph sweep`: run a sweep's members on a Dask cluster, recording as they finish.

Order of business (nothing is started before the input is known to be good):
  1. read the sweep file and resolve every member's scene with `ipsph run`'s own checks
     (a bad sweep exits 2 in one line naming the member and the key);
  2. plan the output folder: a completed sweep has nothing to do (exit 0, no cluster), an
     unfinished one needs --resume (only its incomplete members run) or --overwrite;
  3. start a LocalCluster on 127.0.0.1 (scheduler, nannies, workers and dashboard all on the
     loopback interface) or join --scheduler ADDRESS (TLS from Dask's own configuration);
  4. check that every worker sees OUT (a probe file written here, read and answered there);
  5. submit one task per member (`member.run_member`: `ipsph run` as a child process), each
     needing the worker resource `ipsph_member=1`, so a worker runs one member at a time with
     all its threads; print progress; rewrite OUT/sweep.json and OUT/summary.csv atomically at
     every change.
Faults: a failing member is recorded and the others go on; a worker that dies has its member
rerun by Dask (from the checkpoint the dying member wrote); Ctrl-C asks every running member
to write a checkpoint and stop, records them as interrupted and exits 130.
"""

from __future__ import annotations

import sys
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import EXIT_ERROR, EXIT_INTERRUPTED, InputError
from . import member as mem
from . import records
from .cluster import (
    _dashboard,
    _need_distributed,
    _scheduler_info,
    check_shared_folder,
    local_layout,
    start_local_cluster,
)
from .plan import plan, prepare
from .spec import load_sweep, validate

EXIT_MEMBERS_FAILED = EXIT_ERROR
DEFAULT_DASHBOARD = "127.0.0.1:8787"


@dataclass
class SweepOptions:
    out: Path
    scheduler: str | None = None  # join this Dask scheduler instead of a LocalCluster
    workers: int | None = None  # LocalCluster workers (default: cores // threads_per_worker)
    threads_per_worker: int | None = None  # LocalCluster threads per worker = each member's Numba threads
    resume: bool = False
    overwrite: bool = False
    render: bool = True
    max_particles: int | None = None
    progress: bool = True
    dashboard_address: str = DEFAULT_DASHBOARD
    wait_workers: float = 60.0  # --scheduler: seconds to wait for the first worker
    extra_set: list[str] = field(default_factory=list)


def _log(msg: str, opts: SweepOptions | None = None) -> None:
    if opts is None or opts.progress:
        print(f"ipsph sweep: {msg}", file=sys.stderr, flush=True)


# -- progress ----------------------------------------------------------------------------------
class Progress:
    def __init__(self, opts: SweepOptions, total: int, slots: int, dashboard: str | None):
        self.opts, self.total, self.slots, self.dashboard = opts, total, max(1, slots), dashboard
        self.t0 = time.time()
        self.started: dict[str, float] = {}
        self.walls: list[float] = []
        self.last_line, self.last_print = None, 0.0

    def eta(self, pending: int) -> str:
        if not self.walls:
            return "ETA after the first member"
        avg = sum(self.walls) / len(self.walls)
        now = time.time()
        left = sum(max(avg - (now - t), 0.0) for t in self.started.values())
        left += avg * max(pending - len(self.started), 0)
        s = int(round(left / self.slots))
        return f"ETA {s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"

    def show(self, recs: list[dict], eta: bool = True) -> None:
        c = records.counts(recs)
        pend = c.get("pending", 0) + c.get("running", 0)
        line = (
            f"{c.get('completed', 0)}/{self.total} done, {c.get('running', 0)} running, "
            f"{c.get('failed', 0)} failed"
            + (f", {c['interrupted']} interrupted" if c.get("interrupted") else "")
            + f", {c.get('pending', 0)} waiting"
        )
        now = time.time()
        if line != self.last_line or now - self.last_print > 30:
            tail = f"; {self.eta(pend)}" if pend and eta else ""
            _log(line + tail + (f"; dashboard {self.dashboard}" if self.dashboard else ""), self.opts)
            self.last_line, self.last_print = line, now


# -- the sweep ---------------------------------------------------------------------------------
def run_sweep(sweep_file: str | Path, opts: SweepOptions) -> tuple[int, list[dict]]:
    """Run a sweep; returns (exit code, member records). Input errors raise before anything starts.

    Exit code: 0 every member completed, 1 some member failed (sweep.json says why), 130 stopped by Ctrl-C."""
    t_begin = time.perf_counter()
    out = Path(opts.out).expanduser()
    sweep = load_sweep(sweep_file, opts.extra_set)
    if opts.scheduler is None:
        n_workers, n_threads = local_layout(opts.workers, opts.threads_per_worker)
    else:
        if opts.workers is not None or opts.threads_per_worker is not None:
            raise InputError(
                "--workers / --threads-per-worker size a LocalCluster; with --scheduler the cluster "
                "decides (each member uses its worker's threads)"
            )
        n_workers, n_threads = 1, None
    _need_distributed()
    validate(sweep, opts.max_particles, concurrent=n_workers)
    old = records.read_sweep_json(out) if out.is_dir() else None
    recs, todo = plan(sweep, out, opts.resume, opts.overwrite)
    if not todo:
        _log(f"all {len(recs)} members in {out} are complete; nothing to run", opts)
        return 0, recs
    prepare(sweep, out, opts.overwrite, recs, old)
    out_abs = out.resolve()
    varied = [k for k, _ in sweep.grid] + [k for k, _ in sweep.zipped]
    params = {r["name"]: r["parameters"] for r in recs}
    timings = {"validate": time.perf_counter() - t_begin}  # seconds per phase (python -m benchmarks sweep reads them)
    info = {
        **sweep.as_dict(),
        "out": str(out_abs),
        "members_total": len(recs),
        "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "timings_s": timings,
    }
    by_name = {r["name"]: r for r in recs}

    def save() -> None:
        records.write_sweep_json(out, info, recs)
        records.write_summary_csv(out, recs, varied, params)

    save()
    from distributed import Client

    cluster = None
    sweep_id = uuid.uuid4().hex[:12]
    t0 = time.perf_counter()
    if opts.scheduler is None:
        _log(
            f"{len(todo)} of {len(recs)} members to run; starting a LocalCluster on 127.0.0.1: {n_workers} "
            f"workers x {n_threads} threads",
            opts,
        )
        cluster = start_local_cluster(n_workers, n_threads, opts.dashboard_address)
        client = Client(cluster)
        info["scheduler"] = {
            "kind": "LocalCluster",
            "address": cluster.scheduler_address,
            "workers": n_workers,
            "threads_per_worker": n_threads,
        }
    else:
        _log(f"{len(todo)} of {len(recs)} members to run; joining the Dask scheduler at {opts.scheduler}", opts)
        try:
            client = Client(opts.scheduler, timeout=opts.wait_workers)
        except (OSError, TimeoutError) as exc:
            raise InputError(f"--scheduler {opts.scheduler}: cannot connect: {' '.join(str(exc).split())}") from exc
        info["scheduler"] = {"kind": "external", "address": opts.scheduler}
    code = 0
    try:
        if opts.scheduler is not None:
            try:
                client.wait_for_workers(1, timeout=opts.wait_workers)
            except TimeoutError as exc:
                raise InputError(
                    f"--scheduler {opts.scheduler}: no worker joined within {opts.wait_workers:.0f} s"
                ) from exc
        timings["cluster_start"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        check_shared_folder(client, out)
        timings["shared_folder_check"] = time.perf_counter() - t0
        workers = _scheduler_info(client, -1)["workers"]
        exclusive = not all(mem.RESOURCE in (w.get("resources") or {}) for w in workers.values())
        if exclusive:
            _log(
                f"note: the workers do not declare the resource {mem.RESOURCE}=1 (start them with "
                f"--resources {mem.RESOURCE}=1, docs/sweeps.md); each runs one member at a time by a lock, "
                f"but Dask may queue several on one worker",
                opts,
            )
        info["scheduler"]["worker_threads"] = sorted({int(w.get("nthreads", 0)) for w in workers.values()})
        dash = _dashboard(client)
        info["dashboard"] = dash
        t0 = time.perf_counter()
        code = _submit_and_wait(
            client, sweep, out_abs, todo, by_name, recs, opts, exclusive, save, dash, sweep_id, len(workers)
        )
        timings["members"] = time.perf_counter() - t0
        t0 = time.perf_counter()
    finally:
        try:
            client.close()
        finally:
            if cluster is not None:
                cluster.close()
        for r in recs:  # a member stopped by a dying worker finishes its checkpoint on its own: wait for it
            _wait_child_gone(out / r["name"])
    timings["close"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_begin
    save()
    _log(_closing_line(code, recs, out_abs), opts)
    return code, recs


def _submit_and_wait(
    client, sweep, out_abs, todo, by_name, recs, opts, exclusive, save, dash, sweep_id, n_workers
) -> int:
    from distributed import wait

    member_of = {m.name: m for m in sweep.members}
    futures = {}
    for name in todo:
        m = member_of[name]
        job = {
            "name": name,
            "folder": str(out_abs / name),
            "scene": str(sweep.scene),
            "set_args": m.set_args(),
            "render": opts.render,
            "max_particles": opts.max_particles,
            "exclusive": exclusive,
            "sweep_id": sweep_id,
        }
        f = client.submit(
            mem.run_member,
            job,
            key=f"ipsph-member-{name}-{sweep_id}",
            pure=False,
            resources=None if exclusive else {mem.RESOURCE: 1},
            retries=0,
        )
        futures[f] = name
    progress = Progress(opts, len(recs), n_workers, dash)
    progress.show(recs)
    pending = set(futures)
    interrupted = False
    try:
        while pending:
            try:
                done, pending = wait(list(pending), timeout=1.0, return_when="FIRST_COMPLETED")
            except TimeoutError:
                done = set()
            changed = _collect(done, futures, by_name, progress)
            changed |= _poll_running(out_abs, pending, futures, by_name, progress)
            if changed:
                save()
            progress.show(recs)
    except KeyboardInterrupt:
        interrupted = True
        _log(
            "interrupted: asking the running members to write a checkpoint and stop "
            "(Ctrl-C again to leave them to stop on their own)",
            opts,
        )
        try:
            client.run(mem.stop_members, sweep_id, on_error="ignore")
            done, pending = wait(list(pending), timeout=300)
            _collect(done, futures, by_name, progress)
        except (KeyboardInterrupt, TimeoutError):  # a second Ctrl-C, or members that would not stop
            done = {f for f in pending if f.done()}
            _collect(done, futures, by_name, progress)
            pending = pending - done
        for f in pending:
            name = futures[f]
            if by_name[name]["status"] == "running":
                by_name[name].update(status="interrupted", reason="stopped by Ctrl-C")
            f.cancel()
    for r in recs:
        if r["status"] == "running":
            r["status"] = "pending"
    save()
    progress.show(recs, eta=not interrupted)
    failed = [r for r in recs if r["status"] == "failed"]
    for r in failed:
        _log(f"member {r['name']} failed (exit {r['exit_code']}): {r['reason']}", opts)
    if interrupted:
        return EXIT_INTERRUPTED
    return EXIT_MEMBERS_FAILED if failed else 0


def _closing_line(code: int, recs: list[dict], out_abs: Path) -> str:
    """What the sweep says last, once the cluster is closed (a worker's teardown log cannot follow it)."""
    if code == EXIT_INTERRUPTED:
        return "stopped; finished members are intact; continue with the same command and --resume"
    return (
        f"{sum(r['status'] == 'completed' for r in recs)}/{len(recs)} members completed in {out_abs}; "
        f"{records.SWEEP_JSON}, {records.SUMMARY_CSV}; `ipsph plot {out_abs}` overlays them"
    )


def _collect(done, futures, by_name, progress) -> bool:
    for f in done:
        name = futures[f]
        rec = by_name[name]
        try:
            res = f.result()
        except Exception as exc:  # e.g. KilledWorker: the member's workers died too often
            rec.update(status="failed", exit_code=None, reason=f"{type(exc).__name__}: {' '.join(str(exc).split())}")
        else:
            res.pop("name", None)
            rec.update(res)
            if rec["status"] == "not started":
                rec["status"] = "pending"
        t = progress.started.pop(name, None)
        if rec["status"] == "completed" and t is not None:
            progress.walls.append(time.time() - t)
    return bool(done)


def _poll_running(out_abs: Path, pending, futures, by_name, progress) -> bool:
    """Members whose folder shows a live run are `running` (the workers write run.json at start)."""
    changed = False
    for f in pending:
        name = futures[f]
        rec = by_name[name]
        if rec["status"] == "running":
            continue
        try:
            live = (out_abs / name / mem.PID_FILE).stat().st_mtime >= progress.t0 - 1.0
        except OSError:
            live = False
        if live:
            if name not in progress.started:
                progress.started[name] = time.time()
            if rec["status"] != "running":
                rec["status"] = "running"
                changed = True
    return changed


def _wait_child_gone(folder: Path, timeout: float = 120.0) -> None:
    """Block while a child still holds the member folder's lock (a member stopping after its worker died)."""
    import fcntl

    lock_path = folder / mem.LOCK_FILE
    if not lock_path.exists():
        return
    t0 = time.time()
    with open(lock_path, "a+") as lock:
        while time.time() - t0 < timeout:
            try:
                fcntl.flock(lock.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
                return
            except BlockingIOError:
                time.sleep(0.2)


def sweep(sweep_file: str | Path, out: str | Path, **options) -> list[dict]:
    """Run a sweep from Python: `ipsph.sweep("study.toml", "out-study", workers=2, threads_per_worker=1)`.

    Options are SweepOptions' fields (scheduler, workers, threads_per_worker, resume, overwrite, render,
    max_particles, progress, dashboard_address, extra_set). Returns the member records (as in
    OUT/sweep.json: name, parameters, status, exit_code, reason, wall_seconds, threads, host, attempts).
    Bad input raises ipsph.errors.InputError (a ValueError) before anything starts; a Ctrl-C stops the
    members (checkpointed) and raises KeyboardInterrupt after recording them."""
    options.setdefault("progress", False)
    code, recs = run_sweep(sweep_file, SweepOptions(out=Path(out), **options))
    if code == EXIT_INTERRUPTED:
        raise KeyboardInterrupt
    return recs
