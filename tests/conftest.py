"""Markers: ``mpi`` (the test runs pimpm or a check under mpiexec, set here
from the test's source) and ``slow`` (set on the test). ``make test-fast``
runs neither: ``pytest -m "not mpi and not slow"``."""
import inspect

import pytest

#: calls that start mpiexec (tests/helpers.py and the tests' own runners)
MPI_RUNNERS = ("run_mpi(", "run_pimpm(", "run_on_ranks(", "run_with_failure(", "mpiexec")


def pytest_configure(config):
    config.addinivalue_line("markers", "mpi: runs pimpm or a check under mpiexec (subprocesses)")
    config.addinivalue_line("markers", "slow: takes more than a few seconds")


def pytest_collection_modifyitems(config, items):
    for item in items:
        function = getattr(item, "function", None)
        try:
            source = inspect.getsource(function) if function is not None else ""
        except (OSError, TypeError):
            source = ""
        if any(runner in source for runner in MPI_RUNNERS):
            item.add_marker(pytest.mark.mpi)
