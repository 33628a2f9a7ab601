"""Machine facts and load bookkeeping for benchmarks on a shared machine.

Timings on a shared 2-core machine vary several-fold with other people's load, so every benchmark run
is bracketed by a :class:`LoadSampler` and a run on a loaded machine can be flagged or discarded.

* ``cpu_busy`` is the machine-wide busy fraction from ``/proc/stat`` (1 - (idle + iowait) / total).
* ``others_busy`` subtracts the CPU time used by this process and its live descendants (psutil), so a
  benchmark's own threads do not count as "load": it is the share of the machine used by someone else.
* ``loadavg`` is the kernel's 1-minute load average (lagged by design; it includes our own threads).
"""

from __future__ import annotations

import os
import platform
import resource
import threading
import time
from dataclasses import asdict, dataclass

__all__ = ["LoadSampler", "LoadSummary", "load_sampler", "machine_info", "peak_rss_mb"]


def _read_proc_stat() -> tuple[int, int] | None:
    """(busy, total) jiffies summed over all CPUs from the first line of /proc/stat; None off Linux."""
    try:
        with open("/proc/stat", encoding="ascii") as fh:
            fields = fh.readline().split()
    except OSError:
        return None
    if not fields or fields[0] != "cpu":
        return None
    values = [int(v) for v in fields[1:]]
    # user nice system idle iowait irq softirq steal guest guest_nice; guest* are already in user/nice
    values = values[:8]
    idle = values[3] + (values[4] if len(values) > 4 else 0)
    total = sum(values)
    return total - idle, total


def _own_cpu_by_pid() -> dict[int, float]:
    """CPU seconds (user + system) of this process and each live descendant, by pid."""
    import psutil  # light, but keep it out of module import

    me = psutil.Process()
    procs = [me]
    try:
        procs += me.children(recursive=True)
    except psutil.Error:
        pass
    out: dict[int, float] = {}
    for p in procs:
        try:
            t = p.cpu_times()
        except psutil.Error:
            continue
        out[p.pid] = t.user + t.system
    return out


def _own_delta(prev: dict[int, float], cur: dict[int, float]) -> float:
    """CPU seconds used between two snapshots; a pid new in ``cur`` counts in full (it was born in between)."""
    return sum(t - prev.get(pid, 0.0) for pid, t in cur.items())


@dataclass(frozen=True)
class LoadSummary:
    """What the machine did while a benchmark ran. Fractions are of the whole machine (all CPUs)."""

    seconds: float
    samples: int
    cpus: int
    loadavg_mean: float
    loadavg_max: float
    cpu_busy_mean: float
    cpu_busy_max: float
    others_busy_mean: float
    others_busy_max: float

    def as_dict(self) -> dict:
        return asdict(self)

    def loaded(self, others_busy_limit: float = 0.15) -> bool:
        """True when someone else used more than ``others_busy_limit`` of the machine on average."""
        return self.others_busy_mean > others_busy_limit


