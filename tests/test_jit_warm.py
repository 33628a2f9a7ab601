"""The cold-start compile helper (ipsph/run/jit_warm.py): its signature list matches what the methods
compile, and the helper really fills the Numba cache so that the run loads instead of compiling."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from ipsph.run import jit_warm

REPO = Path(__file__).resolve().parents[1]

_USED = """
import gc, json, sys, tempfile
from pathlib import Path
from numba.core.registry import CPUDispatcher
from ipsph.run import runner
from ipsph.scene import default_scene_path, load_scene
from ipsph.run.jit_warm import kind_overrides
scene = load_scene(default_scene_path(), kind_overrides(sys.argv[1]) + ["simulation.particle_radius=0.04",
                                                                        "simulation.end_time=0.08"])
with tempfile.TemporaryDirectory() as tmp:
    runner.run(scene, runner.RunOptions(out_dir=Path(tmp) / "out", render=False, progress=False))
used = sorted({(d.py_func.__module__, d.py_func.__qualname__, tuple(repr(t) for t in sig))
               for d in gc.get_objects() if isinstance(d, CPUDispatcher) and d.py_func.__module__.startswith("ipsph.")
               for sig in d.signatures})
print(json.dumps(used))
"""


# The field kinds are not held to this here: with a warm cache their prange launchers load whole and
# the wrappers they call (cpu_field._project_one, ...) are never seen, so the comparison would depend
# on the cache's state. Recording only top-level compiles would let them join (next step).
@pytest.mark.parametrize("method", jit_warm.METHODS)
@pytest.mark.slow
def test_the_signature_list_holds_every_kernel_a_method_runs(method):
    """Fails when a kernel is added or its argument types change without `python -m scripts.jit_record`
    (the helper would then compile the wrong thing and the cold start would not gain)."""
    env = dict(os.environ, IPSPH_NO_JIT_HELPER="1")
    out = subprocess.run(
        [sys.executable, "-c", _USED, method], capture_output=True, text=True, env=env, cwd=REPO, timeout=600
    )
    assert out.returncode == 0, out.stderr
    used = {(m, q, tuple(s)) for m, q, s in json.loads(out.stdout.strip().splitlines()[-1])}
    listed = {(m, q, tuple(s)) for m, q, s in jit_warm.load_signatures()[method]}
    assert used - listed == set(), "run `python -m scripts.jit_record`"
    assert listed - used == set(), "the list names kernels this method no longer runs"


def test_the_signature_file_is_the_recorder_s_output():
    """jit_signatures.json is generated (`python -m scripts.jit_record`, which also has `--check`), never
    edited by hand: its text is exactly what the recorder writes for its content, and the test
    above holds that content to what the methods compile."""
    from scripts import jit_record

    text = jit_warm.SIGNATURES_FILE.read_text()
    assert text == jit_record.render_signatures(json.loads(text)["methods"]), "run `python -m scripts.jit_record`"


def test_signatures_parse_back_to_numba_types():
    from numba.core.types import Type

    for entries in jit_warm.load_signatures().values():
        for _, _, sig in entries:
            types = jit_warm._parse(sig)
            assert all(isinstance(t, Type) for t in types) and [repr(t) for t in types] == sig


@pytest.mark.slow
def test_the_helper_fills_an_empty_cache_so_the_run_loads_instead_of_compiling(tmp_path):
    """The helper compiles from the END of the list: with LIMIT 1 it writes the method's last kernel
    (a small one) into the (empty) cache; a fresh process then finds it there (no compile event)."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    last = jit_warm.load_signatures()["pf"][-1:]
    probe = "import sys; from ipsph.run import jit_warm; print(jit_warm.missing_from_cache('pf'))"
    before = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, env=env, cwd=REPO)
    assert int(before.stdout) == len(jit_warm.load_signatures()["pf"])  # empty: everything missing
    res = subprocess.run(
        [sys.executable, "-m", "ipsph.run.jit_warm", "pf", "1"],
        capture_output=True,
        text=True,
        env=env,
        cwd=REPO,
        timeout=600,
    )
    assert res.returncode == 0, res.stderr
    after = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, env=env, cwd=REPO)
    assert int(after.stdout) == len(jit_warm.load_signatures()["pf"]) - 1
    check = f"""
import json
from numba.core import event
from ipsph.run import jit_warm
compiled = []
class L(event.Listener):
    def on_start(self, ev): pass
    def on_end(self, ev): compiled.append(ev.data["dispatcher"].py_func.__qualname__)
event.register("numba:compile", L())
for module, qualname, sig in {last!r}:
    jit_warm._dispatcher(module, qualname).compile(jit_warm._parse(sig))
print(json.dumps(compiled))
"""
    loaded = subprocess.run([sys.executable, "-c", check], capture_output=True, text=True, env=env, cwd=REPO)
    assert loaded.returncode == 0, loaded.stderr
    assert json.loads(loaded.stdout) == []  # it came from the helper's cache entry


def test_a_warm_cache_starts_no_helper(monkeypatch):
    monkeypatch.setattr(jit_warm, "missing_from_cache", lambda method: 0)
    assert jit_warm.start("ipsph") is None
    monkeypatch.setenv("IPSPH_NO_JIT_HELPER", "1")
    monkeypatch.setattr(jit_warm, "missing_from_cache", lambda method: 5)
    assert jit_warm.start("ipsph") is None
