"""What a problem will need, estimated before anything is allocated: the
number of unknowns against PETSc's index range, and memory (particles with
their kernel buffers, grid vectors, the tangent matrix
preallocated on the DMDA's box stencil) against what the machine has. A
problem that cannot fit is refused with the key to change. Once the bodies
are seeded, :func:`run_estimate` refines it for the summary that ``--check``
and a run print: the particles as seeded, the tangent on the nodes they
reach and the direct solver's factors (docs/PERFORMANCE.md, "What a run's
memory is made of": the constants below are measured there, and a run's
last line prints its peak against this estimate)."""
import os

import numpy as np
from mpi4py import MPI

#: bytes per particle beyond its history and footprint: fields (x, x0, v, a, F,
#: stress, ...), the Newton iteration's buffers (F_inc, F, stress, tangent
#: density), seeding's and migration's temporaries. Peaks of whole billet runs
#: come to about 3 kB per particle (docs/PERFORMANCE.md)
PARTICLE_FIELDS_BYTES = 8 * 300
#: bytes per node and unknown of the grid vectors (DMDA, SNES, nodal state)
NODE_VECTOR_BYTES = 8 * 40
#: resident memory of a rank before the problem's own: Python with numpy,
#: numba's compiled kernels, PETSc, MPI and h5py (the bar in tension: 197 MiB
#: a rank on 1 and 2 ranks; the 2 mm 3D upsetting about 212 MiB)
PROGRAM_BYTES = 205 * 2**20
#: peak resident bytes a material particle adds with GIMP in 2D and 3D (the
#: slope of a run's peak against the particles per cell on a fixed grid:
#: the billet with 2, 4 and 6 particles per cell along each axis, the 1 mm
#: 3D upsetting with 2, 3 and 4); other shape functions differ by their
#: footprint (FOOTPRINT_ENTRY_BYTES a node)
MATERIAL_PARTICLE_BYTES = {2: 1190, 3: 4362}
FOOTPRINT_ENTRY_BYTES = {2: 33, 3: 41}        # S, G, node index, active
#: a rigid particle (the platen's 1,058 to 67,712 particles changed the 1 mm
#: upsetting's peak by less than the runs' noise of 30 MiB)
RIGID_PARTICLE_BYTES = 500
#: bytes per scalar entry of the tangent's pattern on the nodes the material
#: reaches: the block pattern, the COO indices and values, the free dofs'
#: copy and PETSc's two matrices (the 1 mm 3D upsetting: about 74 KiB a
#: reached node, 1,125 entries each)
PATTERN_ENTRY_BYTES = 66
#: MUMPS's memory for a factorization of N free dofs on 2 ranks, c N^p bytes
#: (INFOG(22), all ranks; fitted to the billet at 0.5, 0.25 and 0.125 cm and
#: the 3D upsetting at 2, 1 and 0.5 mm), and what each rank beyond the first
#: adds (the 1 mm upsetting on 1-4 ranks: 83, 117, 128 and 195 MiB)
FACTOR_MODEL = {2: (1.64e4, 0.86), 3: (6.67e3, 1.17)}
FACTOR_PER_RANK = 0.45
#: an iterative solver's preconditioner (GAMG's hierarchy) against the
#: tangent (the 3D upsetting with gmres-gamg: about 10 GB at a million
#: particles on 2 ranks, 779 MiB at 1 mm)
PRECONDITIONER_SHARE = 0.5
#: what the tangent's pattern and the factors grow by as the bodies deform
#: and reach more nodes (the 0.5 mm 3D upsetting: 4.1 GiB at its fourth step,
#: 4.9-5.3 GiB by 60%)
DEFORMATION_GROWTH = 0.25


def estimated_particles(config, per_body=False):
    """Upper bound of the material and rigid particles: each body's bounding
    box in cells times the particles per cell (a list per body if ``per_body``)."""
    dim = config["dim"]
    g = config["grid"]
    h = (np.asarray(g["upper"]) - np.asarray(g["lower"])) / np.asarray(g["cells"])
    counts = []
    for body in config["bodies"]:
        geo = body["geometry"]
        if "particles" in geo:                # geometries from files: counted when read
            counts.append(float(geo["particles"]))
            continue
        if "lower" in geo:
            extent = np.asarray(geo["upper"]) - np.asarray(geo["lower"])
        elif "radius" in geo:
            extent = np.full(dim, 2.0 * geo["radius"])
        else:
            extent = np.asarray(g["upper"]) - np.asarray(g["lower"])
        cells = np.prod(np.ceil(extent / h) + 1.0)
        counts.append(float(cells) * float(np.prod(np.broadcast_to(body["particles_per_cell"], (dim,)))))
    return counts if per_body else sum(counts)


