"""Measured quantities of the validation problems, defined once for the
scripts and tests that report them.

* The billet's **bulge** (Guilkey & Weiss 5.1): the horizontal displacement
  of the billet particle that starts at the outer edge of the symmetry plane
  y = 0, i.e. among the body's particles with the lowest initial y, the one
  with the largest initial x.
* The upset cylinder's **radius at mid-height** (Sulsky & Kaul 3.2.7): the
  largest radius of its particles within two cells of the symmetry plane.
"""
import numpy as np


def edge_particle_id(ids, x0, body, body_index=0, comm=None):
    """Id of the particle of body ``body_index`` that starts on the lowest
    row (smallest initial y) farthest out in x. Arrays are this rank's
    particles; with ``comm`` the search spans all ranks (collective)."""
    mine = body == body_index
    y_min = float(x0[mine, 1].min()) if np.any(mine) else np.inf
    if comm is not None:
        y_min = -comm.allreduce(-y_min, op=_max())
    on_plane = mine & (x0[:, 1] == y_min)
    best = (float(x0[on_plane, 0].max()), -int(ids[on_plane][np.argmax(x0[on_plane, 0])])) \
        if np.any(on_plane) else (-np.inf, 0)
    if comm is not None:
        best = max(comm.allgather(best))
    return -best[1]


def bulge(sim, body_index=0):
    """The billet's bulge in a running simulation (collective)."""
    p = sim.particles
    edge = edge_particle_id(p["id"], p["x0"], p["body"], body_index, sim.comm)
    here = p["id"] == edge
    local = float(p["x"][here, 0][0] - p["x0"][here, 0][0]) if np.any(here) else 0.0
    return sim.comm.allreduce(local)


def bulge_from_fields(ids, displacement, edge_id):
    """The bulge from output fields (results.h5): the x displacement of the
    particle ``edge_id`` (from :func:`edge_particle_id` on the first step)."""
    return float(displacement[int(np.flatnonzero(ids == edge_id)[0]), 0])


def midplane_radius(x, body, cell_size, body_index=0, comm=None):
    """Largest radius (x) of body ``body_index``'s particles with y below two
    cells (``cell_size`` the cell height)."""
    band = (body == body_index) & (x[:, 1] < 2.0 * cell_size)
    local = float(x[band, 0].max()) if np.any(band) else -np.inf
    return local if comm is None else comm.allreduce(local, op=_max())


def _max():
    from mpi4py import MPI      # imported here: scripts that only read files need no MPI
    return MPI.MAX
