"""What a problem will need, estimated from its input before anything is
allocated: the number of unknowns against PETSc's index range, and memory
(particles with their kernel buffers, grid vectors, the tangent matrix
preallocated on the DMDA's box stencil) against what the machine has. A
problem that cannot fit is refused with the key to change; ``--check``
prints the estimate. The direct solver's factors come on top and are not
estimated (they depend on the ordering); see docs/PERFORMANCE.md for
measured peaks."""
import os

import numpy as np

#: bytes per particle beyond its history and footprint: fields (x, x0, v, a, F,
#: stress, ...), the Newton iteration's buffers (F_inc, F, stress, tangent
#: density), seeding's and migration's temporaries. Peaks of whole billet runs
#: come to about 3 kB per particle (docs/PERFORMANCE.md)
PARTICLE_FIELDS_BYTES = 8 * 300
#: bytes per node and unknown of the grid vectors (DMDA, SNES, nodal state)
NODE_VECTOR_BYTES = 8 * 40


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
            counts = estimated_particles(config, per_body=True)
            i = int(np.argmax(counts))
            geo = config["bodies"][i]["geometry"]
            where = (f"bodies[{i}].geometry.file = {geo['file']!r} ({geo['particles']} particles)"
                     if "particles" in geo else
                     f"bodies[{i}].particles_per_cell = {config['bodies'][i]['particles_per_cell']}")
        else:
            where = f"grid.cells = {list(cells)}"
        details = ", ".join(f"{k} {describe_bytes(v)}" for k, v in parts.items())
        return (f"{where}: expected a problem that fits in memory: it needs about "
                f"{describe_bytes(need)} ({details}) and this machine has {describe_bytes(have)} available")
    return None


def describe_bytes(n):
    for unit, size in (("TB", 2**40), ("GB", 2**30), ("MB", 2**20)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n / 1024:.3g} kB"


def summary_line(config, ranks):
    _, _, need, parts = estimate(config, ranks)
    have = available_memory()
    return (f"  memory    about {describe_bytes(need)} before the direct solver's factors "
            f"({', '.join(f'{k} {describe_bytes(v)}' for k, v in parts.items())})"
            + (f"; {describe_bytes(have)} available" if have else ""))

