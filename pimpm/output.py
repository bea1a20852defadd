"""Parallel result output: one HDF5 file per run plus XDMF descriptions for ParaView.

Layout of ``<directory>/results.h5``::

    /                      attrs: dim, lower, spacing, nodes (grid description)
    /steps/NNNNNN          attrs: step, time
    /steps/NNNNNN/particles/<field>   global arrays, rank-order concatenation
    /steps/NNNNNN/grid/<field>        node arrays in XDMF (z,) y, x order

Every dataset carries the attribute ``AttributeType`` (Scalar, Vector, Tensor,
Tensor6 or Matrix), which is also what the XDMF files declare.

Component conventions (what XDMF/ParaView expect):

* a field with per-item shape ``()`` is a Scalar, stored as ``(n,)``;
* per-item shape ``(dim,)`` or ``(3,)`` is a Vector, zero-padded to ``(n, 3)``
  (so 2-D positions get z = 0);
* ``(dim, dim)``, ``(3, 3)`` or ``(9,)`` is a Tensor, zero-padded to 3x3 and
  stored row-major as ``(n, 9)``; ``(6,)`` is stored as-is as a Tensor6;
* anything else is flattened to ``(n, k)`` and declared as a Matrix.

Grid fields are stored as ``(ny, nx) + comp`` in 2-D and ``(nz, ny, nx) + comp``
in 3-D (x varies fastest), with comp = ``()``, ``(3,)``, ``(9,)``, ``(6,)`` or ``(k,)``
by the same rules.

Parallel I/O: the file is opened with h5py's ``mpio`` driver when ``comm.size > 1``
and as a plain serial file when ``comm.size == 1`` (Debian's h5py only loads its MPI
build under mpiexec or with ``H5PY_ALWAYS_USE_MPI``). All sizes, offsets, dtypes and
field lists are agreed on with one ``allgather`` *before* any HDF5 call, so every rank
performs the same sequence of (collective) metadata operations with identical
arguments, and input errors raise the same ``ValueError`` on every rank instead of
hanging the run. Data are written with collective transfers; a rank with nothing to
write takes part with an empty selection (h5py's ``dset[a:a] = x`` silently skips
the write call, which would deadlock a collective transfer, so the low-level API is
used).

The XDMF files (``particles.xdmf``, ``grid.xdmf``; XDMF 3.0, relative paths to
``results.h5``) are rewritten by rank 0 after every step through a temporary file
and ``os.replace``, after the HDF5 file was flushed, so after a crash both the HDF5
file and the XDMF files describe all completed steps.

* ``particles.xdmf``: Temporal collection of Polyvertex grids, geometry XYZ from
  ``particles/position``, one Node attribute per field. Steps with no particles at
  all are left out (zero-sized DataItems upset the readers).
* ``grid.xdmf``: Temporal collection of ``3DCoRectMesh`` grids (Dimensions, Origin
  and Spacing in z y x order, ORIGIN_DXDYDZ). A 2-D grid is described as one node
  layer (nz = 1, origin z = 0): ParaView 5.11 (Xdmf3ReaderS/T and the legacy
  XDMFReader) places a ``2DCoRectMesh`` in the x = 0 plane, away from the particles,
  and the legacy reader fails on its vector attributes. The HDF5 arrays keep their
  ``(ny, nx, ...)`` shape; their DataItems declare ``(1, ny, nx, ...)``.
"""
import os
import xml.etree.ElementTree as ET

import numpy as np

__all__ = ["ResultWriter", "H5_NAME", "PARTICLES_XDMF", "GRID_XDMF"]

H5_NAME = "results.h5"
PARTICLES_XDMF = "particles.xdmf"
GRID_XDMF = "grid.xdmf"


def _step_name(step):
    return "%06d" % int(step)


