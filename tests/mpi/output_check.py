"""End-to-end check of pimpm.io.ResultWriter; run under mpiexec (any number of ranks).

    mpiexec -n 3 --oversubscribe python tests/mpi/output_check.py OUTDIR

Every rank writes fake particles (uneven counts, rank 1 has none in the first step
and rank 0 none in the second) and fake grid boxes that tile the node grid along x,
for 2 steps, in 2-D and in 3-D, then reopens the file in append mode and rewrites the
last step. Rank 0 then reads results.h5 and both XDMF files
back and compares every value with what was written. Exit status 0 = all good;
1 = mismatch (listed on stderr). An unexpected exception aborts all ranks.
"""
import os
import sys
import traceback
import xml.etree.ElementTree as ET

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(os.path.dirname(HERE)))  # repo root, for `pimpm`

NODES = {2: (7, 5), 3: (5, 4, 3)}
LOWER = {2: (-1.0, 0.5), 3: (-1.0, 0.5, 2.0)}
SPACING = {2: (0.25, 0.5), 3: (0.25, 0.5, 0.125)}
STEPS = [0, 7]
TIMES = [0.0, 1.0 / 3.0]
PARTICLE_FIELDS = ["position", "displacement", "velocity", "stress", "F", "von_mises",
                   "J", "body", "id", "flag"]
PARTICLE_KINDS = {"position": "Vector", "displacement": "Vector", "velocity": "Vector",
                  "stress": "Tensor", "F": "Tensor", "von_mises": "Scalar", "J": "Scalar",
                  "body": "Scalar", "id": "GlobalId", "flag": "Scalar"}
PARTICLE_DTYPES = {"velocity": np.float32, "body": np.int32, "id": np.int64,
                   "flag": np.uint8}
GRID_FIELDS = ["mass", "velocity", "count", "stress"]
GRID_KINDS = {"mass": "Scalar", "velocity": "Vector", "count": "Scalar", "stress": "Tensor"}
GRID_DTYPES = {"mass": np.float64, "velocity": np.float32, "count": np.int32,
               "stress": np.float64}


# ---------------------------------------------------------------- fake data
def particle_counts(size, k):
    """Particle count of every rank at step index k."""
    if size == 1:
        return [7, 4][k]
    counts = [5 + 3 * r + 2 * k for r in range(size)]
    counts[1 if k == 0 else 0] = 0
    return counts


def particle_ids(size, k):
    """Global ids in file (rank) order and per-rank split, identical on every rank."""
    counts = particle_counts(size, k)
    counts = [counts] if size == 1 else counts
    total = sum(counts)
    ids = np.random.default_rng(1234 + k).permutation(total).astype(np.int64) + 1000 * k
    bounds = np.concatenate([[0], np.cumsum(counts)])
    return ids, [ids[bounds[r]:bounds[r + 1]] for r in range(size)]


def particle_values(ids, dim, k):
    """Fields as the caller passes them (natural dim-sized shapes)."""
    x = ids.astype(np.float64)
    a = np.arange(dim)
    return {
        "position": 0.5 * x[:, None] + a[None, :] + 0.01 * k,
        "displacement": np.sin(x[:, None] + a[None, :]),
        "velocity": np.cos(x[:, None] - a[None, :]).astype(np.float32),
        "stress": 10.0 * x[:, None, None] + np.arange(9.0).reshape(3, 3)[None] + k,
        "F": x[:, None, None] + a[None, :, None] - 2.0 * a[None, None, :],
        "von_mises": np.sqrt(x) + k,
        "J": 1.0 + 1e-3 * x,
        "body": (ids % 3).astype(np.int32),
        "id": ids.astype(np.int64),
        "flag": (ids % 2 == 0),
    }


def pad_vec(v):
    out = np.zeros(v.shape[:-1] + (3,), dtype=v.dtype)
    out[..., :v.shape[-1]] = v
    return out


def pad_ten(t):
    out = np.zeros(t.shape[:-2] + (3, 3), dtype=t.dtype)
    out[..., :t.shape[-2], :t.shape[-1]] = t
    return out.reshape(t.shape[:-2] + (9,))


def stored(values, kinds):
    """What the file must hold for given caller values."""
    out = {}
    for name, v in values.items():
        if kinds[name] == "Vector":
            out[name] = pad_vec(v)
        elif kinds[name] == "Tensor":
            out[name] = pad_ten(v)
        else:
            out[name] = v.astype(np.uint8) if v.dtype == bool else v
    return out


