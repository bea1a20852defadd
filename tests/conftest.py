"""Markers: ``mpi`` (the test runs pimpm or a check in subprocesses, mostly
under mpiexec; set here from the sources of the test, its fixtures and the
test modules' functions they call) and ``slow`` (set on the test). ``make test-fast``
runs neither: ``pytest -m "not mpi and not slow"``."""
import inspect

import pytest

#: what starts pimpm in another process: mpiexec (tests/helpers.py and the
#: tests' own runners) or a plain subprocess
MPI_RUNNERS = ("run_mpi(", "run_pimpm(", "run_on_ranks(", "run_with_failure(", "mpiexec", "MPIEXEC",
               "subprocess.", "Popen(")


def pytest_configure(config):
    config.addinivalue_line("markers", "mpi: runs pimpm or a check in subprocesses (mostly under mpiexec)")
    config.addinivalue_line("markers", "slow: takes more than a few seconds")


def _source(function):
    try:
        return inspect.getsource(function)
    except (OSError, TypeError):
        return ""


def _with_callees(functions, depth=3):
    """The functions and the test modules' own functions they call, to
    ``depth`` levels (a test that runs pimpm through a helper of its module)."""
    seen, frontier = [], [f for f in functions if f is not None]
    for _ in range(depth):
        following = []
        for function in frontier:
            if function in seen or not inspect.isfunction(function):
                continue
            seen.append(function)
            module_globals = function.__globals__
            if not module_globals.get("__name__", "").startswith(("test_", "helpers", "conftest")):
                continue
            code = function.__code__
            names = set(code.co_names) | {n for c in code.co_consts if inspect.iscode(c) for n in c.co_names}
            following += [module_globals[n] for n in names if inspect.isfunction(module_globals.get(n))]
        frontier = following
    return seen + [f for f in frontier if inspect.isfunction(f)]


def pytest_collection_modifyitems(config, items):
    """Mark ``mpi`` every test whose function, or a fixture it uses, starts
    mpiexec."""
    for item in items:
        functions = [getattr(item, "function", None)]
        fixture_info = getattr(item, "_fixtureinfo", None)
        if fixture_info is not None:
            for definitions in fixture_info.name2fixturedefs.values():
                functions += [definition.func for definition in definitions]
        source = "".join(_source(f) for f in _with_callees(functions))
        if any(runner in source for runner in MPI_RUNNERS):
            item.add_marker(pytest.mark.mpi)
