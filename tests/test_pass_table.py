"""The pass table (ipsph/backends/passes.py): each row's CPU launcher stands in its home module under
the row's name (where numba's cache and jit_signatures.json look for it), takes the row's inputs and
hands the body every parameter. The launchers' results: tests/test_pair_cache.py and the others;
the CUDA kernels built from the same rows: tests/test_cuda_backend.py."""

import importlib
import inspect

from ipsph.backends.base import LISTS, WALLS
from ipsph.backends.passes import PASSES, source


def test_every_row_has_a_cpu_launcher_in_its_home_under_its_name():
    for p in PASSES.values():
        module = importlib.import_module(f"ipsph.backends.{p.home}")
        launcher = getattr(module, p.name)
        assert (launcher.py_func.__module__, launcher.py_func.__qualname__) == (module.__name__, p.name)
        assert tuple(inspect.signature(launcher.py_func).parameters) == p.inputs, p.name
        assert inspect.getfile(launcher.py_func) == module.__file__, "the disk cache keys a launcher on its file"
        if p.wrapper:
            assert getattr(module, p.wrapper).py_func.__qualname__ == p.wrapper


def test_a_launcher_hands_its_body_every_parameter():
    for p in PASSES.values():
        assert set(p.params) - {"buf"} <= set(p.inputs) | set(p.derives), p.name
        assert ("buf" in p.params) == (p.rows > 0), f"{p.name}: a scratch block exactly when the body takes buf"
        assert p.over in p.inputs and not set(p.inputs) & set(p.derives), p.name
        text = source(p, "", ["for i in range({n}):"])
        compile(text, p.name, "exec")  # the generated launcher is valid Python


def test_the_names_run_pass_fills_in_are_never_a_body_s_scratch_or_index():
    for p in PASSES.values():
        bound = {a for a in p.inputs if a in LISTS or a in WALLS or a == "mirror"}
        assert "i" not in p.inputs and "buf" not in bound, p.name
