"""The time loop of a run: step control (failed steps cut and retried) and
observers that see every step (history, output, progress, statistics).
The command line and the scripts under ``scripts/`` all run simulations
through :class:`Analysis`, so none re-implements the loop.
"""
import json
import os
import resource
import sys
import time as wallclock

from mpi4py import MPI

from . import interrupt
from .errors import OutputFailed, StepFailed, UsageError
from .io import History, ResultWriter, prepare_output_directory, write_results
from .io.checkpoint import PHYSICS_KEYS, physics_json, read_checkpoint, write_checkpoint
from .io.history import history_columns
from .io.restart import check_restart_files
from .resources import describe_bytes
from .simulation import Simulation
from .stages import log_stage
from .step_control import TimeStepControl
from .summary import summary


class Observer:
    """Sees the run: every method gets the :class:`Analysis` first."""

    def start(self, analysis):
        """Before the first step."""

    def step(self, analysis, info):
        """After each successful step (``info``: the step's data, with
        ``step_cuts`` and ``final`` set)."""

    def cut(self, analysis, failure):
        """A step failed and is retried at ``analysis.control.dt``."""

    def failed(self, analysis, failure):
        """A step failed with no cut left: the run stops."""

    def interrupted(self, analysis, stop):
        """A signal stopped the run (``stop``: pimpm.interrupt.Interrupted);
        the simulation is at its last completed step."""

    def output_failed(self, analysis, failure):
        """Writing the results failed (pimpm.errors.OutputFailed): the run
        stops, writing nothing more."""

    def finish(self, analysis, status):
        """After the loop (status 0 done, 1 numerical failure)."""

    def close(self):
        """Release files: after the loop, and after an exception on one rank
        (on several ranks an unexpected exception leaves them open)."""


class Analysis:
    """Runs ``sim`` to ``time.end_time`` with :class:`TimeStepControl`."""

    def __init__(self, sim, observers=(), control=None):
        self.sim = sim
        self.observers = list(observers)
        self.control = control or TimeStepControl(sim.config["time"])
        self.failure = None          # the message of the step that stopped the run

    def _notify(self, event, *args):
        for observer in self.observers:
            getattr(observer, event)(self, *args)

    def run(self, max_steps=None):
        """Returns 0 when the end time (or ``max_steps``) was reached, 1 when
        a step failed with no cut left, 128 + the signal's number when a
        SIGTERM or SIGINT stopped it (:mod:`pimpm.interrupt`; the step in
        progress is abandoned); the observers are closed then. An
        unexpected exception propagates; on several ranks the observers are
        left open, since closing them is collective and the other ranks may
        be waiting in another collective (the CLI then stops every rank with
        MPI_Abort)."""
        sim, control = self.sim, self.control
        status = 0
        try:
            try:
                self._notify("start")
                while not control.done(sim.time) and (max_steps is None or sim.step_index < max_steps):
                    interrupt.inject(sim.comm.rank, sim.step_index + 1)
                    interrupt.check(sim.comm)                 # collective, at every step boundary
                    if sim.integrator.explicit:
                        control.set_explicit_step(sim)
                    try:
                        info = sim.advance(control.next_dt(sim.time))
                    except StepFailed as failure:
                        if control.failed():
                            self._notify("cut", failure)
                            continue
                        self.failure = str(failure)
                        self._notify("failed", failure)
                        status = 1
                        break
                    info["step_cuts"] = control.succeeded(info["newton_iterations"])
                    info["final"] = control.done(sim.time)
                    self._notify("step", info)
            except interrupt.Interrupted as stop:             # on every rank at once
                self._notify("interrupted", stop)
                status = stop.exit_status
            except OutputFailed as failure:                   # on every rank at once
                self.failure = str(failure)
                self._notify("output_failed", failure)
                status = 1
            self._notify("finish", status)
        except BaseException:
            if sim.comm.size == 1:
                self._close()
            raise
        self._close()
        return status

    def _close(self):
        for observer in self.observers:
            observer.close()


class HistoryObserver(Observer):
    """``history.csv``, one row per step (``restart``: continue the file,
    dropping rows after the checkpoint's step)."""

    def __init__(self, sim, path, restart=False):
        self.history = History(sim.comm, path, dim=sim.dim, continue_after=sim.step_index if restart else None,
                               **history_names(sim))

    def step(self, analysis, info):
        self.history.write(info)

    def close(self):
        self.history.close()


def history_names(sim):
    """The rigid bodies, loads and contact tools that history.csv has columns for."""
    return {"rigid_names": [b.name for b in sim.rigid_bodies], "load_names": [load.name for load in sim.loads],
            "contact_names": sim.contact_names}


