"""SPlisHSPlasH as a benchmark peer: run a stock scene in a worker subprocess and return its numbers.

pySPlisHSPlasH (``pip install pysplishsplash``) is never a dependency of ipsph: it is imported only in
the worker (:mod:`ipsph.bench._peer_worker`), and only when installed. The worker gets
``OMP_NUM_THREADS`` (thread count) and ``LD_PRELOAD=libGLdispatch.so.0`` (the wheel's import segfaults
without it on headless Debian images) in its environment; a crash therefore never takes down the caller.

>>> ok, why = peer_available()
>>> r = run_peer(Path(".../Scenes/DamBreakModel.json"), "dfsph", end_time=1.0, threads=2)
>>> r["ms_per_step"], r["density_error_mean_pct"], r["load"]["others_busy_mean"]

See ``_peer_worker`` for the meaning of every key of the result.
"""

from __future__ import annotations

import functools
import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

from ..errors import ConfigError
from .machine import run_json_worker

__all__ = ["GL_PRELOAD", "METHODS", "peer_available", "peer_env", "run_peer"]

GL_PRELOAD = "/lib/x86_64-linux-gnu/libGLdispatch.so.0"
METHODS = ("wcsph", "pcisph", "pbf", "iisph", "dfsph", "pf", "icsph")  # names the worker accepts
_REPO_ROOT = Path(__file__).resolve().parents[2]  # folder holding the ipsph package


def peer_env(threads: int | None = None) -> dict[str, str]:
    """Environment for a peer subprocess: ipsph importable, GL preload when present, OpenMP threads."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(_REPO_ROOT), env.get("PYTHONPATH", "")) if p)
    if os.path.exists(GL_PRELOAD):
        pre = env.get("LD_PRELOAD", "")
        if GL_PRELOAD not in pre.split(":"):
            env["LD_PRELOAD"] = ":".join(p for p in (GL_PRELOAD, pre) if p)
    if threads is not None:
        env["OMP_NUM_THREADS"] = str(threads)
    return env


@functools.lru_cache(maxsize=1)
def peer_available() -> tuple[bool, str]:
    """(True, version) when pySPlisHSPlasH imports in a subprocess, else (False, why). Cached."""
    if importlib.util.find_spec("pysplishsplash") is None:  # does not import it
        return False, "pysplishsplash is not installed (pip install pysplishsplash)"
    code = (
        "import pysplishsplash, pysplishsplash.Exec\n"
        "from importlib import metadata\n"
        "print(metadata.version('pySPlisHSPlasH'))\n"
    )
    try:
        proc = subprocess.run(
            [sys.executable, "-c", code], env=peer_env(1), capture_output=True, text=True, timeout=120
        )
    except subprocess.TimeoutExpired:
        return False, "importing pysplishsplash took over 120 s in a subprocess"
    if proc.returncode != 0:
        tail = (proc.stderr or "").strip().splitlines()[-1:] or [f"exit status {proc.returncode}"]
        if proc.returncode < 0:
            tail = [f"killed by signal {-proc.returncode} (a missing GL library? LD_PRELOAD={GL_PRELOAD})"]
        return False, f"pysplishsplash is installed but does not import: {tail[0]}"
    return True, f"pySPlisHSPlasH {proc.stdout.strip()}"


def _param_args(params: dict | None) -> list[str]:
    """{"boundaryHandlingMethod": 0, "Fluid:viscosity": 0.01} -> ["--param", "boundaryHandlingMethod:0", ...]."""
    args: list[str] = []
    for key, value in (params or {}).items():
        if isinstance(value, (list, tuple)):
            text = ",".join(json.dumps(v) for v in value)
        elif isinstance(value, str):
            text = value
        else:
            text = json.dumps(value)
        if not isinstance(key, str) or not key or key.count(":") > 1:
            raise ConfigError(f"peer params: key {key!r} must be 'name' or 'materialId:name'")
        args += ["--param", f"{key}:{text}"]
    return args


def run_peer(
    scene_json: Path,
    method: str,
    end_time: float,
    threads: int,
    params: dict | None = None,
    timeout: float = 1800,
    work_dir: Path | None = None,
    sample_load: bool = True,
    env: dict[str, str] | None = None,
) -> dict:
    """Run ``scene_json`` in SPlisHSPlasH with ``method`` for ``end_time`` simulated seconds.

    ``params`` override the scene's Configuration (``{"boundaryHandlingMethod": 0}``) or a material
    (``{"Fluid:viscosity": 0.01}``). ``work_dir`` (optional, persistent) keeps SPlisHSPlasH's volume-map
    and boundary-sample cache between runs; by default a temporary folder is used and removed.
    ``env`` adds environment variables for the worker (e.g. ``{"OMP_WAIT_POLICY": "passive"}``).
    The result is the worker's JSON plus ``load`` (a :class:`LoadSummary` dict sampled during the run)
    and ``command``. Raises ConfigError for bad arguments, RuntimeError (with the worker's stderr tail)
    when the peer is missing, crashes, times out or prints no result.
    """
    scene = Path(scene_json)
    resolved = scene.resolve()
    if not resolved.is_file():
        raise ConfigError(f"peer scene {scene} (resolved {resolved}) is not a file: pass a SPlisHSPlasH scene JSON")
    if method not in METHODS:
        raise ConfigError(f"peer method {method!r} is unknown: use one of {', '.join(METHODS)}")
    if not (isinstance(end_time, (int, float)) and end_time > 0):
        raise ConfigError(f"peer end_time {end_time!r} must be a number of simulated seconds > 0")
    if not (isinstance(threads, int) and threads >= 1):
        raise ConfigError(f"peer threads {threads!r} must be an integer >= 1")
    ok, why = peer_available()
    if not ok:
        raise RuntimeError(f"SPlisHSPlasH peer unavailable: {why}")

    cmd = [
        sys.executable,
        "-m",
        "ipsph.bench._peer_worker",
        "--scene",
        str(resolved),
        "--method",
        method,
        "--end-time",
        repr(float(end_time)),
        "--threads",
        str(threads),
        *_param_args(params),
    ]
    if work_dir is not None:
        cmd += ["--work-dir", str(Path(work_dir).resolve())]

    return run_json_worker(
        cmd,
        {**peer_env(threads), **(env or {})},
        timeout,
        "SPlisHSPlasH peer",
        f"{resolved} method={method}",
        sample_load,
    )