def grid_values(dim, k, index):
    """Grid fields at global node indices index = (I, J[, K]) (arrays of equal shape)."""
    I, J = index[0], index[1]
    K = index[2] if dim == 3 else np.zeros_like(I)
    base = I + 10.0 * J + 100.0 * K + 0.5 * k
    comps = np.arange(dim)
    return {
        "mass": 1.0 + base,
        "velocity": (base[..., None] * 0.1 + 7.0 * comps).astype(np.float32),
        "count": (I * J + K + k).astype(np.int32),
        "stress": base[..., None, None] + 3.0 * comps[:, None] + comps[None, :],
    }


def grid_box(size, rank, dim):
    nodes = NODES[dim]
    xs = np.array_split(np.arange(nodes[0]), size)[rank]
    starts = (int(xs[0]) if len(xs) else 0,) + (0,) * (dim - 1)
    sizes = (len(xs),) + tuple(nodes[1:])
    return starts, sizes


# ---------------------------------------------------------------- writing
def write_case(comm, outdir, dim):
    from pimpm.io import ResultWriter

    rank, size = comm.Get_rank(), comm.Get_size()
    starts, sizes = grid_box(size, rank, dim)
    index = np.meshgrid(*[np.arange(s, s + n) for s, n in zip(starts, sizes)], indexing="ij")
    writer = ResultWriter(comm, outdir, dim, LOWER[dim], SPACING[dim], NODES[dim])
    write_steps(writer, comm, dim, index, starts, sizes, range(len(STEPS)))
    writer.close()
    # restart: reopen in append mode and write the last step again (replaces it)
    writer = ResultWriter(comm, outdir, dim, LOWER[dim], SPACING[dim], NODES[dim], append=True)
    write_steps(writer, comm, dim, index, starts, sizes, [len(STEPS) - 1])
    writer.close()


def write_steps(writer, comm, dim, index, starts, sizes, ks):
    rank, size = comm.Get_rank(), comm.Get_size()
    for k in ks:
        step, time = STEPS[k], TIMES[k]
        _, split = particle_ids(size, k)
        mine = split[rank]
        if len(mine) == 0 and k == 1:
            pfields = {}  # an empty rank may pass nothing at all
        else:
            pfields = particle_values(mine, dim, k)
            if len(mine) == 0:
                pfields["id"] = np.zeros(0)  # sloppy dtype on an empty rank is tolerated
        gfields = grid_values(dim, k, index)
        if rank % 2:
            gfields = dict(reversed(list(gfields.items())))  # dict order must not matter
            pfields = dict(reversed(list(pfields.items())))
        writer.write_step(step, time, pfields, gfields, (starts, sizes))


