"""Runs a simulation from a validated configuration: the time loop, the
progress line, the CSV history and the HDF5/XDMF results."""
import csv
import sys
import math
import os
import time as wallclock

import numpy as np

from .output import ResultWriter
from .simulation import Simulation, StepFailed
from .stages import log_stage

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
    steps = step_times(t["end_time"], t["dt"]) if t["dt"] is not None else []
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
    if t["dt"] is None:
        lines.append(f"  time      explicit, automatic dt = {t['cfl']:g} x CFL step "
                     f"(now {t['cfl'] * dt_explicit:.3g}), end {t['end_time']:g}")
    else:
        scheme = t["integrator"] + (" (momentum formulation)" if t["formulation"] == "momentum" else "")
        lines.append(f"  time      {scheme}, dt {t['dt']:g} ({t['dt'] / dt_explicit:.3g} x "
                     f"explicit CFL step {dt_explicit:.3g}), end {t['end_time']:g}, "
                     f"{len(steps)} steps")
    lines.append(f"  output    {config['output']['directory']} every {config['output']['every']} steps")
    if sim.solver is not None:
        lines.append(f"  solver    {sim.solver.describe()}")
    else:
        lines.append(f"  solver    explicit ({t['stress_update'].upper()}), no linear solves")
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
    if comm.rank == 0 and problem is None:
        try:
            os.makedirs(directory, exist_ok=True)
            for f in OUTPUT_FILES:
                if os.path.exists(os.path.join(directory, f)):
                    os.remove(os.path.join(directory, f))
        except OSError as err:
            problem = (f"output.directory = {directory!r}: cannot be created or cleared "
                       f"({err.strerror}): expected a writable directory path")
    problem = comm.bcast(problem)
    if problem:
        raise UsageError(problem)


class History:
    """history.csv, one row per step (rank 0 writes; flushed every row)."""

    def __init__(self, comm, path, rigid_names, dim):
        self.comm = comm
        self.rigid_names = rigid_names
        self.dim = dim
        self.columns = ["step", "time", "dt", "newton_iterations", "linear_iterations",
                        "backtracks", "linear_fallbacks", "step_cuts",
                        "residual_initial", "residual_final", "kinetic_energy", "strain_energy",
                        "total_energy", "external_work"]
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
               info["linear_iterations"], info["backtracks"], info["linear_fallbacks"],
               info["step_cuts"], repr(info["residual_initial"]), repr(info["residual_final"]),
               repr(info["kinetic_energy"]), repr(info["strain_energy"]),
               repr(info["kinetic_energy"] + info["strain_energy"]), repr(info["external_work"])]
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
    notes = ""
    if info["backtracks"] > 0:
        notes += f"  backtracks {info['backtracks']}"
    if info["linear_fallbacks"]:
        notes += f"  direct fallbacks {info['linear_fallbacks']}"
    if info["step_cuts"]:
        notes += f"  dt cuts {info['step_cuts']}"
    if info.get("explicit"):
        return (f"step {info['step']:5d}  t {info['time']:.5e}  dt {info['dt']:.3e}  "
                f"kinetic {info['kinetic_energy']:.4e}  strain {info['strain_energy']:.4e}  {forces}  "
                f"wall {info['wall_time']:.3f} s{notes}")
    return (f"step {info['step']:5d}  t {info['time']:.5e}  dt {info['dt']:.3e}  "
            f"newton {info['newton_iterations']:2d}  linear {info['linear_iterations']:4d}  "
            f"|R| {info['residual_initial']:.3e} -> {info['residual_final']:.3e}  {forces}  "
            f"wall {info['wall_time']:.2f} s{notes}")


