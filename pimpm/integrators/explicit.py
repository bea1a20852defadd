"""Explicit MPM (MPM introduction, eq. 1-10) as a time scheme: its CFL step
and the check of a fixed step against it. The step itself (update-stress-last,
its modified form or update-stress-first) is :mod:`pimpm.steps.explicit`."""
import numpy as np
from mpi4py import MPI

from ..kernels.stress import largest_speed_squared


def stable_time_step(particles, table, grid, cfl, comm):
    """CFL limit dt = cfl * h / max_p (c + |v_p|) (MPM intro), with c the
    dilatational wave speed of each particle's material (``table``: the
    particles' :class:`pimpm.materials.table.MaterialTable`). Collective."""
    h = float(np.min(grid.spacing))
    speed = 0.0
    largest = np.empty(len(table.groups))
    largest_speed_squared(np.ascontiguousarray(particles["v"]), table.material_of, largest)
    for (material, index), speed2 in zip(table.groups, largest):
        if len(index):
            speed = max(speed, material.wave_speed() + np.sqrt(speed2))
    speed = comm.allreduce(speed, op=MPI.MAX)
    return cfl * h / speed


class Explicit:
    name = "explicit"
    explicit = True
    dynamic = True
    parameters = {}

    def check_time_step(self, sim):
        """A fixed ``time.dt`` above the stability limit is refused; returns
        the message or None. Collective."""
        time = sim.config["time"]
        if time["dt"] is not None:
            limit = sim.stable_time_step() / time["cfl"]
            if time["dt"] > limit:
                return (f"time.dt = {time['dt']!r}: expected at most the explicit stability limit "
                        f"h / (c + |v|) = {limit:.6g} (omit time.dt for an automatic "
                        f"step of time.cfl = {time['cfl']} times it)")
        return None