def restart_line(sim, directory):
    """The summary's line for a run that continues a checkpoint."""
    return f"  restart   from step {sim.step_index} (t = {sim.time:.6g}) of {directory}/checkpoint.h5"


class OutputObserver(Observer):
    """results.h5 and the XDMF files: the initial state, every ``every``
    steps, the last step, and after a failure or an interruption the last
    good step. ``restart``: continue the files of a checkpointed run as if it
    had never stopped: the steps written after the checkpoint's are dropped,
    and so is the checkpoint's own step when it is off the ``every`` grid
    (written only because the run stopped there); an on-grid one is kept
    and not written again."""

    def __init__(self, sim, directory, every, restart=False):
        grid = sim.grid
        self.writer = ResultWriter(sim.comm, directory, sim.dim, grid.lower, grid.spacing, grid.nodes,
                                   append=restart)
        self.every = every
        self.written = -1
        if restart:
            kept = sim.step_index if sim.step_index % every == 0 else sim.step_index - 1
            self.writer.drop_steps_after(kept)
            self.written = kept
        self.restart = restart

    def _write(self, sim):
        with log_stage(sim.stages["Output"]):
            write_results(sim, self.writer)
        self.written = sim.step_index

    def start(self, analysis):
        if not self.restart:
            self._write(analysis.sim)

    def step(self, analysis, info):
        if info["step"] % self.every == 0 or info["final"]:
            self._write(analysis.sim)

    def output_failed(self, analysis, failure):
        self.every = None                         # write nothing more

    def finish(self, analysis, status):
        if status and self.every is not None and self.written != analysis.sim.step_index:
            self._write(analysis.sim)             # keep the last good state

    def close(self):
        self.writer.close()


class CheckpointObserver(Observer):
    """``checkpoint.h5`` (pimpm.io.checkpoint): every ``every`` steps (0:
    never), and always when the run stops on a failure or a signal, so that
    it can be continued from its last good step."""

    def __init__(self, sim, directory, every):
        self.directory = directory
        self.every = every

    def _write(self, analysis):
        with log_stage(analysis.sim.stages["Output"]):
            write_checkpoint(analysis.sim, analysis.control, self.directory)

    def step(self, analysis, info):
        if self.every and info["step"] % self.every == 0:
            self._write(analysis)

    def failed(self, analysis, failure):
        self._write(analysis)

    def interrupted(self, analysis, stop):
        self._write(analysis)


class ProgressObserver(Observer):
    """One line per step on rank 0; cuts, failures, interruptions and the end said."""

    def __init__(self, sim, directory, echo=print, input_path=None):
        self.input_path = input_path or "INPUT.yaml"
        self.rigid_names = [b.name for b in sim.rigid_bodies]
        self.directory = directory
        self.root = sim.comm.rank == 0
        self.echo = echo
        self.start_time = wallclock.perf_counter()

    def step(self, analysis, info):
        if self.root:
            self.echo(progress_line(info, self.rigid_names), flush=True)

    def cut(self, analysis, failure):
        if self.root:
            self.echo(f"pimpm: {failure}; cutting the step to {analysis.control.dt:.4g} and retrying")

    def failed(self, analysis, failure):
        sim = analysis.sim
        if self.root:
            print(f"pimpm: error: {failure}, even after {analysis.control.max_cuts} step cuts. "
                  f"Results up to step {sim.step_index} (t = {sim.time:.6g}) are in {self.directory}.",
                  file=sys.stderr, flush=True)

    def output_failed(self, analysis, failure):
        sim = analysis.sim
        if self.root:
            checkpoint = os.path.join(self.directory, "checkpoint.h5")
            resume = (f"the run continues from {checkpoint} with 'python -m pimpm {self.input_path} "
                      f"--restart' once there is room" if os.path.isfile(checkpoint) else
                      "no checkpoint was written (output.checkpoint_every)")
            print(f"pimpm: error: {failure}. The run stops after step {sim.step_index} "
                  f"(t = {sim.time:.6g}); the results written before are intact; {resume}",
                  file=sys.stderr, flush=True)

    def interrupted(self, analysis, stop):
        sim = analysis.sim
        if self.root:
            print(f"pimpm: {stop} during step {sim.step_index + 1}; the state after step "
                  f"{sim.step_index} (t = {sim.time:.6g}) is in {self.directory}/checkpoint.h5 and its "
                  f"results are kept: continue with 'python -m pimpm {self.input_path} --restart'",
                  file=sys.stderr, flush=True)

    def finish(self, analysis, status):
        memory = memory_line(analysis.sim)          # collective
        if status == 0 and self.root:
            self.echo(f"pimpm: finished {analysis.sim.step_index} steps in "
                      f"{wallclock.perf_counter() - self.start_time:.1f} s; results in "
                      f"{self.directory}/ (particles.xdmf, grid.xdmf, history.csv)")
            self.echo(memory)


