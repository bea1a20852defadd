"""Runs a simulation from a validated configuration: the time loop, the
progress line, the CSV history and the HDF5/XDMF results."""
import csv
import math
import os
import time as wallclock

import numpy as np

from .output import ResultWriter
from .simulation import Simulation, StepFailed

MAX_CUTS = 4   # a failed step is retried as two half steps, at most this many times
OUTPUT_FILES = ("results.h5", "particles.xdmf", "grid.xdmf", "history.csv")


class UsageError(Exception):
    """Bad use (existing output directory, ...): exit status 2, nothing written."""


def step_times(end_time, dt):
    """Time-step sizes to reach end_time: full steps then a shorter last one."""
    n = max(1, math.ceil(end_time / dt - 1e-9))
    sizes = [dt] * n
    sizes[-1] = end_time - dt * (n - 1)
    if sizes[-1] <= 1e-9 * dt:
        sizes.pop()
    return sizes


def explicit_time_step(sim):
    """Explicit CFL step dx / c for the stiffest material (MPM intro)."""
    h = float(np.min(sim.grid.spacing))
    return h / max(m.wave_speed() for m in sim.materials)


def summary(sim, config):
    """Problem summary lines (printed by --check and at the start of a run)."""
    comm = sim.comm
    counts = np.zeros(len(config["bodies"]), dtype=np.int64)
    for pset in (sim.particles, sim.rigid):
        counts += np.bincount(pset["body"], minlength=len(counts)).astype(np.int64)
    counts = comm.allreduce(counts)
    t = config["time"]
    steps = step_times(t["end_time"], t["dt"])
    cells = "x".join(str(int(c)) for c in sim.grid.cells)
    lines = [
        f"pimpm: {config.get('title') or 'untitled'}",
        f"  grid      {cells} cells, spacing {', '.join(f'{h:g}' for h in sim.grid.spacing)}, "
        f"{int(np.prod(sim.grid.nodes)) * sim.dim} unknowns, {config['kinematics']}, "
        f"{config['grid']['shape_functions']} shape functions",
        f"  ranks     {comm.size} (process grid {'x'.join(str(int(p)) for p in sim.grid.proc_sizes)})",
    ]
    for b, n in zip(config["bodies"], counts):
        kind = "rigid" if b.get("rigid") else f"material {b['material']}"
        lines.append(f"  body      {b['name']}: {int(n)} particles ({kind})")
    dt_explicit = explicit_time_step(sim)
    lines.append(f"  time      {t['integrator']}, dt {t['dt']:g} ({t['dt'] / dt_explicit:.3g} x explicit "
                 f"CFL step {dt_explicit:.3g}), end {t['end_time']:g}, {len(steps)} steps")
    lines.append(f"  output    {config['output']['directory']} every {config['output']['every']} steps")
    return lines


def prepare_output_directory(comm, directory, overwrite):
    """Refuse to overwrite results unless asked; create the directory.
    Collective; raises UsageError on every rank."""
    problem = None
    if comm.rank == 0:
        existing = [f for f in OUTPUT_FILES if os.path.exists(os.path.join(directory, f))]
        if os.path.exists(directory) and not os.path.isdir(directory):
            problem = f"output.directory = {directory!r}: exists and is not a directory"
        elif existing and not overwrite:
            problem = (f"output.directory = {directory!r} already holds results "
                       f"({', '.join(existing)}): expected a new directory "
                       f"(or pass --overwrite to replace them)")
    problem = comm.bcast(problem)
    if problem:
        raise UsageError(problem)
    if comm.rank == 0:
        os.makedirs(directory, exist_ok=True)
        for f in OUTPUT_FILES:
            if os.path.exists(os.path.join(directory, f)):
                os.remove(os.path.join(directory, f))
    comm.Barrier()


