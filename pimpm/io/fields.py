"""What a simulation writes at an output step: particle fields (material
particles, then rigid ones) and the grid fields of the last step."""
import numpy as np

from .. import faults
from ..materials import von_mises

#: the grid fields with one value per node (kept per dof, repeated, as the step's arrays)
SCALAR_GRID_FIELDS = ("mass", "contact_status", "contact_pressure")


def particle_fields(sim):
    p, r = sim.particles, sim.rigid
    nr = len(r)
    J = np.linalg.det(p["F"])
    return {
        "position": np.concatenate([p["x"], r["x"]]),
        "displacement": np.concatenate([p["x"] - p["x0"], r["x"] - r["x0"]]),
        "velocity": np.concatenate([p["v"], r["v"]]),
        "stress": np.concatenate([p["stress"], np.zeros((nr, 3, 3))]),
        "von_mises": np.concatenate([von_mises(p["stress"]), np.zeros(nr)]),
        # sigma_1 - sigma_2 of the in-plane stress (photoelastic fringes, G&W eq. 22)
        "principal_stress_difference": np.concatenate([np.sqrt(
            (p["stress"][:, 0, 0] - p["stress"][:, 1, 1]) ** 2 + 4.0 * p["stress"][:, 0, 1] ** 2),
            np.zeros(nr)]),
        "J": np.concatenate([J, np.ones(nr)]),
        "body": np.concatenate([p["body"], r["body"]]),
        "id": np.concatenate([p["id"], r["id"]]),
        # the history fields the materials' models declare as output (plastic strain, work)
        **{name: np.concatenate([p["h_" + name], np.zeros((nr,) + p["h_" + name].shape[1:])])
           for name in dict.fromkeys(n for m in sim.materials for n in m.model.output)},
        **contact_fields(sim),
    }


def contact_fields(sim):
    """With contact tools: each particle's contact state at the last step (0
    open, 1 stick, 2 slip, the most slipping over the tools) and the force the
    tools exert on it (pimpm.terms.contact); nothing otherwise."""
    tools = sim.contact_tools
    if not tools:
        return {}
    p, nr = sim.particles, len(sim.rigid)
    status = np.max([p[t.output_fields[0]] for t in tools], axis=0).astype(p["body"].dtype)
    force = np.sum([p[t.output_fields[1]] for t in tools], axis=0)
    return {"contact_status": np.concatenate([status, np.zeros(nr, dtype=status.dtype)]),
            "contact_force": np.concatenate([force, np.zeros((nr, sim.dim))])}


def grid_fields(sim):
    """Grid fields of the last step on owned nodes, x axis first (before the
    first step: the nodal state of the particles)."""
    grid = sim.grid
    if sim.last_grid is None:
        n = grid.n_owned_nodes * sim.dim
        node_index, S, _ = sim.footprint()
        mass, velocity, acceleration, _ = sim.nodal_state(node_index, S)
        sim.last_grid = {"mass": mass, "velocity": velocity, "acceleration": acceleration,
                         "displacement_increment": np.zeros(n), **sim.fields.node_contact(grid)}
    out = {}
    for name, values in sim.last_grid.items():
        view = grid.owned_view(values)
        out[name] = view[..., 0] if name in SCALAR_GRID_FIELDS else view
    return out


def write_results(sim, writer):
    """One output step of ``sim`` through a ResultWriter. Collective."""
    faults.checkpoint("output", sim.comm.rank, sim.step_index)
    writer.write_step(sim.step_index, sim.time, particle_fields(sim), grid_fields(sim),
                      sim.grid.owned_box())
