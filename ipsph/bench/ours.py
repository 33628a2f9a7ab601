"""Our methods as benchmark subjects: one simulation per worker subprocess, with the machine's load.

>>> r = run_ours(Path(".../Scenes/DamBreakModel.json"), "ipsph", end_time=1.0, threads=2)
>>> r["ms_per_step_median"], r["wall_seconds_per_sim_second"], r["load"]["others_busy_mean"]

The worker (:mod:`ipsph.bench._ours_worker`) gets ``NUMBA_NUM_THREADS`` in its environment, so
the thread pool is sized before Numba starts; its peak RSS therefore belongs to one method only.
See the worker's docstring for the meaning of every key of the result.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from ..errors import ConfigError
from ..params import METHOD_NAMES
from .machine import run_json_worker

__all__ = ["METHODS", "ours_env", "run_ours"]

METHODS = METHOD_NAMES
_REPO_ROOT = Path(__file__).resolve().parents[2]


def ours_env(threads: int | None = None, extra: dict[str, str] | None = None) -> dict[str, str]:
    """Environment for a worker: ipsph importable, NUMBA_NUM_THREADS set. OpenMP keeps its
    default wait policy (or the caller's), as SPlisHSPlasH's workers do and as the Python API
    does: the workers drive `Simulation` and render nothing, so `ipsph run`'s passive policy,
    which is there for its render process, does not apply."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(_REPO_ROOT), env.get("PYTHONPATH", "")) if p)
    if threads is not None:
        env["NUMBA_NUM_THREADS"] = str(threads)
    env.update(extra or {})
    return env


def run_ours(
    scene_path: str | Path,
    method: str,
    end_time: float | None,
    threads: int,
    overrides: tuple[str, ...] | list[str] = (),
    *,
    steps: int | None = None,
    warmup: int = 1,
    timeout: float = 1800,
    sample_load: bool = True,
    env: dict[str, str] | None = None,
) -> dict:
    """Run `scene_path` ("default" for the built-in scene) with `method` in a worker subprocess.

    Either `end_time` (simulated seconds) or `steps` (+ `warmup` steps left out of the statistics).
    Returns the worker's JSON plus ``load`` (a LoadSummary dict sampled around the worker) and
    ``command``. Raises ConfigError for bad arguments and RuntimeError (with the worker's stderr
    tail) when the worker fails, times out or prints no result.
    """
    if method not in METHODS:
        raise ConfigError(f"method {method!r} is unknown: use one of {', '.join(METHODS)}")
    if not (isinstance(threads, int) and threads >= 1):
        raise ConfigError(f"threads {threads!r} must be an integer >= 1")
    if (end_time is None) == (steps is None):
        raise ConfigError("give exactly one of end_time and steps")
    scene = str(scene_path)
    if scene != "default":
        resolved = Path(scene).expanduser().resolve()
        if not resolved.is_file():
            raise ConfigError(f"scene {scene_path} (resolved {resolved}) is not a file")
        scene = str(resolved)
    # -P: the current folder is not put first on sys.path, so ipsph comes from PYTHONPATH (ours_env)
    cmd = [
        sys.executable,
        "-P",
        "-m",
        "ipsph.bench._ours_worker",
        "--scene",
        scene,
        "--method",
        method,
        "--threads",
        str(threads),
    ]
    if steps is not None:
        cmd += ["--steps", str(int(steps)), "--warmup", str(int(warmup))]
    else:
        cmd += ["--end-time", repr(float(end_time))]
    for item in overrides:
        cmd += ["--set", str(item)]

    return run_json_worker(
        cmd, ours_env(threads, env), timeout, "ipsph worker", f"{scene} method={method}", sample_load
    )
