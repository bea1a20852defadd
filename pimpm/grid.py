"""The background grid: a PETSc DMDA that owns the nodal unknowns, and the rule
that decides which MPI rank owns each cell (and so each particle).

Ownership rule: cell ``c`` (along each axis) belongs to the rank that owns its
lower node ``c``; the last node along an axis has no cell of its own. With a
box stencil of width 1 every node of an owned cell is then in the rank's
ghosted local range, so particle-to-grid scatters and element matrices can be
written in local (ghosted) numbering.
"""
import numpy as np
from petsc4py import PETSc

from .errors import SetupError
from .kernels import reorder, transfer


class Grid:
    """Uniform structured grid on a DMDA with ``dof = dim`` (one unknown per
    displacement component and node)."""

    def __init__(self, comm, lower, upper, cells, stencil_width=1, ownership_ranges=None,
                 proc_sizes=None):
        """``ownership_ranges``: nodes per rank along each axis (DMDA ``lx,
        ly, lz``) on the process grid ``proc_sizes``; PETSc's even split if None."""
        self.comm = comm  # mpi4py communicator
        self.stencil_width = stencil_width
        self.dim = len(cells)
        self.lower = np.asarray(lower, dtype=float)
        self.upper = np.asarray(upper, dtype=float)
        self.cells = np.asarray(cells, dtype=np.int64)
        self.nodes = self.cells + 1
        self.spacing = (self.upper - self.lower) / self.cells
        self.cell_volume = float(np.prod(self.spacing))
        petsc_comm = PETSc.Comm(comm)
        if ownership_ranges is None and comm.size > 1:
            self._check_ranks(petsc_comm, proc_sizes)
        self.da = PETSc.DMDA().create(
            dim=self.dim, dof=self.dim, sizes=tuple(int(n) for n in self.nodes),
            stencil_type=PETSc.DMDA.StencilType.BOX, stencil_width=stencil_width,
            proc_sizes=None if proc_sizes is None else tuple(int(p) for p in proc_sizes),
            ownership_ranges=None if ownership_ranges is None else
            tuple(tuple(int(n) for n in r) for r in ownership_ranges),
            comm=petsc_comm)
        self.da.setUp()
        self._wide = {}          # dofs per node -> (DMDA, local, global vector): sum_columns_to_owned
        lo, hi = self.lower, self.upper
        self.da.setUniformCoordinates(*[v for d in range(self.dim) for v in (lo[d], hi[d])])

        # Owned and ghosted node boxes (per axis [start, end)).
        self.owned_start = np.array([r[0] for r in self.da.getRanges()], dtype=np.int64)
        self.owned_end = np.array([r[1] for r in self.da.getRanges()], dtype=np.int64)
        self.ghost_start = np.array([r[0] for r in self.da.getGhostRanges()], dtype=np.int64)
        self.ghost_end = np.array([r[1] for r in self.da.getGhostRanges()], dtype=np.int64)
        self.ghost_shape = self.ghost_end - self.ghost_start
        self.owned_shape = self.owned_end - self.owned_start
        self.n_local_nodes = int(np.prod(self.ghost_shape))   # ghosted
        self.n_owned_nodes = int(np.prod(self.owned_shape))

        # Process grid and per-axis ownership boundaries, for locating owners.
        self.proc_sizes = np.array(self.da.getProcSizes(), dtype=np.int64)
        self._axis_ends = [np.cumsum(np.asarray(r, dtype=np.int64))
                           for r in self.da.getOwnershipRanges()]
        self._axis_end_table = np.zeros((self.dim, int(np.max(self.proc_sizes))), dtype=np.int64)
        for d, ends in enumerate(self._axis_ends):
            self._axis_end_table[d, :len(ends)] = ends

        # Cells owned by this rank (per axis [start, end)).
        self.owned_cell_start = self.owned_start.copy()
        self.owned_cell_end = np.minimum(self.owned_end, self.cells)

        # Ghosted-local multi-index of every ghosted-local node (x fastest).
        ghost_mesh = np.meshgrid(*[np.arange(n) for n in self.ghost_shape], indexing="ij")
        self.ghost_ijk = np.stack([np.ascontiguousarray(m.T).ravel() for m in ghost_mesh], axis=1)

        # Owned nodes in ghosted local numbering, in PETSc's global (x fastest) order.
        rel = [np.arange(s, e) - g for s, e, g in
               zip(self.owned_start, self.owned_end, self.ghost_start)]
        mesh = np.meshgrid(*rel, indexing="ij")  # axis 0 = x
        local = self._local_node_index_from_rel(mesh)
        # transpose to (z, y, x) so that ravel() is x fastest
        self.owned_local_nodes = np.ascontiguousarray(local.T).ravel()

        # Global (natural) node multi-index of each owned node, same order.
        self.owned_node_ijk = np.stack(
            [np.ascontiguousarray(m.T).ravel() + g for m, g in zip(mesh, self.ghost_start)], axis=1)

    # ------------------------------------------------------------------ indices
    def _check_ranks(self, petsc_comm, proc_sizes):
        """PETSc's DMDA stops with an error on some ranks only (the others
        wait) when a rank would own fewer nodes along an axis than the
        stencil is wide (issue 32: a 3D GIMP grid of 2 cells on 4 ranks).
        Ask PETSc for its process grid on a DMDA without a stencil and refuse
        such a split here, on every rank alike. Collective."""
        probe = PETSc.DMDA().create(dim=self.dim, dof=1, sizes=tuple(int(n) for n in self.nodes),
                                    stencil_width=0, comm=petsc_comm,
                                    proc_sizes=None if proc_sizes is None else tuple(int(p) for p in proc_sizes))
        probe.setUp()
        procs = probe.getProcSizes()
        probe.destroy()
        narrow = [d for d in range(self.dim) if self.nodes[d] // procs[d] < self.stencil_width]
        if narrow:
            axes = ", ".join("xyz"[d] for d in narrow)
            raise SetupError(
                f"grid.cells = {[int(c) for c in self.cells]}: on {self.comm.size} ranks (process grid "
                f"{'x'.join(str(int(p)) for p in procs)}) a rank would own fewer than "
                f"{self.stencil_width} node layers along {axes}, which the shape functions' stencil "
                f"needs: expected at least {self.stencil_width * max(procs[d] for d in narrow) - 1} cells "
                f"along {axes}, or fewer ranks")

    def _local_node_index_from_rel(self, rel):
        """Linear ghosted-local node index from ghost-relative per-axis indices
        (x fastest)."""
        index = rel[-1]
        for d in range(self.dim - 2, -1, -1):
            index = index * self.ghost_shape[d] + rel[d]
        return index

    def local_node_index(self, ijk):
        """Ghosted-local linear index of global node multi-indices ``ijk``
        (array with the axis index last)."""
        rel = [ijk[..., d] - self.ghost_start[d] for d in range(self.dim)]
        return self._local_node_index_from_rel(rel)

    def cell_of(self, x):
        """Cell multi-index (n, dim) containing each position, clipped to the grid."""
        c = np.floor((x - self.lower) / self.spacing).astype(np.int64)
        return np.clip(c, 0, self.cells - 1)

    def inside(self, x):
        """True for positions inside the grid (closed box)."""
        return np.all((x >= self.lower) & (x <= self.upper), axis=1)

    def contains(self, x):
        """Do all positions ``x`` (n, dim) lie inside the grid (closed box)?
        (False for a NaN.)"""
        return bool(reorder.all_inside(np.ascontiguousarray(x, dtype=float), self.lower, self.upper))

    def owner_of_positions(self, x):
        """MPI rank owning the cell that holds each position (n, dim), clipped
        onto the grid (compiled :meth:`owner_of_cells` of :meth:`cell_of`)."""
        out = np.empty(len(x), dtype=np.int64)
        reorder.cell_owners(np.ascontiguousarray(x, dtype=float), self.lower, self.spacing, self.cells,
                            self._axis_end_table, self.proc_sizes, out)
        return out

    def cell_keys(self, x, shift=None):
        """Natural linear index of the cell holding each position + ``shift``
        (clipped onto the grid; compiled :meth:`global_cell_index` of :meth:`cell_of`)."""
        out = np.empty(len(x), dtype=np.int64)
        reorder.cell_keys(np.ascontiguousarray(x, dtype=float), self.lower, self.spacing, self.cells,
                          np.zeros(self.dim) if shift is None else np.asarray(shift, dtype=float), out)
        return out

    def footprints_in_ghosts(self, x, kind):
        """Do the footprints of positions ``x`` (shape functions of kernel
        ``kind``, :mod:`pimpm.kernels.transfer`) lie in this rank's ghosted
        node box, so that this rank can scatter and gather them?"""
        return bool(transfer.footprints_in_box(kind, np.ascontiguousarray(x, dtype=float), self.lower, self.spacing,
                                               self.cells, self.ghost_start, self.ghost_end))

    def key_descents(self, x, shift=None):
        """How many positions have a smaller :meth:`cell_keys` key than the
        one before them (compiled, no keys stored)."""
        return int(reorder.key_descents(np.ascontiguousarray(x, dtype=float), self.lower, self.spacing,
                                        self.cells, np.zeros(self.dim) if shift is None else
                                        np.asarray(shift, dtype=float)))

    def owner_of_cells(self, cells):
        """MPI rank owning each cell (n, dim): the owner of the cell's lower node."""
        rank = np.zeros(len(cells), dtype=np.int64)
        stride = 1
        for d in range(self.dim):
            q = np.searchsorted(self._axis_ends[d], cells[:, d], side="right")
            rank += q * stride
            stride *= self.proc_sizes[d]
        return rank

    def local_cell_index(self, cells):
        """Linear index of owned cells relative to this rank's owned cell box
        (used to group particles by cell)."""
        shape = self.owned_cell_end - self.owned_cell_start
        index = cells[:, -1] - self.owned_cell_start[-1]
        for d in range(self.dim - 2, -1, -1):
            index = index * shape[d] + (cells[:, d] - self.owned_cell_start[d])
        return index

    def global_cell_index(self, cells):
        """Linear natural index of cells (x fastest)."""
        index = cells[:, -1].copy()
        for d in range(self.dim - 2, -1, -1):
            index = index * self.cells[d] + cells[:, d]
        return index

    # ------------------------------------------------------------------ vectors
    def owned_view(self, array):
        """Reshape an owned (global Vec) dof array to ``owned_shape + (dim,)``
        with the x axis first."""
        shape = tuple(int(s) for s in self.owned_shape[::-1]) + (self.dim,)
        a = np.asarray(array).reshape(shape)
        return np.ascontiguousarray(np.moveaxis(a, list(range(self.dim)), list(range(self.dim))[::-1]))

    def owned_box(self):
        """(starts, sizes) of this rank's owned node box."""
        return tuple(int(s) for s in self.owned_start), tuple(int(s) for s in self.owned_shape)

    def node_coordinates_owned(self):
        """Coordinates (n_owned_nodes, dim) of the owned nodes, PETSc order."""
        return self.lower + self.owned_node_ijk * self.spacing

    def box_preallocation(self, width):
        """For every owned node (PETSc order): how many nodes lie within
        ``width`` of it along every axis (the DMDA box stencil), on this rank
        and on others. An upper bound of a tangent's block row lengths."""
        lo = np.maximum(self.owned_node_ijk - width, 0)
        hi = np.minimum(self.owned_node_ijk + width, self.nodes - 1)
        total = np.prod(hi - lo + 1, axis=1)
        own_lo = np.maximum(lo, self.owned_start)
        own_hi = np.minimum(hi, self.owned_end - 1)
        own = np.prod(np.maximum(own_hi - own_lo + 1, 0), axis=1)
        return own, total - own

    def face_dofs(self, face, components):
        """Owned dof indices (into the owned/global-local array) of the nodes
        on a grid face (e.g. ``"xmin"``) for the given components."""
        axis = "xyz".index(face[0])
        value = 0 if face.endswith("min") else int(self.cells[axis])
        nodes = np.nonzero(self.owned_node_ijk[:, axis] == value)[0]
        comps = np.asarray(components, dtype=np.int64)
        return (nodes[:, None] * self.dim + comps[None, :]).ravel()

    # ----------------------------------------------------- local <-> global sums
    def _scratch(self):
        if not hasattr(self, "_local_vec"):
            self._local_vec = self.da.createLocalVec()
            self._global_vec = self.da.createGlobalVec()
        return self._local_vec, self._global_vec

    def sum_to_owned(self, local_values):
        """Sum ghosted-local nodal values (n_local_nodes, dim) over all ranks
        (DMDA localToGlobal with ADD); returns this rank's owned dof array
        (n_owned_nodes * dim,) in PETSc order. Collective."""
        lvec, gvec = self._scratch()
        lvec.getArray()[:] = np.asarray(local_values, dtype=float).reshape(-1)
        gvec.zeroEntries()
        self.da.localToGlobal(lvec, gvec, addv=PETSc.InsertMode.ADD_VALUES)
        return gvec.getArray().copy()

    def sum_columns_to_owned(self, local_values):
        """Sum ghosted-local nodal values (n_local_nodes, k) of any width k
        over all ranks in one exchange (a DMDA of k dofs per node, made once
        per width); returns this rank's owned values (n_owned_nodes, k), in
        PETSc's node order. The sums are those of :meth:`sum_to_owned`
        column by column (the same contributions, added in the same order).
        Collective."""
        k = local_values.shape[1]
        da, lvec, gvec = self._wide_da(k)
        lvec.getArray()[:] = np.asarray(local_values, dtype=float).reshape(-1)
        gvec.zeroEntries()
        da.localToGlobal(lvec, gvec, addv=PETSc.InsertMode.ADD_VALUES)
        return gvec.getArray().reshape(-1, k).copy()

    def _wide_da(self, k):
        """The DMDA of ``k`` dofs per node on this grid's layout, with a local
        and a global vector (made once per width)."""
        if k not in self._wide:
            da = self.da.duplicate(dof=k)
            self._wide[k] = (da, da.createLocalVec(), da.createGlobalVec())
        return self._wide[k]

    def owned_columns_to_local(self, owned_values):
        """Ghosted-local copy (n_local_nodes, k) of owned nodal values
        (n_owned_nodes, k) of any width k. Collective."""
        k = owned_values.shape[1]
        da, lvec, gvec = self._wide_da(k)
        gvec.getArray()[:] = np.asarray(owned_values, dtype=float).reshape(-1)
        da.globalToLocal(gvec, lvec, addv=PETSc.InsertMode.INSERT_VALUES)
        return lvec.getArray().reshape(-1, k).copy()

    def max_columns_to_owned(self, local_values):
        """The largest of the ghosted-local nodal values (n_local_nodes, k)
        over all ranks, on the owned nodes (n_owned_nodes, k): a scatter with
        MAX (DMDA localToGlobal only adds or inserts). Collective."""
        k = local_values.shape[1]
        da, lvec, gvec = self._wide_da(k)
        if not hasattr(self, "_max_scatters"):
            self._max_scatters = {}
        if k not in self._max_scatters:
            indices = PETSc.IS().createGeneral(da.getLGMap().getIndices(), comm=PETSc.COMM_SELF)
            self._max_scatters[k] = PETSc.Scatter().create(lvec, None, gvec, indices)
            indices.destroy()
        lvec.getArray()[:] = np.asarray(local_values, dtype=float).reshape(-1)
        gvec.set(-np.inf)
        self._max_scatters[k].scatter(lvec, gvec, addv=PETSc.InsertMode.MAX_VALUES,
                                      mode=PETSc.ScatterMode.FORWARD)
        return gvec.getArray().reshape(-1, k).copy()

    def destroy(self):
        """Free the DMDAs (collective)."""
        for scatter in getattr(self, "_max_scatters", {}).values():
            scatter.destroy()
        self._max_scatters = {}
        for da, lvec, gvec in self._wide.values():
            for obj in (lvec, gvec, da):
                obj.destroy()
        self._wide = {}
        self.da.destroy()

    def sum_scalar_to_owned(self, local_values):
        """Sum a ghosted-local nodal scalar (n_local_nodes,) over all ranks and
        repeat it per component: an owned dof array like :meth:`sum_to_owned`
        (nodal masses and weights). Collective."""
        return self.sum_to_owned(np.repeat(np.asarray(local_values)[:, None], self.dim, axis=1))

    def owned_to_local(self, owned_values):
        """Ghosted-local copy (n_local_nodes, dim) of an owned dof array.
        Collective."""
        lvec, gvec = self._scratch()
        gvec.getArray()[:] = owned_values
        self.da.globalToLocal(gvec, lvec, addv=PETSc.InsertMode.INSERT_VALUES)
        return lvec.getArray().reshape(self.n_local_nodes, self.dim).copy()

    def natural_node_index(self):
        """Natural (x fastest) linear index of each owned node, in owned order."""
        ijk = self.owned_node_ijk
        index = ijk[:, -1]
        for d in range(self.dim - 2, -1, -1):
            index = index * self.nodes[d] + ijk[:, d]
        return index

    def transfer_owned(self, values, other):
        """Owned nodal ``values`` (``k`` per node) of this grid as owned values
        of ``other``, the same grid partitioned differently. Collective. Through
        PETSc's natural (x fastest) ordering of the DMDAs: each rank sends and
        receives only what changes owner, no rank holds the whole grid."""
        k = len(values) // self.n_owned_nodes                 # every rank owns nodes
        source, _, g_source = self._wide_da(k)
        target, _, g_target = other._wide_da(k)
        n_source, n_target = source.createNaturalVec(), target.createNaturalVec()
        g_source.getArray()[:] = values
        source.globalToNatural(g_source, n_source)
        # the natural numbering is the same in both: entry i goes to entry i
        start, end = n_target.getOwnershipRange()
        wanted = PETSc.IS().createStride(end - start, first=start, step=1, comm=PETSc.COMM_SELF)
        scatter = PETSc.Scatter().create(n_source, wanted, n_target, wanted)
        scatter.scatter(n_source, n_target, addv=PETSc.InsertMode.INSERT_VALUES)
        target.naturalToGlobal(n_target, g_target)
        out = g_target.getArray(readonly=True).copy()
        for obj in (scatter, wanted, n_source, n_target):
            obj.destroy()
        return out

    def vec_to_local(self, vec):
        """Ghosted-local copy (n_local_nodes, dim) of a global Vec. Collective."""
        lvec, _ = self._scratch()
        self.da.globalToLocal(vec, lvec, addv=PETSc.InsertMode.INSERT_VALUES)
        return lvec.getArray().reshape(self.n_local_nodes, self.dim).copy()

    def global_dof_offset(self):
        """First global row of this rank's owned dofs."""
        _, gvec = self._scratch()
        return gvec.getOwnershipRange()[0]