# ---------------------------------------------------------------- checking
def check_case(outdir, dim, size):
    """Return a list of mismatch messages (empty = all good). Rank 0 only."""
    import h5py

    errs = []

    def expect(cond, msg):
        if not cond:
            errs.append("dim=%d: %s" % (dim, msg))
        return cond

    def same(a, b, msg):
        a, b = np.asarray(a), np.asarray(b)
        ok = a.shape == b.shape and np.array_equal(a, b)
        return expect(ok, "%s differs (shapes %s vs %s)" % (msg, a.shape, b.shape))

    path = os.path.join(outdir, "results.h5")
    nodes = NODES[dim]
    shapes = {}  # h5 path -> (shape, dtype) for the XDMF check
    with h5py.File(path, "r") as f:
        expect(int(f.attrs["dim"]) == dim, "file attr dim")
        same(f.attrs["lower"], LOWER[dim], "file attr lower")
        same(f.attrs["spacing"], SPACING[dim], "file attr spacing")
        same(f.attrs["nodes"], nodes, "file attr nodes")
        names = sorted(f["steps"].keys())
        expect(names == ["%06d" % s for s in STEPS], "step groups %s" % names)
        full = np.meshgrid(*[np.arange(n) for n in nodes], indexing="ij")
        for k, (step, time) in enumerate(zip(STEPS, TIMES)):
            g = f["steps/%06d" % step]
            expect(int(g.attrs["step"]) == step, "step attr of step %d" % step)
            expect(float(g.attrs["time"]) == time, "time attr of step %d" % step)
            # particles
            ids, _ = particle_ids(size, k)
            pg = g["particles"]
            expect(sorted(pg.keys()) == sorted(PARTICLE_FIELDS),
                   "particle fields %s" % sorted(pg.keys()))
            expect(int(pg.attrs["count"]) == len(ids), "particle count attr")
            file_ids = pg["id"][...]
            same(file_ids, ids, "step %d particle ids in rank order" % step)
            order = np.argsort(file_ids)
            want = stored(particle_values(np.sort(ids), dim, k), PARTICLE_KINDS)
            for name in PARTICLE_FIELDS:
                d = pg[name]
                shapes[d.name] = (d.shape, d.dtype)
                same(d[...][order], want[name], "step %d particle %s" % (step, name))
                expect(d.dtype == np.dtype(PARTICLE_DTYPES.get(name, np.float64)),
                       "particle %s dtype %s" % (name, d.dtype))
                expect(d.attrs["AttributeType"] == PARTICLE_KINDS[name],
                       "particle %s AttributeType" % name)
            if dim == 2:
                expect(np.all(pg["position"][:, 2] == 0), "2-D positions z = 0")
            # the Polyvertex connectivity shared by the steps with this count
            conn = f.get("polyvertex/%d" % len(ids))
            if expect(conn is not None, "polyvertex/%d missing" % len(ids)):
                shapes[conn.name] = (conn.shape, conn.dtype)
                same(conn[...], np.arange(len(ids)).reshape(-1, 1), "connectivity 0..n-1")
            # grid
            gg = g["grid"]
            expect(sorted(gg.keys()) == sorted(GRID_FIELDS), "grid fields %s" % sorted(gg.keys()))
            want = stored(grid_values(dim, k, full), GRID_KINDS)
            rev = tuple(range(dim - 1, -1, -1))
            for name in GRID_FIELDS:
                d = gg[name]
                shapes[d.name] = (d.shape, d.dtype)
                w = want[name]
                w = np.transpose(w, rev + tuple(range(dim, w.ndim)))  # to (z,) y, x order
                same(d[...], w, "step %d grid %s" % (step, name))
                expect(d.dtype == np.dtype(GRID_DTYPES[name]), "grid %s dtype" % name)
                expect(d.attrs["AttributeType"] == GRID_KINDS[name], "grid %s type" % name)

    # XDMF
    def check_item(item, what, lead=()):
        ntypes = {"f": "Float", "i": "Int", "u": "UInt"}
        expect(item.get("Format") == "HDF", "%s DataItem Format" % what)
        fname, _, dpath = item.text.strip().partition(":")
        expect(fname == "results.h5", "%s refers to %r, not the relative results.h5"
               % (what, fname))
        if not expect(dpath in shapes, "%s refers to missing dataset %s" % (what, dpath)):
            return None
        shape, dtype = shapes[dpath]
        dims = tuple(int(x) for x in item.get("Dimensions").split())
        expect(dims == tuple(lead) + shape,
               "%s Dimensions %s vs dataset %s" % (what, dims, tuple(lead) + shape))
        nt = item.get("NumberType")
        if dtype.itemsize == 1:
            expect(nt == {"i": "Char", "u": "UChar"}[dtype.kind], "%s NumberType" % what)
        else:
            expect(nt == ntypes[dtype.kind], "%s NumberType %s for %s" % (what, nt, dtype))
        expect(int(item.get("Precision")) == dtype.itemsize, "%s Precision" % what)
        return dpath

    def collection(name):
        p = os.path.join(outdir, name)
        if not expect(os.path.exists(p), "%s missing" % name):
            return []
        root = ET.parse(p).getroot()
        expect(root.tag == "Xdmf" and root.get("Version") == "3.0", "%s root" % name)
        coll = root.find("Domain/Grid")
        expect(coll.get("GridType") == "Collection"
               and coll.get("CollectionType") == "Temporal", "%s temporal collection" % name)
        grids = coll.findall("Grid")
        expect(len(grids) == len(STEPS), "%s has %d steps" % (name, len(grids)))
        for g, time in zip(grids, TIMES):
            expect(float(g.find("Time").get("Value")) == time, "%s time" % name)
        return grids

    for k, g in enumerate(collection("particles.xdmf")):
        step = STEPS[k]
        topo = g.find("Topology")
        expect(topo.get("TopologyType") == "Polyvertex", "particle topology")
        n = len(particle_ids(size, k)[0])
        expect(int(topo.get("NumberOfElements")) == n, "particle NumberOfElements")
        items = topo.findall("DataItem")
        if expect(len(items) == 1, "particle topology has one connectivity DataItem"):
            p = check_item(items[0], "particle connectivity")
            expect(p == "/polyvertex/%d" % n, "connectivity dataset %s" % p)
        geo = g.find("Geometry")
        expect(geo.get("GeometryType") == "XYZ", "particle geometry type")
        p = check_item(geo.find("DataItem"), "particle geometry")
        expect(p == "/steps/%06d/particles/position" % step, "geometry dataset %s" % p)
        atts = {a.get("Name"): a for a in g.findall("Attribute")}
        expect(sorted(atts) == sorted(PARTICLE_FIELDS), "particle attributes %s" % sorted(atts))
        for name, a in atts.items():
            expect(a.get("AttributeType") == PARTICLE_KINDS.get(name), "xdmf %s type" % name)
            expect(a.get("Center") == "Node", "xdmf %s center" % name)
            p = check_item(a.find("DataItem"), "particle attribute %s" % name)
            expect(p == "/steps/%06d/particles/%s" % (step, name), "attribute path %s" % p)

    for k, g in enumerate(collection("grid.xdmf")):
        step = STEPS[k]
        topo = g.find("Topology")
        # 2-D grids are written as one layer of a 3DCoRectMesh (nz = 1, z = 0), which
        # ParaView puts in the z = 0 plane with the particles.
        lead = (1,) if dim == 2 else ()
        expect(topo.get("TopologyType") == "3DCoRectMesh", "grid topology type")
        dims = [int(x) for x in topo.get("Dimensions").split()]
        expect(dims == list(lead) + list(NODES[dim][::-1]),
               "grid Dimensions %s (want z y x)" % dims)
        geo = g.find("Geometry")
        expect(geo.get("GeometryType") == "ORIGIN_DXDYDZ", "grid geometry type")
        items = geo.findall("DataItem")
        expect(len(items) == 2, "grid geometry has origin and spacing")
        if len(items) == 2:
            origin = [float(x) for x in items[0].text.split()]
            spacing = [float(x) for x in items[1].text.split()]
            expect(origin == [0.0] * len(lead) + list(LOWER[dim][::-1]),
                   "grid origin %s (want z y x)" % origin)
            expect(spacing[len(lead):] == list(SPACING[dim][::-1]) and len(spacing) == 3
                   and spacing[0] > 0, "grid spacing %s (want z y x)" % spacing)
        atts = {a.get("Name"): a for a in g.findall("Attribute")}
        expect(sorted(atts) == sorted(GRID_FIELDS), "grid attributes %s" % sorted(atts))
        for name, a in atts.items():
            expect(a.get("AttributeType") == GRID_KINDS.get(name), "grid xdmf %s type" % name)
            expect(a.get("Center") == "Node", "grid xdmf %s center" % name)
            p = check_item(a.find("DataItem"), "grid attribute %s" % name, lead)
            expect(p == "/steps/%06d/grid/%s" % (step, name), "grid attribute path %s" % p)

    leftovers = [n for n in os.listdir(outdir) if n.endswith(".tmp")]
    expect(not leftovers, "temporary files left: %s" % leftovers)
    return errs


