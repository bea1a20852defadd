"""Stopping a run on SIGTERM, SIGINT or SIGHUP (a closed terminal) without
losing it (docs/RELIABILITY.md).

The command line installs :func:`install`: the first signal only raises a
flag; the time loop and the residual callback reduce that flag over the
ranks (so a signal that reached one rank stops all of them at the same
point), the step in progress is abandoned, a checkpoint of the last good
step and its output are written, and every rank exits with 128 + the
signal's number (143 for SIGTERM, 130 for SIGINT, 129 for SIGHUP). A second signal stops
the process at once.

Under OpenMPI a signal to mpiexec reaches the ranks as SIGTERM about one
second later, and mpiexec kills them about one second after that: enough for
the checkpoint of a moderate problem (checkpoints are written aside and
renamed, so a kill in the middle leaves the previous one intact).

Test-only: ``PIMPM_INJECT_SIGNAL=NAME:RANK:STEP`` makes rank RANK send itself
the signal NAME (TERM, INT or HUP) at the start of step STEP, through the real
handler.
"""
import os
import signal

import numpy as np
from mpi4py import MPI

from .faults import parse_injection

SIGNALS = {"TERM": signal.SIGTERM, "INT": signal.SIGINT, "HUP": signal.SIGHUP}

#: the first signal received (0: none)
received = 0


class Interrupted(Exception):
    """Raised on every rank, at the same point, once a signal is known to all."""

    def __init__(self, signum):
        super().__init__(f"interrupted by {signal.Signals(signum).name}")
        self.signum = signum

    @property
    def exit_status(self):
        return 128 + self.signum


def _handler(signum, frame):
    global received
    if received:                               # a second signal: stop now
        os._exit(128 + signum)
    received = signum


def install():
    """Catch SIGTERM, SIGINT and SIGHUP (the command line does; library use does not)."""
    for sig in SIGNALS.values():
        signal.signal(sig, _handler)


def agreed(comm, local_count=0):
    """(largest ``local_count`` over the ranks, the signal any rank received
    or 0). Collective: one allreduce carries both."""
    flags = np.array([local_count, received], dtype=np.int64)
    comm.Allreduce(MPI.IN_PLACE, flags, op=MPI.MAX)
    return int(flags[0]), int(flags[1])


def check(comm):
    """Raise Interrupted on every rank if any rank received a signal. Collective."""
    signum = comm.allreduce(received, op=MPI.MAX)
    if signum:
        raise Interrupted(signum)


_PLAN = parse_injection("PIMPM_INJECT_SIGNAL", "NAME", tuple(SIGNALS))
if _PLAN is not None:
    _PLAN = (SIGNALS[_PLAN[0]],) + _PLAN[1:]


def inject(rank, step):
    """Send the injected signal to this process if this is its rank and step."""
    if _PLAN is not None and _PLAN[1:] == (rank, step):
        os.kill(os.getpid(), _PLAN[0])