class LoadSampler:
    """Background sampler of load average and CPU busy fraction; use as a context manager.

    >>> with LoadSampler(interval=0.5) as s:
    ...     run_benchmark()
    >>> s.summary().others_busy_mean
    """

    def __init__(self, interval: float = 0.5):
        if not interval > 0.0:
            raise ValueError(f"LoadSampler interval must be > 0 s, got {interval!r}")
        self.interval = float(interval)
        self._loadavg: list[float] = []
        self._busy: list[float] = []
        self._others: list[float] = []
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._t0 = self._t1 = 0.0
        self._first = None

    # -- sampling ---------------------------------------------------------------------------------
    def _snapshot(self):
        return _read_proc_stat(), _own_cpu_by_pid()

    def _record(self, prev, cur) -> None:
        (stat0, own0), (stat1, own1) = prev, cur
        self._loadavg.append(os.getloadavg()[0])
        if stat0 is None or stat1 is None:
            return
        d_busy, d_total = stat1[0] - stat0[0], stat1[1] - stat0[1]
        if d_total <= 0:
            return
        hz = os.sysconf("SC_CLK_TCK")
        busy = d_busy / d_total
        own = _own_delta(own0, own1) * hz / d_total  # own CPU seconds as a fraction of all CPU jiffies
        self._busy.append(min(max(busy, 0.0), 1.0))
        self._others.append(min(max(busy - own, 0.0), 1.0))

    def _run(self) -> None:
        prev, t_prev = self._first, self._t0
        while not self._stop.wait(self.interval):
            cur = self._snapshot()
            self._record(prev, cur)
            prev, t_prev = cur, time.perf_counter()
        if time.perf_counter() - t_prev > 0.25 * self.interval or not self._busy:
            self._record(prev, self._snapshot())  # the tail after the last full interval

    def start(self) -> "LoadSampler":
        if self._thread is not None:
            raise RuntimeError("LoadSampler already started")
        self._t0 = time.perf_counter()
        self._first = self._snapshot()
        self._thread = threading.Thread(target=self._run, name="ipsph-load-sampler", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> LoadSummary:
        if self._thread is None:
            raise RuntimeError("LoadSampler was never started")
        self._stop.set()
        self._thread.join()
        self._t1 = time.perf_counter()
        return self.summary()

    def __enter__(self) -> "LoadSampler":
        return self.start()

    def __exit__(self, *exc) -> None:
        if self._thread is not None and not self._stop.is_set():
            self.stop()

    # -- results ----------------------------------------------------------------------------------
    def summary(self) -> LoadSummary:
        def mean(xs):
            return sum(xs) / len(xs) if xs else float("nan")

        def peak(xs):
            return max(xs) if xs else float("nan")

        end = self._t1 if self._t1 else time.perf_counter()
        return LoadSummary(
            seconds=end - self._t0,
            samples=len(self._busy),
            cpus=os.cpu_count() or 1,
            loadavg_mean=mean(self._loadavg),
            loadavg_max=peak(self._loadavg),
            cpu_busy_mean=mean(self._busy),
            cpu_busy_max=peak(self._busy),
            others_busy_mean=mean(self._others),
            others_busy_max=peak(self._others),
        )


def load_sampler(interval: float = 0.5) -> LoadSampler:
    """A :class:`LoadSampler` to use in a ``with`` block; read ``.summary()`` afterwards."""
    return LoadSampler(interval)


def peak_rss_mb(children: bool = False) -> float:
    """Peak resident set size in MiB of this process (or of its waited-for children), from getrusage."""
    who = resource.RUSAGE_CHILDREN if children else resource.RUSAGE_SELF
    kb = resource.getrusage(who).ru_maxrss  # KiB on Linux
    return kb / 1024.0


def machine_info() -> dict:
    """CPU model, logical cores (all and usable by this process), memory, OS and Python versions."""
    model = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                if line.startswith("model name"):
                    model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    mem_gb = float("nan")
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemTotal:"):
                    mem_gb = int(line.split()[1]) / 1024.0**2
                    break
    except OSError:
        pass
    try:
        usable = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        usable = os.cpu_count() or 1
    return {
        "cpu_model": model,
        "logical_cores": os.cpu_count() or 1,
        "usable_cores": usable,
        "memory_gb": round(mem_gb, 2),
        "platform": platform.platform(),
        "python": platform.python_version(),
    }


STDERR_TAIL = 3000  # characters of a failed worker's stderr kept in the error


def run_json_worker(cmd: list[str], env: dict, timeout: float, what: str, where: str, sample_load: bool = True) -> dict:
    """Run one benchmark worker process whose last stdout line is one JSON object.

    The machine's load is sampled while it runs (result["load"]); the command is kept in
    result["command"]. A timeout, a crash or a missing JSON line raises RuntimeError naming
    `what` (e.g. "ipsph worker") and `where` (scene, method) with the tail of its stderr.
    """
    import json
    import subprocess

    sampler = LoadSampler(0.5) if sample_load else None
    if sampler:
        sampler.start()
    try:
        proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired as exc:
        err = exc.stderr.decode(errors="replace") if isinstance(exc.stderr, bytes) else (exc.stderr or "")
        raise RuntimeError(
            f"{what} timed out after {timeout} s on {where}; stderr tail:\n{err[-STDERR_TAIL:]}"
        ) from None
    finally:
        load = sampler.stop() if sampler else None
    lines = [ln for ln in (proc.stdout or "").splitlines() if ln.strip()]
    result = None
    if proc.returncode == 0 and lines:
        try:
            result = json.loads(lines[-1])
        except json.JSONDecodeError:
            result = None
    if result is None:
        status = f"killed by signal {-proc.returncode}" if proc.returncode < 0 else f"exit status {proc.returncode}"
        raise RuntimeError(f"{what} failed ({status}) on {where}; stderr tail:\n{(proc.stderr or '')[-STDERR_TAIL:]}")
    result["load"] = load.as_dict() if load else None
    result["command"] = cmd
    return result


def timed_ipsph_run(args: list[str], out, threads: int, timeout: float, env: dict | None = None) -> dict:
    """`python -m ipsph run ARGS -o OUT` in a fresh process with `threads` Numba threads (this
    checkout first on PYTHONPATH), timed, with the machine's load sampled while it runs.

    Returns seconds (wall), cpu_seconds (the process and its children: the render process),
    exit_code (-1 on timeout), stderr_tail, load (LoadSummary), frames and pngs written to OUT.
    """
    import resource
    import subprocess
    import sys
    from pathlib import Path

    out = Path(out)
    env = dict(os.environ if env is None else env, NUMBA_NUM_THREADS=str(threads))
    root = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH", "")) if p)
    cmd = [sys.executable, "-m", "ipsph", "run", *args, "--quiet", "--threads", str(threads), "-o", str(out)]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    sampler = LoadSampler(0.5).start()
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout)
        code, err = proc.returncode, proc.stderr
    except subprocess.TimeoutExpired:
        code, err = -1, f"timed out after {timeout} s"
    secs = time.perf_counter() - t0
    load = sampler.stop()
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    from ..io import FRAMES_DIR, RENDERS_DIR

    count = lambda folder, pattern: len(list((out / folder).glob(pattern))) if (out / folder).is_dir() else 0  # noqa: E731
    return {
        "seconds": secs,
        "exit_code": code,
        "stderr_tail": (err or "")[-1000:],
        "load": load,
        "cpu_seconds": (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime),
        "frames": count(FRAMES_DIR, "*.vtu"),
        "pngs": count(RENDERS_DIR, "*.png"),
        "command": cmd,
    }