class TimeStepControl:
    """Step sizes: an optional ramp from ``dt_initial`` up to ``dt`` by at most
    ``ramp_factor`` per step (Sulsky & Kaul 3.1.1 use 20%); a failed step is
    cut in half and retried, at most ``max_cuts`` times in a row; after a cut,
    dt grows back by ``ramp_factor`` after each easy step (at most
    ``easy_newton_iterations`` Newton iterations). The last step is shortened
    to land on ``end_time``."""

    def __init__(self, time_config):
        self.fixed = time_config["dt"]
        self.target = time_config["dt"]
        self.dt = time_config["dt_initial"]
        self.ramp = time_config["ramp_factor"]
        self.max_cuts = time_config["max_cuts"]
        self.easy = time_config["easy_newton_iterations"]
        self.end = time_config["end_time"]
        self.cuts = 0               # consecutive cuts of the current step

    def set_explicit_step(self, sim):
        """Explicit steps follow the CFL limit (or the fixed time.dt below it)."""
        stable = sim.stable_time_step()
        self.target = stable if self.fixed is None else min(self.fixed, stable / sim.config["time"]["cfl"])
        if self.cuts == 0:
            self.dt = self.target

    def done(self, time):
        return time >= self.end * (1.0 - 1e-12)

    def next_dt(self, time):
        remaining = self.end - time
        dt = self.dt
        # land on end_time exactly, without leaving a sliver for one more step
        return remaining if dt >= remaining * (1.0 - 1e-9) else dt

    def failed(self):
        """Cut the step; False when no cut is left."""
        if self.cuts >= self.max_cuts:
            return False
        self.cuts += 1
        self.dt *= 0.5
        return True

    def succeeded(self, newton_iterations):
        cuts, self.cuts = self.cuts, 0
        if newton_iterations <= self.easy and self.dt < self.target:
            self.dt = min(self.target, self.dt * self.ramp)
        return cuts


def run(config, comm, overwrite=False, echo=print):
    """Run the whole simulation. Returns 0 on success, 1 on numerical failure
    (the results up to the last good step are kept)."""
    say = echo if comm.rank == 0 else (lambda *a, **k: None)

    def error(message):
        if comm.rank == 0:
            print(message, file=sys.stderr, flush=True)

    directory = config["output"]["directory"]
    sim = Simulation(config, comm)          # bad solver options fail here, before any output
    prepare_output_directory(comm, directory, overwrite)
    for line in summary(sim, config):
        say(line)
    writer = ResultWriter(comm, directory, sim.dim, sim.grid.lower, sim.grid.spacing, sim.grid.nodes)
    rigid_names = [name for _, name, _, _ in sim.rigid_bodies]
    history = History(comm, os.path.join(directory, "history.csv"), rigid_names, sim.dim)
    every = config["output"]["every"]
    control = TimeStepControl(config["time"])
    start = wallclock.perf_counter()
    status = 0
    written = -1
    try:
        write_results(sim, writer)
        written = sim.step_index
        while not control.done(sim.time):
            if sim.explicit:
                control.set_explicit_step(sim)
            dt = control.next_dt(sim.time)
            try:
                info = sim.advance(dt)
            except StepFailed as failure:
                if control.failed():
                    say(f"pimpm: {failure}; cutting the step to {control.dt:.4g} and retrying")
                    continue
                error(f"pimpm: error: {failure}, even after {control.max_cuts} step cuts. Results up "
                      f"to step {sim.step_index} (t = {sim.time:.6g}) are in {directory}.")
                status = 1
                break
            info["step_cuts"] = control.succeeded(info["newton_iterations"])
            history.write(info)
            say(progress_line(info, rigid_names), flush=True)
            if info["step"] % every == 0 or control.done(sim.time):
                write_results(sim, writer)
                written = sim.step_index
        if status and written != sim.step_index:
            write_results(sim, writer)             # keep the last good state
    finally:
        writer.close()
        history.close()
        if sim.solver is not None:
            sim.solver.destroy()
    if status == 0:
        say(f"pimpm: finished {sim.step_index} steps in {wallclock.perf_counter() - start:.1f} s; "
            f"results in {directory}/ (particles.xdmf, grid.xdmf, history.csv)")
    return status


def write_results(sim, writer):
    with log_stage(sim.stages["Output"]):
        writer.write_step(sim.step_index, sim.time, sim.particle_output(), sim.grid_output(),
                          sim.grid.owned_box())
