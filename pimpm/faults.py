"""Test-only failure injection, to check that a failure on one rank stops
every rank (tests/test_reliability.py, docs/INPUT.md).

``PIMPM_INJECT_FAILURE=WHERE:RANK:STEP`` makes rank RANK raise a
RuntimeError when it reaches WHERE during step STEP (1-based; for
``output``, the output written after step STEP; 0 is the initial output).
WHERE is one of ``step`` (the start of a step), ``residual`` (inside the
SNES residual callback) or ``output`` (inside the HDF5 write). Unset, it
costs one dictionary look-up per call site.
"""
import os

POINTS = ("step", "residual", "output")


def _parse(text):
    if not text:
        return None
    where, rank, step = text.split(":")
    if where not in POINTS:
        raise ValueError(f"PIMPM_INJECT_FAILURE = {text!r}: expected WHERE:RANK:STEP with WHERE "
                         f"one of {', '.join(POINTS)}")
    return where, int(rank), int(step)


_PLAN = _parse(os.environ.get("PIMPM_INJECT_FAILURE", ""))


def checkpoint(where, rank, step):
    """Raise the injected failure if this is its place, rank and step."""
    if _PLAN is not None and _PLAN == (where, rank, step):
        raise RuntimeError(f"injected failure (PIMPM_INJECT_FAILURE) at {where}, rank {rank}, step {step}")
