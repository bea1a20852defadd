"""``history.csv``: one row per step (rank 0 writes; flushed every row)."""
import csv
import io
import os

from ..errors import OutputFailed
from .safe_files import atomic_write_text, open_append, open_new


#: each contact tool's columns: the sum of its pressures times areas, the
#: length of the sum of its tangential forces, the area (length in 2D) in
#: contact and the number of particle-domain corners pressing on it
CONTACT_COLUMNS = ("normal_force", "tangential_force", "contact_area", "contact_points")


def history_columns(rigid_names, dim, load_names=(), contact_names=()):
    """The columns of ``history.csv`` for these rigid bodies, loads and
    contact tools."""
    columns = ["step", "time", "dt", "newton_iterations", "linear_iterations",
               "backtracks", "linear_fallbacks", "step_cuts",
               "residual_initial", "residual_final", "kinetic_energy", "strain_energy",
               "total_energy", "external_work"]
    for name in list(rigid_names) + list(load_names):
        columns += [f"{name}_force_{a}" for a in "xyz"[:dim]]
        columns += [f"{name}_displacement_{a}" for a in "xyz"[:dim]]
    for name in contact_names:        # tools in unilateral contact (pimpm.terms.contact)
        columns += [f"{name}_{c}" for c in CONTACT_COLUMNS]
    if contact_names:
        columns.append("frictional_dissipation")
    return columns + ["particle_imbalance", "wall_time"]


class History:
    """``continue_after``: continue an existing file (a restart), keeping its
    rows up to that step and dropping those after it."""

    def __init__(self, comm, path, rigid_names, dim, continue_after=None, load_names=(), contact_names=()):
        self.comm = comm
        self.path = path
        self.rigid_names = rigid_names
        self.load_names = list(load_names)
        self.contact_names = list(contact_names)
        self.dim = dim
        self.columns = history_columns(rigid_names, dim, self.load_names, self.contact_names)
        self.file = None
        if comm.rank == 0:
            if continue_after is None:
                self.file = open_new(path, newline="")
                self.writer = csv.writer(self.file)
                self.writer.writerow(self.columns)
                self.file.flush()
            else:
                self._keep_rows_up_to(path, continue_after)
                self.file = open_append(path, newline="")
                self.writer = csv.writer(self.file)

    def _keep_rows_up_to(self, path, step):
        rows = []
        if os.path.isfile(path) and not os.path.islink(path):
            with open(path, newline="") as f:
                rows = [r for r in csv.reader(f)]
        kept = [self.columns] + [r for r in rows[1:] if r and int(r[0]) <= step]
        text = io.StringIO()
        csv.writer(text).writerows(kept)
        atomic_write_text(path, text.getvalue())

    def write(self, info):
        """Append the step's row (rank 0). Collective: a failed write (a full
        disk) is OutputFailed on every rank."""
        error = None
        if self.file is not None:
            try:
                self._write_row(info)
            except OSError as err:
                error = f"{type(err).__name__}: {err}"
        if self.comm.size > 1:
            error = self.comm.bcast(error, root=0)
        if error is not None:
            raise OutputFailed(f"writing {self.path} failed ({error})")

    def _write_row(self, info):
        row = [info["step"], repr(info["time"]), repr(info["dt"]), info["newton_iterations"],
               info["linear_iterations"], info["backtracks"], info["linear_fallbacks"],
               info["step_cuts"], repr(info["residual_initial"]), repr(info["residual_final"]),
               repr(info["kinetic_energy"]), repr(info["strain_energy"]),
               repr(info["kinetic_energy"] + info["strain_energy"]), repr(info["external_work"])]
        for name in self.rigid_names:
            row += [repr(float(f)) for f in info["forces"][name]]
            row += [repr(float(u)) for u in info["displacements"][name]]
        for name in self.load_names:
            row += [repr(float(f)) for f in info["load_forces"][name]]
            row += [repr(float(u)) for u in info["load_displacements"][name]]
        for name in self.contact_names:
            row += [repr(info["contact"][name][c]) for c in CONTACT_COLUMNS]
        if self.contact_names:
            row.append(repr(info["frictional_dissipation"]))
        row += [f"{info['particle_imbalance']:.4f}", f"{info['wall_time']:.4f}"]
        self.writer.writerow(row)
        self.file.flush()

    def close(self):
        if self.file is not None:
            self.file.close()
            self.file = None
