"""The Dask task of one member: `ipsph run` as a child process, in the member's own folder.

Why a child process and not the solver inside the worker:
  * fault isolation: a member that crashes, runs out of memory or is killed takes only its own
    process down; the worker (and the other members it may run later) lives on;
  * `ipsph run` is what runs, argument for argument: the same exit codes (2, 3, 4, 130), the
    same files, and the same bits as a separate `ipsph run --threads T` (Numba's thread count is
    per process, fixed by NUMBA_NUM_THREADS before Numba loads, so T is exactly the worker's
    thread count and nothing is oversubscribed);
  * stopping: SIGTERM makes `ipsph run` finish its step and write a final frame and a checkpoint,
    which is how Ctrl-C and a dying worker leave a member that `--resume` continues.

The member folder is locked (flock on OUT/<member>/.sweep.lock, held by the child through an
inherited descriptor) while a child runs in it, so a rerun after a worker died waits for the old
child to finish writing its checkpoint before it resumes.

Attempt bookkeeping lives in the folder too (sweep-member.log: one header per attempt, then the
child's stderr), so it survives the worker.
"""

from __future__ import annotations

import fcntl
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

from ..io import CHECKPOINT_FILE, RUN_JSON

LOCK_FILE = ".sweep.lock"
LOG_FILE = "sweep-member.log"
PID_FILE = ".sweep-member.pid"
RESOURCE = "ipsph_member"  # Dask worker resource: one member at a time per worker

_RUNNING: dict[int, subprocess.Popen] = {}  # this worker process's running children, by pid
_ONE_AT_A_TIME = threading.Lock()  # for workers started without the resource
_STOPPED: set[str] = set()  # sweeps stopped by Ctrl-C: their queued members do not start


def stop_members(sweep_id: str) -> int:
    """Ask this worker's running members to stop (SIGTERM: final frame + checkpoint). Returns how many."""
    _STOPPED.add(sweep_id)
    n = 0
    for proc in list(_RUNNING.values()):
        if proc.poll() is None:
            try:
                proc.send_signal(signal.SIGTERM)
                n += 1
            except ProcessLookupError:
                pass
    return n


def probe_folder(probe: str, token: str) -> bool | str:
    """Run on each worker by the client: True when it reads `probe` (holding `token`) and can write beside it."""
    p = Path(probe)
    try:
        if p.read_text() != token:
            return "the probe file holds something else (another machine's folder at the same path?)"
        w = p.with_name(f"{p.name}.{socket.gethostname()}-{os.getpid()}")
        w.write_text(token)
        w.unlink()
    except OSError as exc:
        return f"{type(exc).__name__}: {exc.strerror or exc}"
    return True


def worker_threads() -> int:
    try:
        from distributed import get_worker

        return int(get_worker().state.nthreads)
    except (ImportError, ValueError, AttributeError):
        return 1


def _read_json(path: Path) -> dict | None:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def folder_state(folder: Path) -> str:
    """completed | checkpoint (an unfinished run with a checkpoint) | started (an unfinished run) | empty."""
    info = _read_json(folder / RUN_JSON)
    if info is None:
        return "empty"
    if info.get("completed"):
        return "completed"
    return "checkpoint" if (folder / CHECKPOINT_FILE).is_file() else "started"


def _error_line(log_tail: str) -> str | None:
    lines = [ln.strip() for ln in log_tail.splitlines() if ln.strip()]
    errs = [ln for ln in lines if ln.startswith("ipsph: error:")]
    if errs:
        return errs[-1][len("ipsph: error:") :].strip()
    tb = [ln for ln in lines if not ln.startswith(("ipsph: note", "ipsph: warning", "=="))]
    return tb[-1] if tb else None


def _attempts(log: Path) -> int:
    try:
        return sum(1 for ln in log.read_text(errors="replace").splitlines() if ln.startswith("== attempt "))
    except OSError:
        return 0


def run_member(job: dict) -> dict:
    """Run one member (the dict `engine` builds) to its end; returns its record.

    job: name, folder, scene, set_args, render, max_particles, exclusive (take the process lock), sweep_id.
    """
    if job.get("sweep_id") in _STOPPED:
        return {"name": job["name"], "status": "not started"}
    if job.get("exclusive"):
        with _ONE_AT_A_TIME:
            return _run_member(job)
    return _run_member(job)