def _xdmf_number_type(dtype):
    """(NumberType, Precision) of an XDMF DataItem for a numpy dtype."""
    dtype = np.dtype(dtype)
    if dtype.kind == "f":
        return "Float", str(dtype.itemsize)
    if dtype.kind == "i":
        return {1: "Char", 2: "Short"}.get(dtype.itemsize, "Int"), str(dtype.itemsize)
    if dtype.kind == "u":
        return {1: "UChar", 2: "UShort"}.get(dtype.itemsize, "UInt"), str(dtype.itemsize)
    raise ValueError("no XDMF number type for dtype %s" % dtype)


def _file_dtype(dtypes):
    """Common on-disk dtype for a field given the dtypes seen on the ranks."""
    dtypes = [np.dtype(d) for d in dtypes]
    for d in dtypes:
        if d.kind not in "biuf":
            raise ValueError("unsupported dtype %s (only bool, int, uint, float)" % d)
    dt = np.result_type(*dtypes)
    if dt.kind == "b":
        return np.dtype(np.uint8)
    if dt.kind == "f" and dt.itemsize < 4:
        return np.dtype(np.float32)
    if dt.kind == "f" and dt.itemsize > 8:
        return np.dtype(np.float64)
    if dt.kind == "u" and dt.itemsize > 4:
        return np.dtype(np.int64)  # XDMF readers have no 8-byte unsigned type
    return dt


def _classify(comp_shape, dim):
    """XDMF attribute type and stored per-item shape for a per-item shape."""
    comp_shape = tuple(int(c) for c in comp_shape)
    if comp_shape == ():
        return "Scalar", ()
    if len(comp_shape) == 1:
        k = comp_shape[0]
        if k in (dim, 3):
            return "Vector", (3,)
        if k == 9:
            return "Tensor", (9,)
        if k == 6:
            return "Tensor6", (6,)
        return "Matrix", (k,)
    if len(comp_shape) == 2 and comp_shape[0] == comp_shape[1] and comp_shape[0] in (dim, 3):
        return "Tensor", (9,)
    return "Matrix", (int(np.prod(comp_shape)),)


def _to_file_components(arr, nlead, kind, out_comp, dtype):
    """Pad/reshape the trailing (component) axes of ``arr`` to the stored layout."""
    lead = arr.shape[:nlead]
    comp = arr.shape[nlead:]
    if kind == "Vector" and comp[0] < 3:
        out = np.zeros(lead + (3,), dtype=dtype)
        out[..., :comp[0]] = arr
        return out
    if kind == "Tensor" and comp in ((2, 2),):
        out = np.zeros(lead + (3, 3), dtype=dtype)
        out[..., :2, :2] = arr
        return out.reshape(lead + (9,))
    return np.ascontiguousarray(arr, dtype=dtype).reshape(lead + tuple(out_comp))


