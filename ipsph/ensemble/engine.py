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

import logging
import os
import shutil
import sys
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import EXIT_ERROR, EXIT_INTERRUPTED, InputError, OutputError
from ..io import check_writable
from . import member as mem
from . import records
from .spec import Sweep, load_sweep, validate

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


def usable_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def local_layout(workers: int | None, threads: int | None) -> tuple[int, int]:
    """(workers, threads per worker) of a LocalCluster: the given ones, the rest from the machine's cores."""
    cores = usable_cores()
    if workers is not None and workers < 1:
        raise InputError(f"--workers {workers}: must be >= 1")
    if threads is not None and threads < 1:
        raise InputError(f"--threads-per-worker {threads}: must be >= 1")
    if threads is None:
        threads = max(1, cores // workers) if workers else 1
    if workers is None:
        workers = max(1, cores // threads)
    return workers, threads


def _need_distributed() -> None:
    try:
        import distributed  # noqa: F401
    except ImportError as exc:
        raise InputError(
            "ipsph sweep needs Dask distributed, which is not installed: "
            "pip install 'ipsph[sweep]' (or pip install distributed)"
        ) from exc


# -- the output folder -------------------------------------------------------------------------
def _member_entry(sweep: Sweep, m) -> dict:
    return {
        "name": m.name,
        "folder": m.name,
        "parameters": m.params(),
        "varied": dict(m.varied),
        "status": "pending",
        "exit_code": None,
        "reason": None,
        "wall_seconds": None,
        "threads": None,
        "host": None,
        "attempts": 0,
    }


def plan(sweep: Sweep, out: Path, resume: bool, overwrite: bool) -> tuple[list[dict], list[str]]:
    """(records of every member, names of the members to run); raises OutputError (exit 2) on a conflict.

    Creates nothing and deletes nothing (see `prepare`)."""
    if out.exists() and not out.is_dir():
        raise OutputError(f"output folder {out} (resolved {out.resolve()}) is a file; choose another -o")
    fresh = {m.name: _member_entry(sweep, m) for m in sweep.members}
    old = records.read_sweep_json(out) if out.is_dir() else None
    if (out / records.SWEEP_JSON).exists() and old is None and not overwrite:
        raise OutputError(f"{out / records.SWEEP_JSON} cannot be read; pass --overwrite to start the sweep afresh")
    if old is not None and not overwrite:
        old_members = {r["name"]: r for r in old.get("members", [])}
        why = None
        if old.get("scene") != str(sweep.scene):
            why = f"its base scene was {old.get('scene')}, now {sweep.scene}"
        elif set(old_members) != set(fresh):
            gone = sorted(set(old_members) - set(fresh))
            new = sorted(set(fresh) - set(old_members))
            why = "members " + ", ".join([f"{n} removed" for n in gone[:2]] + [f"{n} added" for n in new[:2]])
        else:
            for n, r in fresh.items():
                if old_members[n].get("parameters") != records.to_jsonable(r["parameters"]):
                    why = f"member {n} has other parameters"
                    break
        if why:
            raise OutputError(
                f"{out} holds a different sweep ({why}); pass --overwrite to replace it or choose another -o"
            )
        recs = []
        for n, r in fresh.items():
            o = old_members[n]
            r.update(
                {
                    k: o.get(k)
                    for k in ("status", "exit_code", "reason", "wall_seconds", "threads", "host", "attempts", "resumed")
                }
            )
            recs.append(r)
    else:
        recs = list(fresh.values())
        if not overwrite:
            for r in recs:
                if (out / r["name"] / "run.json").exists():
                    raise OutputError(
                        f"{out / r['name']} holds an earlier run that is not part of a sweep in "
                        f"{out}; pass --overwrite to replace it or choose another -o"
                    )
    if overwrite:
        for r in recs:
            r.update(_member_entry(sweep, next(m for m in sweep.members if m.name == r["name"])))
        return recs, [r["name"] for r in recs]
    todo = []
    for r in recs:
        if mem.folder_state(out / r["name"]) == "completed":
            r["status"] = "completed"
        else:
            if r["status"] in ("completed", "running"):
                r["status"] = "pending"
            todo.append(r["name"])
    if old is not None and todo and len(todo) < len(recs) and not resume:
        raise OutputError(
            f"{out} holds an unfinished sweep ({len(recs) - len(todo)} of {len(recs)} members "
            f"completed); pass --resume to run the other {len(todo)}, or --overwrite to start afresh"
        )
    if (
        old is not None
        and todo
        and len(todo) == len(recs)
        and not resume
        and any(mem.folder_state(out / n) != "empty" for n in todo)
    ):
        raise OutputError(
            f"{out} holds an unfinished sweep (no member completed); pass --resume to continue "
            f"it, or --overwrite to start afresh"
        )
    return recs, todo


def prepare(sweep: Sweep, out: Path, overwrite: bool, recs: list[dict], old: dict | None) -> None:
    """Create OUT (checking it is writable); with --overwrite delete the earlier sweep's member folders."""
    check_writable(out)
    if overwrite:
        names = {r["name"] for r in recs} | {r["name"] for r in (old or {}).get("members", [])}
        for n in names:
            if n and "/" not in n and n not in (".", ".."):
                shutil.rmtree(out / n, ignore_errors=True)
        for f in (records.SWEEP_JSON, records.SUMMARY_CSV):
            (out / f).unlink(missing_ok=True)


# -- the cluster -------------------------------------------------------------------------------
def start_local_cluster(workers: int, threads: int, dashboard_address: str):
    """A LocalCluster listening on 127.0.0.1 only; each worker offers one member slot (RESOURCE)."""
    from distributed import LocalCluster

    return LocalCluster(
        n_workers=workers,
        threads_per_worker=threads,
        processes=True,
        host="127.0.0.1",
        dashboard_address=dashboard_address,
        worker_dashboard_address=None,
        resources={mem.RESOURCE: 1},
        memory_limit=0,
        silence_logs=logging.ERROR,
        preload=["ipsph.ensemble._worker_setup"],
    )


def check_shared_folder(client, out: Path) -> None:
    """Every worker must read a probe file written here and write one beside it (OutputError if not)."""
    token = uuid.uuid4().hex
    probe = out / f".sweep-probe-{token}"
    probe.write_text(token)
    try:
        answers = client.run(mem.probe_folder, str(probe), token, on_error="return")
    finally:
        probe.unlink(missing_ok=True)
        for f in out.glob(f".sweep-probe-{token}.*"):
            f.unlink(missing_ok=True)
    bad = {a: r for a, r in answers.items() if r is not True}
    if bad:
        addr, why = next(iter(bad.items()))
        raise OutputError(
            f"{len(bad)} of {len(answers)} workers cannot use {out.resolve()} ({addr}: {why}); "
            f"the sweep's output folder must be on a filesystem every worker shares, "
            f"at the same path"
        )


def _scheduler_info(client, n_workers: int) -> dict:
    try:  # distributed >= 2025.1 lists only 5 workers unless told
        return client.scheduler_info(n_workers=n_workers)
    except TypeError:
        return client.scheduler_info()


def _dashboard(client) -> str | None:
    info = _scheduler_info(client, 0)
    if "dashboard" not in info.get("services", {}):
        return None
    return client.dashboard_link


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
        _log("stopped; finished members are intact; continue with the same command and --resume", opts)
        return EXIT_INTERRUPTED
    _log(
        f"{sum(r['status'] == 'completed' for r in recs)}/{len(recs)} members completed in {out_abs}; "
        f"{records.SWEEP_JSON}, {records.SUMMARY_CSV}; `ipsph plot {out_abs}` overlays them",
        opts,
    )
    return EXIT_MEMBERS_FAILED if failed else 0


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
