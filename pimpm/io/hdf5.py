"""The parallel HDF5 result file ``results.h5`` (layout: :mod:`.layout`)
and, after every step, the XDMF files that describe it (:mod:`.xdmf`).

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

The XDMF files are rewritten by rank 0 after every step, after the HDF5 file
was flushed, so after a crash both describe all completed steps.
"""
import os

import numpy as np

from ..errors import OutputFailed
from .layout import GRID_XDMF, H5_NAME, PARTICLES_XDMF, POLYVERTEX, _attr_str, _ordered, _to_file_components
from .plan import StepPlanner, plan_bytes
from .space import check_room
from .xdmf import XdmfFiles

__all__ = ["ResultWriter", "H5_NAME", "PARTICLES_XDMF", "GRID_XDMF"]


def collective_transfer():
    """A dataset transfer property list for collective MPI-IO writes."""
    import h5py
    dxpl = h5py.h5p.create(h5py.h5p.DATASET_XFER)
    dxpl.set_dxpl_mpio(h5py.h5fd.MPIO_COLLECTIVE)
    return dxpl


def write_slab(dset, start, data, dxpl):
    """Write ``data`` at ``start`` of ``dset``. All ranks call this with the
    collective transfer ``dxpl`` (None: serial file); a rank with nothing to
    write takes part with an empty selection (h5py's ``dset[a:a] = x`` would
    skip the call and deadlock the others)."""
    import h5py
    if data.size > 0:
        data = np.ascontiguousarray(data, dtype=dset.dtype)
        fspace = dset.id.get_space()
        fspace.select_hyperslab(tuple(int(s) for s in start), data.shape)
        mspace = h5py.h5s.create_simple(data.shape)
    else:
        if dxpl is None:
            return  # serial: nothing to do
        fspace = dset.id.get_space()
        fspace.select_none()
        mspace = h5py.h5s.create_simple((1,))
        mspace.select_none()
        data = np.zeros((1,), dtype=dset.dtype)
    dset.id.write(mspace, fspace, data, dxpl=dxpl)


def same_grid(attrs, dim, nodes, lower, spacing):
    """True if a results file's attributes describe this grid."""
    return (int(attrs["dim"]) == dim and np.array_equal(attrs["nodes"], nodes)
            and np.allclose(attrs["lower"], lower) and np.allclose(attrs["spacing"], spacing))


def step_records(steps):
    """{step: its description for the XDMF files} of a results file's
    ``steps`` group, read from its attributes and datasets' metadata."""
    records = {}
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
        records[rec["step"]] = rec
    return records


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
        self._xdmf = None   # rank 0's XdmfFiles (each step's XML kept)

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
        self.planner = StepPlanner(comm, self.dim, self.nodes)

        mode = "a" if append else "w"
        if self.size > 1:
            self._file = h5py.File(self.path, mode, driver="mpio", comm=comm)
            self._dxpl = collective_transfer()
        else:
            self._file = h5py.File(self.path, mode)
            self._dxpl = None
        f = self._file
        if append and "dim" in f.attrs:
            # every rank reads the same attributes, so all ranks agree here
            if not same_grid(f.attrs, self.dim, self.nodes, self.lower, self.spacing):
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
        plan = self.planner.plan(step, time, particle_fields, grid_fields, grid_box)
        check_room(self.comm, self.directory, plan_bytes(plan), f"step {plan['step']} of the results")
        # --- from here on every rank runs the same HDF5 calls with the same arguments
        error = None
        try:
            self._write_plan(plan, particle_fields, grid_fields)
            self._file.flush()
        except OSError as err:            # a full disk: h5py's write or flush (issue 32)
            error = f"{type(err).__name__}: {err}"
        errors = self.comm.allgather(error) if self.size > 1 else [error]
        failed = [(rank, e) for rank, e in enumerate(errors) if e is not None]
        if failed:
            rank, e = failed[0]
            raise OutputFailed(f"writing step {plan['step']} to {self.directory}/results.h5 failed on rank "
                               f"{rank} of {self.size} ({e})")
        self._records[plan["step"]] = plan["record"]
        self._write_xdmf_checked()

    def drop_steps_after(self, step):
        """Remove the steps written after ``step`` (a restart from its
        checkpoint writes them again). Collective."""
        steps = self._file["steps"]
        for name in sorted(steps.keys()):
            if int(steps[name].attrs["step"]) > step:
                del steps[name]
        self._records = {s: r for s, r in self._records.items() if s <= step}
        self._file.flush()
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

    # ------------------------------------------------------------------ writing
    def _new_dataset(self, group, name, shape, dtype, kind):
        h5py = self._h5py
        dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
        dcpl.set_fill_time(h5py.h5d.FILL_TIME_NEVER)  # every element gets written
        dset = group.create_dataset(name, shape=shape, dtype=dtype, dcpl=dcpl)
        dset.attrs["AttributeType"] = kind
        return dset

    def _write_slab(self, dset, start, data):
        write_slab(dset, start, data, self._dxpl)

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
            if pp["count"] > 0:
                self._write_connectivity(pp["count"], offset, n_local)

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

    def _write_connectivity(self, count, offset, n_local):
        """``/polyvertex/<count>``: 0..count-1, the Polyvertex topology's
        connectivity (the Xdmf3 readers make no cells without one); one per
        particle count, shared by the steps. Collective."""
        group = self._file.require_group(POLYVERTEX)
        name = str(int(count))
        if name in group:
            return
        dset = self._new_dataset(group, name, (count, 1), np.int64, "Scalar")
        local = np.arange(offset, offset + n_local, dtype=np.int64).reshape(-1, 1)
        self._write_slab(dset, (offset, 0), local)

    # ------------------------------------------------------------------ restart
    def _load_records(self):
        """Rebuild the XDMF step list from an existing file (append mode)."""
        self._records.update(step_records(self._file["steps"]))

    def _write_xdmf_checked(self):
        """Rank 0 rewrites the XDMF files; a failure is raised on every rank."""
        err = None
        if self.rank == 0:
            try:
                if self._xdmf is None:
                    self._xdmf = XdmfFiles(self.directory, self.dim, self.nodes, self.lower, self.spacing)
                self._xdmf.write(self._records)
            except Exception as exc:  # noqa: BLE001 - re-raised collectively below
                err = "%s: %s" % (type(exc).__name__, exc)
        if self.size > 1:
            err = self.comm.bcast(err, root=0)
        if err is not None:
            raise OutputFailed(f"writing the XDMF files in {self.directory} failed ({err})")