def memory_line(sim):
    """What the run used, against the start-up estimate (the summary's
    ``memory`` line): the peak resident memory of the ranks, summed and the
    largest, and the direct solver's largest factorization. Collective."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024.0     # Linux: kB
    total = sim.comm.allreduce(peak)
    largest = sim.comm.allreduce(peak, op=MPI.MAX)
    line = (f"pimpm: memory   peak {describe_bytes(total)} resident on {sim.comm.size} "
            f"rank{'s' if sim.comm.size > 1 else ''}")
    if sim.comm.size > 1:
        line += f" ({describe_bytes(largest)} the largest)"
    line += f", estimated {describe_bytes(sim.memory_estimate)}"
    free_dofs = sim.solver.free_dofs if sim.solver is not None else None
    factorization = free_dofs.largest_factorization if free_dofs is not None else None
    if factorization is not None:         # MUMPS counts whole MB (10^6 bytes)
        used = describe_bytes(factorization[1]) if factorization[1] > 0 else "under 1 MB"
        line += f"; the largest factorization {used} ({factorization[0]:,} free dofs, MUMPS)"
    return line


class Trace(Observer):
    """For scripts and tests: ``measure(sim)`` after every step, as
    (time, value) pairs in ``values``, starting with (0, ``initial``).
    ``measure`` is called on every rank (it may be collective)."""

    def __init__(self, measure, initial=0.0):
        self.measure = measure
        self.values = [(0.0, initial)]

    def step(self, analysis, info):
        self.values.append((analysis.sim.time, self.measure(analysis.sim)))


class StepStatistics(Observer):
    """Totals for scripts: steps, cuts, Newton iterations, the last step's
    forces and the largest relative departure of the total energy (kinetic
    + strain) from its initial value."""

    def __init__(self):
        self.newton = 0
        self.cuts = 0
        self.energy = 0.0
        self.forces = {}
        self.energy0 = None
        self.failure = None          # the message of the step that stopped the run, or None
        self.steps = 0

    def start(self, analysis):
        sim = analysis.sim
        self.energy0 = sim.kinetic_energy() + sim.strain_energy()

    def step(self, analysis, info):
        self.cuts += info["step_cuts"]
        self.newton += info["newton_iterations"]
        self.forces = info["forces"]
        if self.energy0 > 0:
            departure = abs(info["kinetic_energy"] + info["strain_energy"] - self.energy0) / self.energy0
            self.energy = max(self.energy, departure)

    def finish(self, analysis, status):
        self.failure = analysis.failure
        self.steps = analysis.sim.step_index


def progress_line(info, rigid_names):
    forces = " ".join(f"{name} F=(" + ", ".join(f"{f:.4e}" for f in info["forces"][name]) + ")"
                      for name in rigid_names)
    notes = ""
    for name, contact in info.get("contact", {}).items():
        notes += f"  {name} contact {contact['contact_points']}"
    if info["backtracks"] > 0:
        notes += f"  backtracks {info['backtracks']}"
    if info["linear_fallbacks"]:
        notes += f"  direct fallbacks {info['linear_fallbacks']}"
    if info["step_cuts"]:
        notes += f"  dt cuts {info['step_cuts']}"
    if info.get("particle_imbalance", 1.0) > 1.1:
        notes += f"  particle imbalance {info['particle_imbalance']:.2f}"
    if info.get("explicit"):
        return (f"step {info['step']:5d}  t {info['time']:.5e}  dt {info['dt']:.3e}  "
                f"kinetic {info['kinetic_energy']:.4e}  strain {info['strain_energy']:.4e}  {forces}  "
                f"wall {info['wall_time']:.3f} s{notes}")
    return (f"step {info['step']:5d}  t {info['time']:.5e}  dt {info['dt']:.3e}  "
            f"newton {info['newton_iterations']:2d}  linear {info['linear_iterations']:4d}  "
            f"|R| {info['residual_initial']:.3e} -> {info['residual_final']:.3e}  {forces}  "
            f"wall {info['wall_time']:.2f} s{notes}")


def run(config, comm, overwrite=False, echo=print, restart=False, input_path=None):
    """Run the whole simulation of a validated configuration with output.
    Returns 0 on success, 1 on numerical failure (the results up to the
    last good step are kept, and a checkpoint of it), 128 + the signal's
    number when SIGTERM or SIGINT stopped it (likewise). ``restart``:
    continue from the checkpoint in the output directory (UsageError if
    there is none, or if the input's grid, materials or bodies changed)."""
    directory = config["output"]["directory"]
    control = TimeStepControl(config["time"])
    if restart:
        sim = prepare_restart(config, comm, control)
    else:
        sim = Simulation(config, comm)          # bad solver options fail here, before any output
        prepare_output_directory(comm, directory, overwrite)
    for line in summary(sim, config):
        if comm.rank == 0:
            echo(line)
    if restart and comm.rank == 0:
        echo(restart_line(sim, directory))
    # a step's checkpoint after its results and history row: a restart takes the
    # results of the checkpoint's step as written (issue 32: a full disk between the
    # two lost that step for good)
    observers = [ProgressObserver(sim, directory, echo, input_path),
                 OutputObserver(sim, directory, config["output"]["every"], restart),
                 HistoryObserver(sim, os.path.join(directory, "history.csv"), restart),
                 CheckpointObserver(sim, directory, config["output"]["checkpoint_every"])]
    status = Analysis(sim, observers, control).run()
    if sim.solver is not None:     # (after an exception, the exit handler frees it on every rank)
        sim.solver.destroy()
    return status


def prepare_restart(config, comm, control):
    """The Simulation continued from the checkpoint of ``config``'s output
    directory, and ``control`` restored from it, after checking (before
    anything is written: a restart is a transaction) the checkpoint, that
    there is time left to run, and the results and history it continues.
    Collective; UsageError or SetupError on every rank otherwise."""
    directory = config["output"]["directory"]
    checkpoint = open_checkpoint(config, comm)
    try:
        sim = Simulation(config, comm, checkpoint)
    except KeyError as err:         # a particle field the run needs is not in it
        raise UsageError(f"output.directory = {directory!r}: checkpoint.h5 has no {err}: expected "
                         "the checkpoint of a run of this input") from None
    control.restore(checkpoint.control)
    steps = (control.dt, control.target, control.initial)
    if (None in steps and not sim.integrator.explicit) or (control.dt is None and control.cuts > 0):
        raise UsageError(f"output.directory = {directory!r}: no usable checkpoint.h5 to restart from "
                         f"(its step sizes {checkpoint.control}): expected the checkpoint of a run of this input")
    if control.done(sim.time):
        raise UsageError(f"time.end_time = {config['time']['end_time']!r}: expected a time after the "
                         f"checkpoint's t = {sim.time:.6g} (step {sim.step_index}) to continue to")
    try:
        check_restart_files(comm, directory, sim.grid, history_columns(dim=sim.dim, **history_names(sim)),
                            step=sim.step_index, time=sim.time)
    except ValueError as err:
        raise UsageError(f"output.directory = {directory!r}: cannot continue its results: {err}") from None
    return sim


def open_checkpoint(config, comm):
    """The checkpoint of ``config``'s output directory, after checking that
    the input still describes the same physical problem. Collective;
    UsageError otherwise."""
    directory = config["output"]["directory"]
    try:
        checkpoint = read_checkpoint(directory, comm)
    except (OSError, KeyError, ValueError) as err:
        raise UsageError(f"output.directory = {directory!r}: no usable checkpoint.h5 to restart from "
                         f"({err}): expected the directory of a run that wrote one") from None
    saved = checkpoint.physics
    now = json.loads(physics_json(config))
    for key in PHYSICS_KEYS:
        if saved.get(key) != now.get(key):
            raise UsageError(f"{key} differs from the checkpointed run's: expected the same grid, "
                             f"kinematics, materials and bodies to restart (time, solver and output "
                             f"may change)")
    return checkpoint


def run_to_end(raw_or_config, comm=None, observers=(), max_steps=None):
    """For scripts: build a Simulation from a validated config, run it with
    the library's loop and step control (no files written) and return
    ``(sim, statistics, status)``; ``statistics`` is a StepStatistics. The solver is
    destroyed; the particles stay readable."""
    from mpi4py import MPI
    sim = Simulation(raw_or_config, MPI.COMM_WORLD if comm is None else comm)
    stats = StepStatistics()
    analysis = Analysis(sim, [stats] + list(observers))
    try:
        status = analysis.run(max_steps=max_steps)
    finally:
        if sim.solver is not None:
            sim.solver.destroy()
    return sim, stats, status
