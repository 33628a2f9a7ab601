"""Shared test fixtures."""

import os

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
