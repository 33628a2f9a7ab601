"""Shared test fixtures."""

import os
import subprocess
import sys

import pytest


def missing(why: str) -> None:
    """Skip a test whose tool this machine lacks; under CI=true fail instead: CI installs it (.ci/run)."""
    if os.environ.get("CI") == "true":
        pytest.fail(f"CI must run this test: {why} (.ci/run installs what it needs)")
    pytest.skip(why)


@pytest.fixture(scope="session")
def gl():
    """Offscreen GL (EGL) for the renders: skipped without it here, a failure under CI=true."""
    from ipsph.post.render import gl_available

    ok, reason = gl_available()
    if not ok:
        missing(f"no offscreen GL: {reason}")


@pytest.fixture(autouse=True)
def _restore_numba_threads():
    """Tests that run the CLI with --threads must not change the thread count of later tests."""
    import numba

    n = numba.get_num_threads()
    yield
    numba.set_num_threads(n)


@pytest.fixture(scope="session", autouse=True)
def _compile_kernels_on_the_other_core():
    """A fresh clone (CI) starts with an empty Numba cache, and most of the suite's time is compiling:
    compile the three methods' kernels, then their field-wall passes (ipsph/run/jit_signatures.json,
    as `ipsph run`'s helper does) in a background process at a lower priority while the first tests
    run, so that later tests load them. A test that needs a kernel first compiles it itself; the
    cache's writes are atomic."""
    from ipsph.run import jit_warm

    if os.environ.get("IPSPH_NO_JIT_HELPER"):
        yield
        return
    code = (
        "import os; os.nice(10); from ipsph.run import jit_warm; "
        "[jit_warm.compile_backwards(k) for k in jit_warm.KINDS if jit_warm.missing_from_cache(k)]"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", code],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    yield
    jit_warm.stop(proc)
