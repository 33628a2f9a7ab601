"""A cold first run compiles on both cores: a helper process compiles the method's kernels from the end.

Numba compiles one kernel at a time, on one core. The first run of a method (empty Numba cache)
spends almost all of its first minute there: about 20 kernels, sampling's first, then the step's.
When the cache lacks a kernel of the method that is about to run, `start` launches
`python -m ipsph.run.jit_warm METHOD`: it compiles the same kernels, with the signatures the run will
use, in REVERSE order of first use, and writes each to the Numba cache. The run compiles from the
front as usual; whenever it reaches a kernel the helper has already cached, Numba loads it in
milliseconds. The two meet in the middle, so on an otherwise idle 2-core machine the compiling
takes about half as long. A warm cache starts no helper (a few `stat` calls decide).

The signatures are recorded, per run kind and in first-compile order, in `jit_signatures.json`
beside this file. A run kind is a method, or a method against field walls ("ipsph+field"), whose
density and projection passes are kernels of their own: `run_kind` names a scene's.
`python -m scripts.jit_record` regenerates the file (a cold run of the coarse default scene per
kind, in a subprocess with an empty cache); tests/test_jit_warm.py fails when a kernel or signature
a kind uses is missing from it.
"""

from __future__ import annotations

import importlib
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

from ..params import FIELD_WALLS, METHOD_NAMES

SIGNATURES_FILE = Path(__file__).with_name("jit_signatures.json")
METHODS = METHOD_NAMES
KINDS = METHODS + tuple(f"{m}+{FIELD_WALLS}" for m in METHODS)  # the run kinds the signature file records


def run_kind(method: str, boundary_model: str) -> str:
    """The signature file's key for a run of `method` against `boundary_model`'s walls."""
    return f"{method}+{FIELD_WALLS}" if boundary_model == FIELD_WALLS else method


def kind_overrides(kind: str) -> list[str]:
    """The scene overrides that make the default scene a run of `kind` (for the recorder and its test)."""
    method, _, model = kind.partition("+")
    return [f"simulation.method={method}"] + ([f"simulation.boundary_model={model}"] if model else [])


def _types_namespace() -> dict:
    from numba import types

    ns = {k: v for k, v in vars(types).items() if not k.startswith("_")}
    ns["bool"] = types.boolean
    return ns


def _parse(sig: list[str]) -> tuple:
    ns = _types_namespace()
    return tuple(eval(s, {"__builtins__": {}}, ns) for s in sig)  # noqa: S307 - our own file, numba type reprs


def load_signatures() -> dict[str, list[tuple[str, str, list[str]]]]:
    try:
        return json.loads(SIGNATURES_FILE.read_text())["methods"]
    except (OSError, ValueError, KeyError):
        return {}


def _dispatcher(module: str, qualname: str):
    obj = importlib.import_module(module)
    for part in qualname.split("."):
        obj = getattr(obj, part)
    return obj


def missing_from_cache(kind: str) -> int:
    """How many of run `kind`'s kernels have no Numba cache index yet (0: warm; checks files only)."""
    n = 0
    for module, qualname, _ in load_signatures().get(kind, []):
        try:
            index = Path(_dispatcher(module, qualname)._cache._cache_file._index_path)
        except Exception:  # not a cached dispatcher any more: the file is stale, say cold
            n += 1
            continue
        n += not index.is_file()
    return n


def start(kind: str):
    """Start the helper when run `kind`'s kernels are not all cached; returns the Popen (or None)."""
    if os.environ.get("IPSPH_NO_JIT_HELPER") or not load_signatures().get(kind):
        return None
    if missing_from_cache(kind) == 0:
        return None
    # its own session: a terminal's Ctrl-C goes to the run, which stops the helper (`stop`)
    return subprocess.Popen(
        [sys.executable, "-m", "ipsph.run.jit_warm", kind],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )


def stop(proc) -> None:
    """End the helper (its cache writes are atomic: a half-written kernel is never seen)."""
    if proc is None or proc.poll() is not None:
        return
    proc.send_signal(signal.SIGTERM)
    try:
        proc.wait(5.0)
    except subprocess.TimeoutExpired:  # pragma: no cover
        proc.kill()
        proc.wait()


def compile_backwards(kind: str, limit: int | None = None) -> list[str]:
    """Compile (or load from the cache) run `kind`'s kernels, last-used first; returns their names."""
    done = []
    entries = list(reversed(load_signatures().get(kind, [])))
    for module, qualname, sig in entries[:limit]:
        try:
            _dispatcher(module, qualname).compile(_parse(sig))
        except Exception:  # a stale entry costs only its own kernel: the run compiles it itself
            continue
        done.append(f"{module}.{qualname}")
    return done


def main(argv: list[str]) -> int:
    if len(argv) in (1, 2) and argv[0] in KINDS:
        try:
            os.nice(5)  # the run itself comes first
        except OSError:  # pragma: no cover
            pass
        compile_backwards(argv[0], int(argv[1]) if len(argv) == 2 else None)
        return 0
    print("usage: python -m ipsph.run.jit_warm KIND [LIMIT]  (KIND: a method, or METHOD+field)", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