class ResultWriter:
    """One HDF5 file per run (results.h5) written in parallel + XDMF files ParaView opens.

    Parameters
    ----------
    comm : mpi4py communicator
    directory : existing directory (created by the caller)
    dim : 2 or 3
    lower, spacing : grid origin and node spacing, ``dim`` floats each
    nodes : number of grid nodes per axis, ``dim`` ints
    append : if True, open an existing results.h5 (e.g. on restart) and keep its steps;
        writing a step that is already present replaces it. Default: start a new file.

    Collective: the constructor, :meth:`write_step` and :meth:`close` must be called
    by every rank of ``comm``. Also usable as a context manager.
    """

    def __init__(self, comm, directory, dim, lower, spacing, nodes, append=False):
        import h5py  # imported late: the MPI/serial build is chosen at import time

        self._h5py = h5py
        self.comm = comm
        self.rank = comm.Get_rank()
        self.size = comm.Get_size()
        self.directory = os.fspath(directory)
        self.path = os.path.join(self.directory, H5_NAME)
        self._file = None
        self._records = {}  # step -> description used to write the XDMF files

        # Agree on the grid description (rank 0's values) before touching the file.
        errors = []
        try:
            dim = int(dim)
            if dim not in (2, 3):
                raise ValueError("dim must be 2 or 3, got %r" % (dim,))
            lower = np.asarray(lower, dtype=np.float64).reshape(-1)
            spacing = np.asarray(spacing, dtype=np.float64).reshape(-1)
            nodes = np.asarray(nodes, dtype=np.int64).reshape(-1)
            if lower.size != dim or spacing.size != dim or nodes.size != dim:
                raise ValueError("lower, spacing and nodes need %d entries each" % dim)
            if np.any(nodes < 1):
                raise ValueError("nodes must be positive, got %s" % nodes.tolist())
            desc = (dim, lower.tolist(), spacing.tolist(), nodes.tolist())
        except (TypeError, ValueError) as exc:
            errors.append("rank %d: %s" % (self.rank, exc))
            desc = None
        mpi_h5 = bool(h5py.get_config().mpi)
        if self.size > 1 and not mpi_h5:
            errors.append(
                "rank %d: h5py is the serial build but comm.size = %d; run under mpiexec "
                "or set H5PY_ALWAYS_USE_MPI=1 before importing h5py" % (self.rank, self.size))
        gathered = comm.allgather((errors, desc))
        all_errors = [e for errs, _ in gathered for e in errs]
        if all_errors:
            raise ValueError("ResultWriter: " + "; ".join(all_errors))
        dim, lower, spacing, nodes = gathered[0][1]
        self.dim = dim
        self.lower = np.array(lower, dtype=np.float64)
        self.spacing = np.array(spacing, dtype=np.float64)
        self.nodes = np.array(nodes, dtype=np.int64)

        mode = "a" if append else "w"
        if self.size > 1:
            self._file = h5py.File(self.path, mode, driver="mpio", comm=comm)
            dxpl = h5py.h5p.create(h5py.h5p.DATASET_XFER)
            dxpl.set_dxpl_mpio(h5py.h5fd.MPIO_COLLECTIVE)
            self._dxpl = dxpl
        else:
            self._file = h5py.File(self.path, mode)
            self._dxpl = None
        f = self._file
        if append and "dim" in f.attrs:
            # every rank reads the same attributes, so all ranks agree here
            same = (int(f.attrs["dim"]) == self.dim
                    and np.array_equal(f.attrs["nodes"], self.nodes)
                    and np.allclose(f.attrs["lower"], self.lower)
                    and np.allclose(f.attrs["spacing"], self.spacing))
            if not same:
                f.close()
                self._file = None
                raise ValueError("ResultWriter(append=True): %s describes a different grid"
                                 % self.path)
        f.attrs["dim"] = np.int64(self.dim)
        f.attrs["lower"] = self.lower
        f.attrs["spacing"] = self.spacing
        f.attrs["nodes"] = self.nodes
        if "steps" not in f:
            f.create_group("steps")
        elif append:
            self._load_records()
        f.flush()

    # ------------------------------------------------------------------ public API
    def write_step(self, step, time, particle_fields, grid_fields, grid_box):
        """Write one output step (collective).

        particle_fields : dict name -> local array, first axis = local particle count
            (may be 0). "position" (n, dim) is required on every rank that has
            particles; a rank without particles may pass ``{}`` or None.
        grid_fields : dict name -> array of shape box_shape + comp_shape over this
            rank's owned node box, indexed [i, j(, k)] (x first); may be {} or None.
        grid_box : (starts, sizes) of the owned node box in global node indices.
        """
        if self._file is None:
            raise RuntimeError("ResultWriter is closed")
        plan = self._plan(step, time, particle_fields, grid_fields, grid_box)
        # --- from here on every rank runs the same HDF5 calls with the same arguments
        self._write_plan(plan, particle_fields, grid_fields)
        self._file.flush()
        self._records[plan["step"]] = plan["record"]
        self._write_xdmf_checked()

    def close(self):
        """Close the HDF5 file (collective). Safe to call twice."""
        if self._file is not None:
            self._file.close()
            self._file = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    # ------------------------------------------------------------------ planning
    def _local_particle_info(self, particle_fields):
        fields = {}
        errors = []
        particle_fields = particle_fields or {}
        count = 0
        if particle_fields:
            pos = np.asarray(particle_fields.get("position", np.zeros(())))
            if "position" not in particle_fields:
                errors.append("particle_fields has no 'position'")
                return 0, fields, errors
            if pos.ndim == 0 or (pos.shape[0] > 0 and (
                    pos.ndim != 2 or _classify(pos.shape[1:], self.dim)[0] != "Vector")):
                errors.append("particle 'position' must have shape (n, %d), got %s"
                              % (self.dim, pos.shape))
                return 0, fields, errors
            count = int(pos.shape[0])
        for name, arr in particle_fields.items():
            if not isinstance(name, str) or not name or "/" in name:
                errors.append("bad particle field name %r" % (name,))
                continue
            arr = np.asarray(arr)
            if arr.ndim == 0:
                errors.append("particle field %r is a scalar, needs a particle axis" % name)
                continue
            if arr.shape[0] != count:
                errors.append("particle field %r has %d entries but position has %d"
                              % (name, arr.shape[0], count))
                continue
            if arr.dtype.kind not in "biuf":
                errors.append("particle field %r has unsupported dtype %s" % (name, arr.dtype))
                continue
            fields[name] = (arr.dtype.str, tuple(int(s) for s in arr.shape[1:]))
        return count, fields, errors

    def _local_grid_info(self, grid_fields, grid_box):
        errors = []
        fields = {}
        grid_fields = grid_fields or {}
        start = size = None
        if grid_box is None:
            if grid_fields:
                errors.append("grid_fields given without grid_box")
            return start, size, fields, errors
        try:
            starts, sizes = grid_box
            start = [int(s) for s in starts]
            size = [int(s) for s in sizes]
        except (TypeError, ValueError):
            errors.append("grid_box must be (starts, sizes), got %r" % (grid_box,))
            return None, None, fields, errors
        if len(start) != self.dim or len(size) != self.dim:
            errors.append("grid_box needs %d starts and sizes, got %r" % (self.dim, grid_box))
            return None, None, fields, errors
        for a in range(self.dim):
            if size[a] < 0 or start[a] < 0 or start[a] + size[a] > self.nodes[a]:
                errors.append("grid_box %r outside the node grid %s"
                              % (grid_box, self.nodes.tolist()))
                return None, None, fields, errors
        for name, arr in grid_fields.items():
            if not isinstance(name, str) or not name or "/" in name:
                errors.append("bad grid field name %r" % (name,))
                continue
            arr = np.asarray(arr)
            if tuple(arr.shape[:self.dim]) != tuple(size) or arr.ndim < self.dim:
                errors.append("grid field %r has shape %s, box sizes are %s"
                              % (name, arr.shape, size))
                continue
            if arr.dtype.kind not in "biuf":
                errors.append("grid field %r has unsupported dtype %s" % (name, arr.dtype))
                continue
            fields[name] = (arr.dtype.str, tuple(int(s) for s in arr.shape[self.dim:]))
        return start, size, fields, errors

    def _plan(self, step, time, particle_fields, grid_fields, grid_box):
        """Agree on everything (one allgather) and compute all shapes and offsets."""
        errors = []
        try:
            step_l = int(step)
            time_l = float(time)
            if step_l < 0:
                raise ValueError("step must be >= 0")
        except (TypeError, ValueError) as exc:
            errors.append("bad step/time (%r, %r): %s" % (step, time, exc))
            step_l, time_l = 0, 0.0
        try:
            pcount, pfields, perr = self._local_particle_info(particle_fields)
        except Exception as exc:  # noqa: BLE001 - reported collectively below
            pcount, pfields, perr = 0, {}, ["particle_fields: %r" % exc]
        try:
            gstart, gsize, gfields, gerr = self._local_grid_info(grid_fields, grid_box)
        except Exception as exc:  # noqa: BLE001
            gstart, gsize, gfields, gerr = None, None, {}, ["grid_fields: %r" % exc]
        errors += perr + gerr
        info = dict(step=step_l, time=time_l, pcount=pcount, pfields=pfields,
                    gstart=gstart, gsize=gsize, gfields=gfields,
                    errors=["rank %d: %s" % (self.rank, e) for e in errors])
        infos = self.comm.allgather(info)

        # Everything below is computed identically on every rank from `infos`.
        all_errors = [e for inf in infos for e in inf["errors"]]
        step_g, time_g = infos[0]["step"], infos[0]["time"]
        if any(inf["step"] != step_g for inf in infos):
            all_errors.append("ranks disagree on step: %s" % [inf["step"] for inf in infos])
        if not all_errors:
            try:
                particles = self._plan_particles(infos)
                grid = self._plan_grid(infos)
            except ValueError as exc:
                all_errors.append(str(exc))
        if all_errors:
            raise ValueError("ResultWriter.write_step(step=%s): " % step_g + "; ".join(all_errors))

        sname = _step_name(step_g)
        record = dict(step=step_g, time=time_g, name=sname,
                      particles=None if particles is None else dict(
                          count=particles["count"],
                          fields=[(n, f["kind"], f["shape"], f["dtype"].str)
                                  for n, f in particles["fields"].items()]),
                      grid=None if grid is None else dict(
                          fields=[(n, f["kind"], f["shape"], f["dtype"].str)
                                  for n, f in grid["fields"].items()]))
        return dict(step=step_g, time=time_g, name=sname, particles=particles, grid=grid,
                    record=record)

    def _plan_particles(self, infos):
        counts = [inf["pcount"] for inf in infos]
        names = sorted(set(n for inf in infos for n in inf["pfields"]))
        if not names:
            return None
        if "position" not in names:
            raise ValueError("no rank passed particle 'position'")
        fields = {}
        total = int(sum(counts))
        offsets = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
        # 'position' first, then alphabetical
        for name in ["position"] + [n for n in names if n != "position"]:
            have = [(r, inf["pfields"][name]) for r, inf in enumerate(infos)
                    if name in inf["pfields"]]
            missing = [r for r, inf in enumerate(infos)
                       if inf["pcount"] > 0 and name not in inf["pfields"]]
            if missing:
                raise ValueError("particle field %r missing on ranks %s that have particles"
                                 % (name, missing))
            # Ranks with particles decide dtype and component shape; empty ranks'
            # zero-length arrays are allowed to be sloppy.
            decisive = [(r, m) for r, m in have if infos[r]["pcount"] > 0] or have
            comps = set(m[1] for _, m in decisive)
            if len(comps) != 1:
                raise ValueError("particle field %r has different per-particle shapes on "
                                 "different ranks: %s" % (name, sorted(comps)))
            comp = comps.pop()
            kind, out_comp = _classify(comp, self.dim)
            if name == "position" and kind != "Vector" and total == 0:
                comp, kind, out_comp = (self.dim,), "Vector", (3,)
            if name == "position" and kind != "Vector":
                raise ValueError("particle 'position' must have shape (n, %d)" % self.dim)
            dtype = _file_dtype([m[0] for _, m in decisive])
            fields[name] = dict(kind=kind, comp=comp, dtype=dtype,
                                shape=(total,) + tuple(out_comp))
        return dict(count=total, counts=counts, offsets=offsets.tolist(), fields=fields)

    def _plan_grid(self, infos):
        names = sorted(set(n for inf in infos for n in inf["gfields"]))
        if not names:
            return None
        boxes = [(inf["gstart"], inf["gsize"]) for inf in infos]
        if any(b[0] is None for b in boxes):
            raise ValueError("grid_fields given but some ranks passed no grid_box: ranks %s"
                             % [r for r, b in enumerate(boxes) if b[0] is None])
        volume = sum(int(np.prod(b[1])) for b in boxes)
        if volume != int(np.prod(self.nodes)):
            raise ValueError("grid boxes cover %d nodes but the grid has %d: boxes must tile "
                             "the node grid (owned nodes only, no ghosts): %s"
                             % (volume, int(np.prod(self.nodes)), boxes))
        space = tuple(int(n) for n in self.nodes[::-1])  # (nz,) ny, nx
        fields = {}
        for name in names:
            missing = [r for r, inf in enumerate(infos)
                       if np.prod(inf["gsize"]) > 0 and name not in inf["gfields"]]
            if missing:
                raise ValueError("grid field %r missing on ranks %s" % (name, missing))
            have = [inf["gfields"][name] for inf in infos
                    if name in inf["gfields"] and np.prod(inf["gsize"]) > 0]
            comps = set(m[1] for m in have)
            if len(comps) != 1:
                raise ValueError("grid field %r has different per-node shapes on different "
                                 "ranks: %s" % (name, sorted(comps)))
            comp = comps.pop()
            kind, out_comp = _classify(comp, self.dim)
            dtype = _file_dtype([m[0] for m in have])
            fields[name] = dict(kind=kind, comp=comp, dtype=dtype,
                                shape=space + tuple(out_comp))
        my = boxes[self.rank]
        return dict(fields=fields, start=my[0], size=my[1])

    # ------------------------------------------------------------------ writing
    def _new_dataset(self, group, name, shape, dtype, kind):
        h5py = self._h5py
        dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
        dcpl.set_fill_time(h5py.h5d.FILL_TIME_NEVER)  # every element gets written
        dset = group.create_dataset(name, shape=shape, dtype=dtype, dcpl=dcpl)
        dset.attrs["AttributeType"] = kind
        return dset

    def _write_slab(self, dset, start, data):
        """Write ``data`` at ``start`` (all ranks call this; empty data = empty selection)."""
        h5s = self._h5py.h5s
        if data.size > 0:
            data = np.ascontiguousarray(data, dtype=dset.dtype)
            fspace = dset.id.get_space()
            fspace.select_hyperslab(tuple(int(s) for s in start), data.shape)
            mspace = h5s.create_simple(data.shape)
        else:
            if self._dxpl is None:
                return  # serial: nothing to do
            fspace = dset.id.get_space()
            fspace.select_none()
            mspace = h5s.create_simple((1,))
            mspace.select_none()
            data = np.zeros((1,), dtype=dset.dtype)
        dset.id.write(mspace, fspace, data, dxpl=self._dxpl)

    def _write_plan(self, plan, particle_fields, grid_fields):
        f = self._file
        steps = f["steps"]
        if plan["name"] in steps:
            del steps[plan["name"]]  # rewriting a step (restart): replace it
        g = steps.create_group(plan["name"])
        g.attrs["step"] = np.int64(plan["step"])
        g.attrs["time"] = np.float64(plan["time"])

        pp = plan["particles"]
        if pp is not None:
            pg = g.create_group("particles")
            pg.attrs["count"] = np.int64(pp["count"])
            pg.attrs["counts_per_rank"] = np.asarray(pp["counts"], dtype=np.int64)
            n_local = pp["counts"][self.rank]
            offset = pp["offsets"][self.rank]
            for name, fd in pp["fields"].items():
                dset = self._new_dataset(pg, name, fd["shape"], fd["dtype"], fd["kind"])
                if pp["count"] == 0:
                    continue  # nothing anywhere: skip the transfer on every rank
                if n_local > 0:
                    arr = np.asarray(particle_fields[name])
                    local = _to_file_components(arr, 1, fd["kind"], fd["shape"][1:], fd["dtype"])
                else:
                    local = np.zeros((0,) + tuple(fd["shape"][1:]), dtype=fd["dtype"])
                self._write_slab(dset, (offset,) + (0,) * (len(fd["shape"]) - 1), local)

        gp = plan["grid"]
        if gp is not None:
            gg = g.create_group("grid")
            dim = self.dim
            start, size = gp["start"], gp["size"]
            nonempty = int(np.prod(size)) > 0
            rev = tuple(range(dim - 1, -1, -1))
            for name, fd in gp["fields"].items():
                dset = self._new_dataset(gg, name, fd["shape"], fd["dtype"], fd["kind"])
                out_comp = tuple(fd["shape"][dim:])
                if nonempty:
                    arr = np.asarray(grid_fields[name])
                    arr = np.transpose(arr, rev + tuple(range(dim, arr.ndim)))
                    local = _to_file_components(arr, dim, fd["kind"], out_comp, fd["dtype"])
                else:
                    local = np.zeros(tuple(size[::-1]) + out_comp, dtype=fd["dtype"])
                file_start = tuple(start[::-1]) + (0,) * len(out_comp)
                self._write_slab(dset, file_start, local)

    # ------------------------------------------------------------------ restart
    def _load_records(self):
        """Rebuild the XDMF step list from an existing file (append mode)."""
        steps = self._file["steps"]
        for sname in sorted(steps.keys()):
            g = steps[sname]
            rec = dict(step=int(g.attrs["step"]), time=float(g.attrs["time"]), name=sname,
                       particles=None, grid=None)
            if "particles" in g:
                pg = g["particles"]
                rec["particles"] = dict(
                    count=int(pg.attrs["count"]),
                    fields=[(n, _attr_str(pg[n].attrs["AttributeType"]), tuple(pg[n].shape),
                             pg[n].dtype.str) for n in _ordered(pg.keys())])
            if "grid" in g:
                gg = g["grid"]
                rec["grid"] = dict(
                    fields=[(n, _attr_str(gg[n].attrs["AttributeType"]), tuple(gg[n].shape),
                             gg[n].dtype.str) for n in sorted(gg.keys())])
            self._records[rec["step"]] = rec

    # ------------------------------------------------------------------ XDMF
    def _write_xdmf_checked(self):
        """Rank 0 rewrites the XDMF files; a failure is raised on every rank."""
        err = None
        if self.rank == 0:
            try:
                self._write_xdmf()
            except Exception as exc:  # noqa: BLE001 - re-raised collectively below
                err = "%s: %s" % (type(exc).__name__, exc)
        if self.size > 1:
            err = self.comm.bcast(err, root=0)
        if err is not None:
            raise RuntimeError("writing XDMF files failed on rank 0: " + err)

    def _write_xdmf(self):
        records = [self._records[s] for s in sorted(self._records)]
        prec = [r for r in records if r["particles"] is not None and r["particles"]["count"] > 0]
        grec = [r for r in records if r["grid"] is not None]
        if prec:
            _atomic_write(os.path.join(self.directory, PARTICLES_XDMF),
                          self._particles_xdmf(prec))
        if grec:
            _atomic_write(os.path.join(self.directory, GRID_XDMF), self._grid_xdmf(grec))

    @staticmethod
    def _attribute(parent, name, kind, shape, dtype, h5path):
        att = ET.SubElement(parent, "Attribute", Name=name, AttributeType=kind, Center="Node")
        _data_item(att, shape, dtype, h5path)

    def _particles_xdmf(self, records):
        root, coll = _xdmf_root("particles")
        for rec in records:
            n = rec["particles"]["count"]
            grid = ET.SubElement(coll, "Grid", Name="particles_" + rec["name"], GridType="Uniform")
            ET.SubElement(grid, "Time", Value=repr(float(rec["time"])))
            ET.SubElement(grid, "Topology", TopologyType="Polyvertex",
                          NumberOfElements=str(n), NodesPerElement="1")
            base = "%s:/steps/%s/particles/" % (H5_NAME, rec["name"])
            fields = {f[0]: f for f in rec["particles"]["fields"]}
            geo = ET.SubElement(grid, "Geometry", GeometryType="XYZ")
            pos = fields["position"]
            _data_item(geo, pos[2], pos[3], base + "position")
            for name, kind, shape, dtype in rec["particles"]["fields"]:
                self._attribute(grid, name, kind, shape, dtype, base + name)
        return root

    def _grid_xdmf(self, records):
        # 2-D grids are described as 3DCoRectMesh with one node layer (nz = 1,
        # z = 0): ParaView 5.11 puts a 2DCoRectMesh in the x = 0 plane (its two
        # Dimensions become z and y), away from the particles at z = 0, and its
        # legacy XDMF reader then fails on vector attributes. The HDF5 arrays keep
        # their (ny, nx, ...) shape; the DataItems declare (1, ny, nx, ...), which
        # holds the same values in the same order.
        root, coll = _xdmf_root("grid")
        dim = self.dim
        nodes, lower, spacing = self.nodes, self.lower, self.spacing
        layer = ()
        if dim == 2:
            nodes = np.append(nodes, 1)
            lower = np.append(lower, 0.0)
            spacing = np.append(spacing, 1.0)
            layer = (1,)
        dims = " ".join(str(int(n)) for n in nodes[::-1])
        origin = " ".join(repr(float(x)) for x in lower[::-1])
        step = " ".join(repr(float(x)) for x in spacing[::-1])
        for rec in records:
            grid = ET.SubElement(coll, "Grid", Name="grid_" + rec["name"], GridType="Uniform")
            ET.SubElement(grid, "Time", Value=repr(float(rec["time"])))
            ET.SubElement(grid, "Topology", TopologyType="3DCoRectMesh", Dimensions=dims)
            geo = ET.SubElement(grid, "Geometry", GeometryType="ORIGIN_DXDYDZ")
            for label, text in (("Origin", origin), ("Spacing", step)):
                item = ET.SubElement(geo, "DataItem", Name=label, Dimensions="3",
                                     NumberType="Float", Precision="8", Format="XML")
                item.text = text
            base = "%s:/steps/%s/grid/" % (H5_NAME, rec["name"])
            for name, kind, shape, dtype in rec["grid"]["fields"]:
                self._attribute(grid, name, kind, layer + tuple(shape), dtype, base + name)
        return root


def _attr_str(value):
    return value.decode() if isinstance(value, bytes) else str(value)


def _ordered(names):
    names = sorted(names)
    return (["position"] if "position" in names else []) + [n for n in names if n != "position"]


def _xdmf_root(name):
    root = ET.Element("Xdmf", Version="3.0")
    root.set("xmlns:xi", "http://www.w3.org/2001/XInclude")
    domain = ET.SubElement(root, "Domain")
    coll = ET.SubElement(domain, "Grid", Name=name, GridType="Collection",
                         CollectionType="Temporal")
    return root, coll


def _data_item(parent, shape, dtype, h5path):
    ntype, precision = _xdmf_number_type(dtype)
    item = ET.SubElement(parent, "DataItem", Dimensions=" ".join(str(int(s)) for s in shape),
                         NumberType=ntype, Precision=precision, Format="HDF")
    item.text = h5path
    return item


def _atomic_write(path, root):
    """Write the XML tree to ``path`` via a temporary file and os.replace."""
    if hasattr(ET, "indent"):
        ET.indent(root, space="  ")
    body = ET.tostring(root, encoding="unicode")
    text = '<?xml version="1.0" ?>\n<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>\n' + body + "\n"
    tmp = path + ".tmp"
    with open(tmp, "w") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)