def _run_member(job: dict) -> dict:
    folder = Path(job["folder"])
    folder.mkdir(parents=True, exist_ok=True)
    threads = int(job.get("threads") or worker_threads())
    host = socket.gethostname()
    lock = open(folder / LOCK_FILE, "a+")
    try:
        t_wait = time.time()
        while True:  # a child of a dead worker may still be writing its checkpoint
            try:
                fcntl.flock(lock.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                time.sleep(0.2)
        waited = time.time() - t_wait
        if job.get("sweep_id") in _STOPPED:
            return {"name": job["name"], "status": "not started"}
        state = folder_state(folder)
        if state == "completed":  # an earlier attempt finished just before its worker died
            info = _read_json(folder / RUN_JSON) or {}
            return _record(
                job, "completed", 0, None, info, threads, host, _attempts(folder / LOG_FILE), 0.0, waited, resumed=False
            )
        attempt = _attempts(folder / LOG_FILE) + 1
        mode = {"checkpoint": "--resume", "started": "--overwrite"}.get(state)
        code, wall, tail = _child(job, folder, lock, threads, mode, attempt, host)
        if code == 2 and mode == "--resume":  # a checkpoint that cannot be continued: start afresh
            mode = "--overwrite"
            code, wall2, tail = _child(job, folder, lock, threads, mode, attempt, host, note="restart")
            wall += wall2
        info = _read_json(folder / RUN_JSON) or {}
        if code == 0:
            status, reason = "completed", None
        elif code == 130:
            status, reason = (
                "interrupted",
                "stopped by a signal after a final frame and a checkpoint; --resume continues it",
            )
        else:
            status = "failed"
            reason = (
                info.get("error")
                or _error_line(tail)
                or (f"killed by signal {signal.Signals(-code).name}" if code < 0 else f"exit code {code}")
            )
        return _record(
            job, status, code, reason, info, threads, host, attempt, wall, waited, resumed=mode == "--resume"
        )
    finally:
        lock.close()


def _child(
    job: dict, folder: Path, lock, threads: int, mode: str | None, attempt: int, host: str, note: str = ""
) -> tuple[int, float, str]:
    cmd = [
        sys.executable,
        "-m",
        "ipsph",
        "run",
        str(job["scene"]),
        "-o",
        str(folder),
        "--quiet",
        "--threads",
        str(threads),
    ]
    for s in job["set_args"]:
        cmd += ["--set", s]
    if not job.get("render", True):
        cmd.append("--no-render")
    if job.get("max_particles"):
        cmd += ["--max-particles", str(int(job["max_particles"]))]
    if mode:
        cmd.append(mode)
    env = dict(os.environ, NUMBA_NUM_THREADS=str(threads), IPSPH_SWEEP_PARENT=str(os.getpid()))
    env.pop("OMP_NUM_THREADS", None)  # Dask sets it to 1 in workers; `ipsph run` leaves it to Numba
    log_path = folder / LOG_FILE
    with open(log_path, "a") as log:
        log.write(
            f"== attempt {attempt}{' ' + note if note else ''} on {host} pid {os.getpid()}, "
            f"{threads} threads, {time.strftime('%Y-%m-%dT%H:%M:%S%z')}: {' '.join(cmd[3:])}\n"
        )
        log.flush()
        start = log.tell()
        t0 = time.perf_counter()
        # own session: a terminal's Ctrl-C reaches the sweep's client, which stops members with SIGTERM
        proc = subprocess.Popen(
            cmd,
            stdin=subprocess.DEVNULL,
            stdout=log,
            stderr=subprocess.STDOUT,
            env=env,
            pass_fds=(lock.fileno(),),
            start_new_session=True,
        )
        _RUNNING[proc.pid] = proc
        if job.get("sweep_id") in _STOPPED:  # Ctrl-C came while it started
            proc.send_signal(signal.SIGTERM)
        try:
            (folder / PID_FILE).write_text(f"{proc.pid} {host}\n")
            code = proc.wait()
        finally:
            _RUNNING.pop(proc.pid, None)
        wall = time.perf_counter() - t0
    try:
        with open(log_path, errors="replace") as f:
            f.seek(start)
            tail = f.read()[-8000:]
    except OSError:
        tail = ""
    return code, wall, tail


def _record(job, status, code, reason, info, threads, host, attempt, wall, waited, resumed) -> dict:
    return {
        "name": job["name"],
        "status": status,
        "exit_code": code,
        "reason": reason,
        "wall_seconds": info.get("wall_seconds") if status == "completed" and not wall else wall,
        "run_wall_seconds": info.get("wall_seconds"),
        "threads": threads,
        "host": host,
        "worker_pid": os.getpid(),
        "attempts": attempt,
        "resumed": resumed,
        "lock_wait_seconds": waited,
        "finished": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    }
