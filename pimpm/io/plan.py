"""Defensive planning of one collective output step: every rank describes
what it holds, one ``allgather`` agrees on all sizes, offsets, dtypes and
field lists before any HDF5 call, so every rank performs the same sequence
of (collective) metadata operations with identical arguments, and input
errors raise the same ``ValueError`` on every rank instead of hanging the run."""
import numpy as np

from .layout import _classify, _file_dtype, _step_name


class StepPlanner:
    """Plans writes for a grid of ``nodes`` (per axis) in ``dim`` dimensions."""

    def __init__(self, comm, dim, nodes):
        self.comm = comm
        self.rank = comm.Get_rank()
        self.dim = dim
        self.nodes = nodes

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

    def plan(self, step, time, particle_fields, grid_fields, grid_box):
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
            if name == "id" and kind == "Scalar" and dtype.kind in "iu":
                kind = "GlobalId"  # ParaView follows a particle by it across steps
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


def plan_bytes(plan):
    """The bytes of the datasets a step ``plan`` writes (every rank's share)."""
    total = 0
    for part in ("particles", "grid"):
        if plan[part] is not None:
            for f in plan[part]["fields"].values():
                total += int(np.prod(f["shape"], dtype=np.int64)) * np.dtype(f["dtype"]).itemsize
    return total
