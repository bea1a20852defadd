"""Explicit MPM (MPM introduction, eq. 1-10) as a time scheme: its CFL step
and the check of a fixed step against it. The step itself (update-stress-last,
its modified form or update-stress-first) is :mod:`pimpm.steps.explicit`."""
import numpy as np
from mpi4py import MPI


def stable_time_step(particles, material_groups, grid, cfl, comm):
    """CFL limit dt = cfl * h / max_p (c + |v_p|) (MPM intro), with c the
    dilatational wave speed of each particle's material. Collective."""
    h = float(np.min(grid.spacing))
    speed = 0.0
    speed2 = np.sum(particles["v"] ** 2, axis=1)
    for material, index in material_groups:
        if len(index):
            speed = max(speed, material.wave_speed() + np.sqrt(np.max(speed2[index])))
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
