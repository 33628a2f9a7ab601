"""The sweep's Dask cluster: the local layout (workers x threads from the machine's cores), a
LocalCluster on the loopback interface, the check that every worker shares the output folder.
"""

from __future__ import annotations

import logging
import os
import uuid
from pathlib import Path

from ..errors import InputError, OutputError
from . import member as mem


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
        preload=["ipsph.sweeps._worker_setup"],
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