def check_bad_input(comm, outdir):
    """Bad input on the last rank only must raise ValueError on every rank (no hang),
    and the writer must stay usable. Returns mismatch messages (same on all ranks)."""
    from pimpm.io import ResultWriter

    rank, size = comm.Get_rank(), comm.Get_size()
    d = os.path.join(outdir, "bad_np%d" % size)
    if rank == 0:
        os.makedirs(d, exist_ok=True)
    comm.Barrier()
    starts, sizes = grid_box(size, rank, 2)
    index = np.meshgrid(*[np.arange(s, s + n) for s, n in zip(starts, sizes)], indexing="ij")
    good = particle_values(np.arange(3, dtype=np.int64) + 10 * rank, 2, 0)
    bad = dict(good, J=np.ones(2)) if rank == size - 1 else good
    with ResultWriter(comm, d, 2, LOWER[2], SPACING[2], NODES[2]) as writer:
        try:
            writer.write_step(0, 0.0, bad, grid_values(2, 0, index), (starts, sizes))
            raised = False
        except ValueError:
            raised = True
        writer.write_step(0, 0.0, good, grid_values(2, 0, index), (starts, sizes))
    flags = comm.allgather(raised)
    return [] if all(flags) else ["bad input raised on ranks %s only" % flags]


def run(comm, outdir):
    """Write and check both dimensions; returns the mismatch list (same on all ranks)."""
    errs = check_bad_input(comm, outdir)
    for dim in (2, 3):
        d = os.path.join(outdir, "dim%d_np%d" % (dim, comm.Get_size()))
        if comm.Get_rank() == 0:
            os.makedirs(d, exist_ok=True)
        comm.Barrier()
        write_case(comm, d, dim)
        comm.Barrier()
        local = check_case(d, dim, comm.Get_size()) if comm.Get_rank() == 0 else None
        errs += comm.bcast(local, root=0)
    return errs


def main():
    from mpi4py import MPI

    comm = MPI.COMM_WORLD
    if len(sys.argv) != 2:
        if comm.Get_rank() == 0:
            print("usage: output_check.py OUTDIR", file=sys.stderr)
        return 2
    try:
        errs = run(comm, sys.argv[1])
    except Exception:  # noqa: BLE001 - never leave the other ranks hanging
        traceback.print_exc()
        sys.stderr.flush()
        comm.Abort(3)
    if errs:
        if comm.Get_rank() == 0:
            print("output_check FAILED (%d ranks):\n  " % comm.Get_size() + "\n  ".join(errs),
                  file=sys.stderr)
        return 1
    if comm.Get_rank() == 0:
        print("output_check OK (%d ranks)" % comm.Get_size())
    return 0


if __name__ == "__main__":
    sys.exit(main())