def estimate(config, ranks):
    """(unknowns, largest block-row count of the tangent on one rank, bytes of
    memory for the whole problem, the parts) for a validated config."""
    dim = config["dim"]
    cells = np.asarray(config["grid"]["cells"], dtype=float)
    nodes = float(np.prod(cells + 1.0))
    unknowns = nodes * dim
    width = 1 if config["grid"]["shape_functions"] == "linear" else 2
    blocks_per_row = (2 * width + 1) ** dim
    nodes_per_particle = (width + 1) ** dim
    particles = estimated_particles(config)
    history = 8 * 30
    footprint = 8 * nodes_per_particle * (2 + dim) + 8 * dim ** 4
    parts = {
        "particles": particles * (PARTICLE_FIELDS_BYTES + history + footprint),
        "grid vectors": nodes * dim * NODE_VECTOR_BYTES,
        "tangent matrix": nodes * blocks_per_row * dim * dim * 12.0,
    }
    # entries of one rank's part of the matrix (32-bit row offsets)
    local_entries = nodes * blocks_per_row * dim * dim / max(1, ranks)
    return unknowns, local_entries, sum(parts.values()), parts


def available_memory():
    """Bytes of memory the machine can give (MemAvailable), or None."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError):
        return None


def check(config, ranks, index_bits):
    """A one-line problem (naming the key) if the problem cannot fit, else None."""
    unknowns, local_entries, need, parts = estimate(config, ranks)
    cells = config["grid"]["cells"]
    largest = 2 ** (index_bits - 1) - 1
    if unknowns > largest:
        return (f"grid.cells = {list(cells)}: {unknowns:.4g} unknowns: expected at most {largest} "
                f"(PETSc's {index_bits}-bit indices)")
    if local_entries > largest:
        return (f"grid.cells = {list(cells)}: the tangent would hold {local_entries:.4g} entries per "
                f"rank: expected at most {largest} (PETSc's {index_bits}-bit indices; use more ranks "
                f"or fewer cells)")
    have = available_memory()
    if have is not None and need > have:
        if max(parts, key=parts.get) == "particles":
            where, _ = _fullest_body(config, estimated_particles(config, per_body=True))
        else:
            where = f"grid.cells = {list(cells)}"
        details = ", ".join(f"{k} {describe_bytes(v)}" for k, v in parts.items())
        return (f"{where}: expected a problem that fits in memory: it needs about "
                f"{describe_bytes(need)} ({details}) and this machine has {describe_bytes(have)} available")
    return None


def _fullest_body(config, counts):
    """(the key that sets its particles, its index) of the body with the most
    of ``counts`` (particles per body)."""
    i = int(np.argmax(counts))
    geo = config["bodies"][i]["geometry"]
    if "particles" in geo:                # geometries from files
        return f"bodies[{i}].geometry.file = {geo['file']!r} ({geo['particles']} particles)", i
    return f"bodies[{i}].particles_per_cell = {config['bodies'][i]['particles_per_cell']}", i


def describe_bytes(n):
    for unit, size in (("TB", 2**40), ("GB", 2**30), ("MB", 2**20)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n / 1024:.3g} kB"


def factor_bytes(free_dofs, dim, ranks):
    """MUMPS's memory for a factorization of ``free_dofs`` unknowns on
    ``ranks`` ranks, all of them (FACTOR_MODEL)."""
    c, p = FACTOR_MODEL[dim]
    return c * float(free_dofs) ** p * (1.0 + FACTOR_PER_RANK * (ranks - 1)) / (1.0 + FACTOR_PER_RANK)


#: particles whose footprints are evaluated at once by :func:`reached_nodes`
FOOTPRINT_CHUNK = 50_000


def reached_nodes(sim):
    """The nodes the material particles' shape functions reach, summed over
    the ranks (a node that two ranks' particles reach counts twice: the
    ranks both hold its pattern rows). Collective."""
    grid, particles = sim.grid, sim.particles
    reached = np.zeros(grid.n_local_nodes, dtype=np.bool_)
    if len(particles):
        x, half = particles["x"], sim.particle_half_sizes()
        for start in range(0, len(particles), FOOTPRINT_CHUNK):
            chunk = slice(start, start + FOOTPRINT_CHUNK)
            node_index, S, _ = sim.shape.footprint(x[chunk], grid, half[chunk])
            reached[node_index[S > 0.0]] = True
    return sim.comm.allreduce(int(np.count_nonzero(reached)))


def run_estimate(sim):
    """(bytes, parts) of resident memory the run will need on all ranks
    together, from the bodies as seeded and the solver chosen: the program
    on each rank, the particles, the grid vectors, the tangent's pattern on
    the nodes the material reaches and, for a direct solver, its factors of
    their dofs. Within 20% of the runs' peaks measured in
    docs/PERFORMANCE.md; a body that spreads over more nodes as it deforms
    (an upsetting to 60%) needs more. Collective."""
    dim, ranks = sim.dim, sim.comm.size
    footprint = sim.shape.nodes_per_particle
    per_particle = MATERIAL_PARTICLE_BYTES[dim] + (footprint - 3 ** dim) * FOOTPRINT_ENTRY_BYTES[dim]
    parts = {"program": float(ranks * PROGRAM_BYTES),
             "particles": float(sim.particles.global_count(sim.comm) * per_particle
                                + sim.rigid.global_count(sim.comm) * RIGID_PARTICLE_BYTES),
             "grid vectors": float(np.prod(sim.grid.nodes)) * dim * NODE_VECTOR_BYTES}
    solver = sim.solver
    if solver is not None and not solver.plan.matrix_free:
        nodes = reached_nodes(sim)
        blocks = (2 * sim.shape.stencil_width + 1) ** dim
        parts["tangent matrix"] = float(nodes * blocks * dim * dim * PATTERN_ENTRY_BYTES)
        if solver.free_dofs is not None:
            parts["direct solver's factors"] = factor_bytes(nodes * dim, dim, ranks)
        elif solver.plan.iterative:
            parts["preconditioner"] = PRECONDITIONER_SHARE * parts["tangent matrix"]
        solver_parts = ("tangent matrix", "direct solver's factors", "preconditioner")
        parts["growth as the bodies deform"] = DEFORMATION_GROWTH * sum(parts.get(k, 0.0) for k in solver_parts)
    return sum(parts.values()), parts


def run_memory_problem(sim, need, parts):
    """A one-line problem (naming the key to change) if the run's estimate
    (:func:`run_estimate`) exceeds the memory available on a machine it
    runs on, each machine taking its ranks' share, else None; the same on
    every rank. A direct solver whose factors are what does not fit is
    named with the iterative preset that needs none. Collective."""
    comm = sim.comm
    node = comm.Split_type(MPI.COMM_TYPE_SHARED)
    share = node.size / comm.size
    node.Free()
    have = available_memory()
    short = comm.allreduce(have is not None and need * share > have, op=MPI.LOR)
    if not short:
        return None
    have = comm.allreduce(have if have is not None else np.inf, op=MPI.MIN) / share
    config = sim.config
    details = ", ".join(f"{k} {describe_bytes(v)}" for k, v in parts.items())
    factors = parts.get("direct solver's factors", 0.0) * (1.0 + DEFORMATION_GROWTH)
    if factors and need - factors <= have:
        where = f"solver.preset = {sim.solver.plan.preset!r}"
        hint = ("; without the direct solver's factors it would fit: try -pimpm_preset gmres-gamg "
                "-pimpm_fallback false (or more machines)")
    elif max(parts, key=parts.get) == "particles":
        from .seeding import particles_per_body
        counts = particles_per_body(config, sim.particles, sim.rigid, comm)
        where, body = _fullest_body(config, counts)
        hint = f" ({int(counts[body]):,} particles seeded in that body)"
    else:
        where, hint = f"grid.cells = {list(config['grid']['cells'])}", ""
    machine = ("this machine has" if share == 1.0 else
               "its machines have (the least of them, scaled from its share of the ranks)")
    return (f"{where}: expected a run that fits in memory: it needs about {describe_bytes(need)} "
            f"({details}) and {machine} {describe_bytes(have)} available{hint}")


def summary_line(sim):
    """The summary's ``memory`` line: the run's estimate
    (``sim.memory_estimate`` and ``sim.memory_parts``, :func:`run_estimate`)."""
    need, parts = sim.memory_estimate, sim.memory_parts
    have = available_memory()
    return (f"  memory    about {describe_bytes(need)} "
            f"({', '.join(f'{k} {describe_bytes(v)}' for k, v in parts.items())})"
            + (f"; {describe_bytes(have)} available" if have else ""))
