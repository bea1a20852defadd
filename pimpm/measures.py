"""Measured quantities of the validation problems, defined once for the
scripts and tests that report them.

* The billet's **bulge** (Guilkey & Weiss 5.1): the horizontal displacement
  of the billet particle that starts at the outer edge of the symmetry plane
  y = 0, i.e. among the body's particles with the lowest initial y, the one
  with the largest initial x.
* The upset cylinder's **radius at mid-height** (Sulsky & Kaul 3.2.7): the
  largest radius of its particles within two cells of the symmetry plane.
* A body's **mean displacement** along a direction (mass-weighted): the
  block's slide down the inclined ramp.
* The self-weight column's **stress error**: sigma_yy of every particle
  against the exact -rho g (L - Y) at its initial height Y, over rho g L.
"""
import numpy as np


def mean_displacement(sim, direction):
    """The mass-weighted mean displacement of the material particles along
    ``direction`` (a unit vector), e.g. a block's slide down a ramp
    (collective)."""
    p = sim.particles
    moved = float(np.sum(p["mass"] * ((p["x"] - p["x0"]) @ np.asarray(direction, dtype=float))))
    return sim.comm.allreduce(moved) / sim.mass0


def edge_particle_id(ids, x0, body, body_index=0, comm=None):
    """Id of the particle of body ``body_index`` that starts on the lowest
    row (smallest initial y) farthest out in x. Arrays are this rank's
    particles; with ``comm`` the search spans all ranks (collective)."""
    mine = body == body_index
    y_min = float(x0[mine, 1].min()) if np.any(mine) else np.inf
    if comm is not None:
        y_min = comm.allreduce(y_min, op=_mpi_op("MIN"))
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
    return local if comm is None else comm.allreduce(local, op=_mpi_op("MAX"))


def _mpi_op(name):
    from mpi4py import MPI      # imported here: scripts that only read files need no MPI
    return getattr(MPI, name)


def column_stress_error(particles, density, gravity, height, comm=None):
    """(max, RMS) over all particles of |sigma_yy + rho g (L - Y)| / (rho g L)
    for a column of height L under gravity g (Y: initial height). Collective
    with ``comm``."""
    exact = -density * gravity * (height - particles["x0"][:, 1])
    error = (particles["stress"][:, 1, 1] - exact) / (density * gravity * height)
    local = (float(np.max(np.abs(error))) if len(error) else 0.0, float(np.sum(error ** 2)), len(error))
    if comm is None:
        worst, squares, count = local
    else:
        worst = comm.allreduce(local[0], op=_mpi_op("MAX"))
        squares, count = comm.allreduce(local[1]), comm.allreduce(local[2])
    return worst, float(np.sqrt(squares / count))


def lattice_j_drift(particles, spacing, region, comm):
    """How far the stored J = det F of particles started on a regular 2D
    lattice (spacing ``spacing``) has drifted from the J their positions
    imply: the mean stored J over the particles whose initial position
    satisfies ``region`` (and that have all four lattice neighbours),
    divided by the mean determinant of the finite-difference deformation
    gradient of the lattice (central differences of the current positions
    over the initial lattice), minus 1. Collective; every rank gets it."""
    p = particles
    mine = (p["x0"], p["x"], np.linalg.det(p["F"]))
    gathered = comm.gather(mine, root=0)
    drift = None
    if comm.rank == 0:
        x0, x, J = (np.concatenate([g[k] for g in gathered]) for k in range(3))
        index = np.rint((x0 - x0.min(axis=0)) / spacing).astype(np.int64)
        width = int(index[:, 1].max()) + 3
        key = (index[:, 0] + 1) * width + (index[:, 1] + 1)
        order = np.argsort(key)
        sorted_key = key[order]

        def neighbour(di, dj):
            k = key + di * width + dj
            at = np.clip(np.searchsorted(sorted_key, k), 0, len(k) - 1)
            return order[at], sorted_key[at] == k

        (e, he), (w, hw), (n, hn), (s, hs) = (neighbour(1, 0), neighbour(-1, 0),
                                              neighbour(0, 1), neighbour(0, -1))
        use = region(x0) & he & hw & hn & hs
        dX = (x[e[use]] - x[w[use]]) / (2.0 * spacing)      # d x / d X
        dY = (x[n[use]] - x[s[use]]) / (2.0 * spacing)      # d x / d Y
        J_lattice = dX[:, 0] * dY[:, 1] - dX[:, 1] * dY[:, 0]
        drift = float(np.mean(J[use]) / np.mean(J_lattice) - 1.0) if np.any(use) else float("nan")
    return comm.bcast(drift, root=0)


def hole_peak_stress(x0, stress, radius, component=(1, 1), sector_degrees=3.0, window=0.15):
    """The peak hoop stress of a plate with a circular hole of ``radius``
    centred at the origin, loaded along y: the particles' stress component
    ``component`` (sigma_yy) within ``sector_degrees`` of the ligament y = 0
    and within ``window`` radii of the hole's edge (by initial position
    ``x0``), fitted by a quadratic in r - a (least squares) and evaluated at
    the edge r = a. Particles sit inside the body, at least a fraction of a
    sub-cell from the edge, where the stress falls by about 7 sigma / a per
    unit distance, so the largest particle stress understates the peak.
    Arrays hold all particles (gather first); ``stress`` is (n, 3, 3) or
    (n, 9). Returns (extrapolated peak, largest particle value in the
    band, number of particles fitted)."""
    stress = np.asarray(stress).reshape(len(x0), 3, 3)
    value = stress[:, component[0], component[1]]
    r = np.linalg.norm(x0[:, :2], axis=1)
    angle = np.degrees(np.arctan2(x0[:, 1], x0[:, 0]))
    band = (angle < sector_degrees) & (r < radius * (1.0 + window))
    coefficients = np.polyfit(r[band] - radius, value[band], 2)
    return float(np.polyval(coefficients, 0.0)), float(value[band].max()), int(band.sum())
