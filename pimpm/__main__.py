"""Command line: ``python -m pimpm INPUT.yaml [--check] [--overwrite] [--restart] [PETSc options]``."""
import argparse
import os
import sys
import traceback

HELP = """\
pimpm: parallel implicit Material Point Method (Guilkey & Weiss 2003) on PETSc.

usage: [mpiexec -n N] python -m pimpm INPUT.yaml [--check] [--overwrite] [--restart]
                                    [--output DIR] [--set KEY.PATH=VALUE ...] [PETSc options]

  INPUT.yaml     problem description (schema: docs/INPUT.md)
  --check        validate the input, print a summary (cells, particles per body,
                 ranks, dt, steps) and exit without running
  --overwrite    replace results already in the output directory
  --output DIR   write the results to DIR (overrides output.directory)
  --set KEY.PATH=VALUE
                 override any input value, validated as if it were in the file
                 (repeatable): --set time.dt=0.0025 --set grid.cells=[160,84]
                 --set bodies[1].velocity=[0,-25]
  --restart      continue from OUTDIR/checkpoint.h5 (written every
                 output.checkpoint_every steps, and when a run stops on a
                 failure, SIGTERM, SIGINT or SIGHUP); end_time, solver and output
                 settings may change, the grid, materials and bodies may not
  --help         this text

Any other option goes to PETSc and overrides the YAML `solver.petsc` block and
pimpm's defaults (Newton with backtracking line search, MUMPS LU), e.g.
  -snes_monitor -snes_converged_reason -ksp_type cg -pc_type gamg -log_view
  -options_file FILE   -help (PETSc's own option list)

Output: OUTDIR/results.h5, particles.xdmf and grid.xdmf (open in ParaView),
history.csv (one row per step), checkpoint.h5 (and its digest,
checkpoint.sha256). Exit status: 0 done,
1 numerical failure (results up to the last good step are kept, and a
checkpoint of it) or an unexpected error (on any rank: every rank stops),
2 bad input or usage, 143 / 130 / 129 stopped by SIGTERM / SIGINT / SIGHUP (the step in
progress is abandoned; results and a checkpoint of the last good step are
kept; a second signal stops at once).
"""


#: pimpm's own flags as a single dash would give them (then PETSc's options)
OWN_FLAGS = ("-check", "-overwrite", "-restart", "-output", "-set")


def split_arguments(argv):
    """Separate pimpm's own arguments from PETSc options: a single-dash token
    starts a PETSc option and the plain tokens after it are its values."""
    ours, petsc = [], []
    in_petsc_option = False
    for token in argv:
        if token.startswith("--"):
            ours.append(token)
            in_petsc_option = False
        elif token.startswith("-") and len(token) > 1:
            petsc.append(token)
            in_petsc_option = True
        elif in_petsc_option:
            petsc.append(token)
        else:
            ours.append(token)
    return ours, petsc


def options_file_problem(petsc_args):
    """The message for an -options_file that is not a readable regular file
    or whose contents PETSc would refuse at start-up (with an error block and
    a traceback, issue 32), or None."""
    for option, value in zip(petsc_args, petsc_args[1:] + [None]):
        if option in ("-options_file", "-options_file_yaml"):
            if value is None or value.startswith("-"):
                return f"{option}: expected a file name after it"
            if not os.path.isfile(value) or not os.access(value, os.R_OK):
                return f"{option} {value}: expected a readable file of PETSc options"
            problem = _options_file_contents_problem(option, value)
            if problem:
                return problem
    return None


def _options_file_contents_problem(option, path):
    """What PETSc would refuse in the options file ``path``: text that is
    not UTF-8, a line that is not '-option [value]' or 'alias -new -old'
    (comments from # or !), or for -options_file_yaml YAML that is not a
    mapping within pimpm's YAML limits."""
    from .config.yaml_input import MAX_INPUT_BYTES, parse_text
    from .config.checks import ConfigError
    if os.path.getsize(path) > MAX_INPUT_BYTES:
        return f"{option} {path}: expected an options file of at most {MAX_INPUT_BYTES // 2**20} MiB"
    try:
        with open(path, "rb") as f:
            text = f.read().decode("utf-8")
    except (OSError, UnicodeDecodeError) as err:
        return f"{option} {path}: cannot read it ({err.__class__.__name__}): expected a UTF-8 text file of options"
    if option == "-options_file_yaml":
        try:
            data = parse_text(f"{option} {path}", text)[0]
        except ConfigError as err:
            return str(err)
        if data is not None and not isinstance(data, dict):
            return f"{option} {path}: expected a YAML mapping of option names to values"
        return None
    for number, line in enumerate(text.splitlines(), start=1):
        tokens = line.split("#", 1)[0].split("!", 1)[0].split()
        if tokens and not (tokens[0].startswith("-") or tokens[0] == "alias"):
            shown = tokens[0] if len(tokens[0]) <= 40 else tokens[0][:37] + "..."
            return (f"{option} {path} line {number}: {shown!r}: expected '-option [value]' or "
                    f"'alias -new -old' (PETSc's options file format)")
    return None


