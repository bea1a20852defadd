"""Test-only failure injection, to check that a failure on one rank stops
every rank (tests/test_reliability.py, docs/INPUT.md).

``PIMPM_INJECT_FAILURE=WHERE:RANK:STEP`` makes rank RANK raise a
RuntimeError when it reaches WHERE during step STEP (1-based; for
``output``, the output written after step STEP; 0 is the initial output).
WHERE is one of ``step`` (the start of a step), ``residual`` (inside the
SNES residual callback), ``jacobian`` (inside the SNES Jacobian callback: a
PETSc.Error, as PETSc raises when a collective call fails on some ranks
only, or on all; :func:`pimpm.solver.failed_on_some_rank`) or ``output``
(inside the HDF5 write). RANK -1 is every rank. Unset, it costs one
dictionary look-up per call site.
"""
import os

POINTS = ("step", "residual", "jacobian", "output")
#: the PETSc error code the ``jacobian`` point raises (PETSC_ERR_ARG_INCOMP)
PETSC_ERROR = 75


def parse_injection(variable, what, choices):
    """``(choice, rank, step)`` from the environment variable ``variable``
    (``WHAT:RANK:STEP``, WHAT one of ``choices``), or None when unset."""
    text = os.environ.get(variable, "")
    if not text:
        return None
    choice, rank, step = text.split(":")
    if choice not in choices:
        raise ValueError(f"{variable} = {text!r}: expected {what}:RANK:STEP with {what} "
                         f"one of {', '.join(choices)}")
    return choice, int(rank), int(step)


_PLAN = parse_injection("PIMPM_INJECT_FAILURE", "WHERE", POINTS)


def checkpoint(where, rank, step):
    """Raise the injected failure if this is its place, rank and step."""
    if _PLAN is not None and _PLAN[0] == where and _PLAN[1] in (rank, -1) and _PLAN[2] == step:
        if where == "jacobian":
            from petsc4py import PETSc
            raise PETSc.Error(PETSC_ERROR)
        raise RuntimeError(f"injected failure (PIMPM_INJECT_FAILURE) at {where}, rank {rank}, step {step}")