class History:
    """history.csv, one row per step (rank 0 writes; flushed every row)."""

    def __init__(self, comm, path, rigid_names, dim):
        self.comm = comm
        self.rigid_names = rigid_names
        self.dim = dim
        self.columns = ["step", "time", "dt", "newton_iterations", "linear_iterations",
                        "residual_initial", "residual_final", "kinetic_energy", "strain_energy"]
        for name in rigid_names:
            self.columns += [f"{name}_force_{a}" for a in "xyz"[:dim]]
        self.columns += ["wall_time"]
        self.file = None
        if comm.rank == 0:
            self.file = open(path, "w", newline="")
            self.writer = csv.writer(self.file)
            self.writer.writerow(self.columns)
            self.file.flush()

    def write(self, info):
        if self.file is None:
            return
        row = [info["step"], repr(info["time"]), repr(info["dt"]), info["newton_iterations"],
               info["linear_iterations"], repr(info["residual_initial"]), repr(info["residual_final"]),
               repr(info["kinetic_energy"]), repr(info["strain_energy"])]
        for name in self.rigid_names:
            row += [repr(float(f)) for f in info["forces"][name]]
        row += [f"{info['wall_time']:.4f}"]
        self.writer.writerow(row)
        self.file.flush()

    def close(self):
        if self.file is not None:
            self.file.close()
            self.file = None


def progress_line(info, rigid_names):
    forces = " ".join(f"{name} F=(" + ", ".join(f"{f:.4e}" for f in info["forces"][name]) + ")"
                      for name in rigid_names)
    return (f"step {info['step']:5d}  t {info['time']:.5e}  dt {info['dt']:.3e}  "
            f"newton {info['newton_iterations']:2d}  linear {info['linear_iterations']:4d}  "
            f"|R| {info['residual_initial']:.3e} -> {info['residual_final']:.3e}  {forces}  "
            f"wall {info['wall_time']:.2f} s")


def run(config, comm, overwrite=False, echo=print):
    """Run the whole simulation. Returns 0 on success, 1 on numerical failure
    (the results up to the last good step are kept)."""
    say = echo if comm.rank == 0 else (lambda *a, **k: None)
    directory = config["output"]["directory"]
    prepare_output_directory(comm, directory, overwrite)
    sim = Simulation(config, comm)
    for line in summary(sim, config):
        say(line)
    writer = ResultWriter(comm, directory, sim.dim, sim.grid.lower, sim.grid.spacing, sim.grid.nodes)
    rigid_names = [name for _, name, _, _ in sim.rigid_bodies]
    history = History(comm, os.path.join(directory, "history.csv"), rigid_names, sim.dim)
    every = config["output"]["every"]
    sizes = step_times(config["time"]["end_time"], config["time"]["dt"])
    start = wallclock.perf_counter()
    status = 0
    try:
        write_results(sim, writer)
        queue = list(sizes)
        smallest = min(sizes) / 2**MAX_CUTS
        while queue:
            dt = queue.pop(0)
            try:
                info = sim.advance(dt)
            except StepFailed as failure:
                if dt / 2 >= smallest * (1 - 1e-12):
                    say(f"pimpm: {failure}; cutting the step to {dt / 2:.4g} and retrying")
                    queue[:0] = [dt / 2, dt / 2]
                    continue
                say(f"pimpm: error: {failure}, even after {MAX_CUTS} step cuts. Results up to "
                    f"step {sim.step_index} (t = {sim.time:.6g}) are in {directory}.")
                status = 1
                break
            history.write(info)
            say(progress_line(info, rigid_names), flush=True)
            if info["step"] % every == 0 or not queue:
                write_results(sim, writer)
    finally:
        writer.close()
        history.close()
    if status == 0:
        say(f"pimpm: finished {sim.step_index} steps in {wallclock.perf_counter() - start:.1f} s; "
            f"results in {directory}/ (particles.xdmf, grid.xdmf, history.csv)")
    return status


def write_results(sim, writer):
    sim.stages["Output"].push()
    writer.write_step(sim.step_index, sim.time, sim.particle_output(), sim.grid_output(),
                      sim.grid.owned_box())
    sim.stages["Output"].pop()