def parse(argv):
    parser = argparse.ArgumentParser(prog="pimpm", add_help=False, allow_abbrev=False)
    parser.add_argument("input", nargs="?")
    parser.add_argument("--check", action="store_true")
    parser.add_argument("--overwrite", action="store_true")
    parser.add_argument("--restart", action="store_true")
    parser.add_argument("--output")
    parser.add_argument("--set", action="append", default=[])
    parser.add_argument("--help", action="store_true")
    ours, petsc = split_arguments(argv)
    args, unknown = parser.parse_known_args(ours)
    return args, unknown, petsc


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    args, unknown, petsc_args = parse(argv)
    if args.help:
        print(HELP, end="")
        return 0

    from mpi4py import MPI

    from . import interrupt
    interrupt.install()                  # SIGTERM/SIGINT: stop at the next step boundary or residual
    comm = MPI.COMM_WORLD

    def fail(message, status=2):
        if comm.rank == 0:
            print(f"pimpm: error: {message}", file=sys.stderr, flush=True)
        return status

    problem = options_file_problem(petsc_args)
    if problem:                          # PETSc would print an error block and a traceback
        return fail(problem)
    import petsc4py
    petsc4py.init([sys.argv[0]] + petsc_args)
    from petsc4py import PETSc  # noqa: F401  (PetscInitialize installs its own signal handlers:
    interrupt.install()         # SIGHUP's among them, which would abort the run; ours go over them)

    if unknown:
        return fail(f"unknown argument(s) {' '.join(unknown)}: see python -m pimpm --help")
    for token in petsc_args:
        if token in OWN_FLAGS:            # -check would go to PETSc, and the run would start
            return fail(f"{token}: expected --{token[1:]} (pimpm's own options take two dashes; "
                        "one dash passes an option to PETSc)")
    if args.output is not None and not args.output.strip():
        return fail(f"--output {args.output!r}: expected a directory name")
    if not args.input:
        if "-help" in petsc_args:
            return 0
        return fail("missing INPUT.yaml: see python -m pimpm --help")

    try:
        return _run(args, comm, fail)
    except BaseException as err:     # noqa: B902 - any failure, on any subset of ranks
        if comm.size == 1 or isinstance(err, SystemExit):
            raise
        # This rank cannot rejoin the others, which may be waiting in a
        # collective call: say why, and stop every rank.
        sys.stdout.flush()
        sys.stderr.write(f"pimpm: error on rank {comm.rank} of {comm.size}: unexpected "
                         f"{type(err).__name__}; stopping all ranks\n{traceback.format_exc()}")
        sys.stderr.flush()
        comm.Abort(1)


def _run(args, comm, fail):
    from .config import ConfigError, load_config
    try:
        overrides = list(args.set)
        if args.output is not None:
            overrides.append(f"output.directory={args.output}")
        config = load_config(args.input, overrides)
    except ConfigError as err:
        return fail(str(err))
    from .options import with_command_line
    try:                     # -pimpm_* aliases of input keys, checked as the keys are
        config = with_command_line(config)
    except ValueError as err:
        return fail(str(err))
    from .analysis import prepare_restart, restart_line, run
    from .errors import SetupError, UsageError
    from .simulation import Simulation
    from .step_control import TimeStepControl
    from .summary import summary
    try:
        if args.check:
            # with --restart, what the restart would continue is checked too (nothing written)
            sim = (prepare_restart(config, comm, TimeStepControl(config["time"])) if args.restart
                   else Simulation(config, comm))
            lines = summary(sim, config)           # collective: every rank builds it
            if args.restart:
                lines.append(restart_line(sim, config["output"]["directory"]))
            if comm.rank == 0:
                print("\n".join(lines))
                print("pimpm: input is valid")
            if sim.solver is not None:
                sim.solver.destroy()
            return 0
        return run(config, comm, overwrite=args.overwrite, restart=args.restart,
                   input_path=args.input)
    except (UsageError, SetupError) as err:
        return fail(str(err))


if __name__ == "__main__":
    sys.exit(main())
