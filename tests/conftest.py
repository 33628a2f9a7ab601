"""Shared test fixtures."""

import pytest


@pytest.fixture(autouse=True)
def _restore_numba_threads():
    """Tests that run the CLI with --threads must not change the thread count of later tests."""
    import numba

    n = numba.get_num_threads()
    yield
    numba.set_num_threads(n)
