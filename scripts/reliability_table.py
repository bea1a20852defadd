#!/usr/bin/env python3
"""The tables of docs/RELIABILITY.md, made by running pimpm as a user would:
every hostile input of issues 13 and 32 (restarts from damaged or linked
files among them), and signals (to one rank, to mpiexec, twice, SIGHUP).
For each: the exit status of mpiexec (or python), the seconds until every
process was gone, the ``pimpm: error``/``interrupted`` line, and what was
written or changed (every file's bytes compared, a link's target too).

    python scripts/reliability_table.py [--json docs/data/reliability.json]
    python scripts/reliability_table.py --pimpm ../baseline --only 1: 2: 3: 4: 5:

``--pimpm DIR`` runs another checkout's pimpm (a ``git worktree`` of an
earlier commit, its kernels compiled) with this script's cases, to show what
a row did before; ``--only PREFIX ...`` keeps the hostile rows whose name
starts with one of the prefixes (issue 32's defects are ``1:`` to ``5:``).
"""
import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time

import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BAR = os.path.join(ROOT, "inputs", "bar_tension.yaml")
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1", PYTHONPATH=ROOT)     # (--pimpm changes PYTHONPATH)


def bar(edit=None):
    with open(BAR) as f:
        raw = yaml.safe_load(f)
    raw["output"] = {"directory": "out"}
    if edit:
        edit(raw)
    return raw


def bomb(levels):
    lines = ["l0: &l0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    for i in range(1, levels + 1):
        lines.append(f"l{i}: &l{i} [" + ", ".join([f"*l{i - 1}"] * 9) + "]")
    return "\n".join(lines) + "\n"


def set_bomb(levels):
    """A flow-style alias bomb for --set: 9**levels values in ~30 characters a level."""
    names = [chr(ord("a") + i) for i in range(levels)]
    parts = [f"&{names[0]} [x, x, x, x, x, x, x, x, x]"]
    parts += [f"&{n} [" + ", ".join([f"*{p}"] * 9) + "]" for p, n in zip(names, names[1:])]
    return "[" + ", ".join(parts) + "]"


def text(content):
    def setup(d):
        with open(os.path.join(d, "in.yaml"), "w") as f:
            f.write(content)
        return ["in.yaml"]
    return setup


def config(edit=None, *extra):
    def setup(d):
        with open(os.path.join(d, "in.yaml"), "w") as f:
            yaml.safe_dump(bar(edit), f)
        return ["in.yaml", *extra]
    return setup


def big_file(d):
    with open(os.path.join(d, "in.yaml"), "wb") as f:
        f.truncate(50 * 2**20)
    return ["in.yaml"]


def fifo(d):
    os.mkfifo(os.path.join(d, "in.yaml"))
    return ["in.yaml"]


def link(name, dangling=False):
    def setup(d):
        config()(d)
        os.makedirs(os.path.join(d, "out"))
        target = os.path.join(d, "victim.txt")
        if not dangling:
            with open(target, "w") as f:
                f.write("precious\n")
        os.symlink(target, os.path.join(d, "out", name))
        return ["in.yaml"]
    return setup


def restart(damage, *extra):
    """The bar stopped after 5 of its 10 steps with a checkpoint, ``damage``
    done to its output directory, then ``--restart``."""
    def setup(d):
        config(lambda r: r["output"].update(checkpoint_every=1))(d)
        proc = subprocess.run(command(1, ["in.yaml", "--set", "time.end_time=5.17"]), cwd=d, env=ENV,
                              capture_output=True, text=True, timeout=300)
        assert proc.returncode == 0, proc.stderr
        damage(os.path.join(d, "out"))
        return ["in.yaml", "--restart", *extra]
    return setup


def set_step(out):
    """The checkpoint's step set to -5 (its digest made to match, if it has
    one: the step's own check is what this row shows)."""
    import hashlib

    import h5py
    with h5py.File(os.path.join(out, "checkpoint.h5"), "r+") as f:
        f.attrs["step"] = -5
    sums = os.path.join(out, "checkpoint.sha256")
    if os.path.exists(sums):
        with open(os.path.join(out, "checkpoint.h5"), "rb") as f, open(sums, "w") as s:
            s.write(hashlib.sha256(f.read()).hexdigest() + "\n")


def flip_bytes(out):
    content = bytearray(open(os.path.join(out, "checkpoint.h5"), "rb").read())
    for k in range(4):
        content[(20931 + 4099 * k) % len(content)] ^= 0xFF
    with open(os.path.join(out, "checkpoint.h5"), "wb") as f:
        f.write(bytes(content))


def linked(name):
    def damage(out):
        target = os.path.join(os.path.dirname(out), "elsewhere-" + name)
        os.replace(os.path.join(out, name), target)
        os.symlink(target, os.path.join(out, name))
    return damage


def appended(name, text):
    def damage(out):
        with open(os.path.join(out, name), "a") as f:
            f.write(text)
    return damage


def replaced(name, text):
    def damage(out):
        with open(os.path.join(out, name), "w") as f:
            f.write(text)
    return damage


def options_file(name, content, option):
    def setup(d):
        with open(os.path.join(d, name), "wb") as f:
            f.write(content)
        return config()(d) + [option, name]
    return setup


def particle_file(content):
    """The bar seeded from a particle CSV file with ``content``."""
    def setup(d):
        with open(os.path.join(d, "p.csv"), "w") as f:
            f.write(content)
        def edit(r):
            r["bodies"][0].update(geometry={"type": "particles", "file": "p.csv"})
            r["bodies"][0].pop("particles_per_cell", None)
        return config(edit)(d)
    return setup


def unwritable_output(d):
    os.makedirs(os.path.join(d, "out"))
    os.chmod(os.path.join(d, "out"), 0o555)
    return config()(d)


def negative_radius(r):
    r.update(kinematics="axisymmetric")
    r["grid"].update(lower=[-0.7, 0.0], upper=[0.0, 0.5])
    r["grid"]["boundary"] = {"xmin": "roller", "ymin": "symmetry"}
    r["bodies"][0]["geometry"].update(lower=[-0.3, 0.0], upper=[0.0, 0.3])
    r["bodies"][1]["geometry"].update(lower=[-0.4, 0.0], upper=[-0.3, 0.3])


def small_3d(d):
    with open(os.path.join(ROOT, "inputs", "upsetting_3d.yaml")) as f:
        raw = yaml.safe_load(f)
    raw["grid"]["cells"] = [2, 2, 2]
    raw["output"] = {"directory": "out"}
    with open(os.path.join(d, "in.yaml"), "w") as f:
        yaml.safe_dump(raw, f)
    return ["in.yaml"]


def hopeless(d):
    """A grid too small for the bulge: the billet reaches the grid's edge."""
    with open(os.path.join(ROOT, "inputs", "billet.yaml")) as f:
        raw = yaml.safe_load(f)
    raw["grid"].update(upper=[24.0, 21.0], cells=[48, 42])
    raw["bodies"][1]["geometry"]["upper"][0] = 23.5
    raw["output"] = {"directory": "out"}
    with open(os.path.join(d, "in.yaml"), "w") as f:
        yaml.safe_dump(raw, f)
    return ["in.yaml"]


M = "elastic"
HOSTILE = [
    ("`title: &a [*a]`", 1, text("title: &a [*a]\n")),
    ("a self-referencing alias under an unknown key", 1, text(open(BAR).read() + "extra: &x {k: *x}\n")),
    ("list nesting 400 levels", 1, text("title: " + "[" * 400 + "]" * 400 + "\n")),
    ("billion-laughs alias bomb, 9 levels", 1, text(bomb(9))),
    ("alias bomb, 6 levels", 1, text(bomb(6))),
    ("a 50 MB YAML file", 1, big_file),
    ("`grid.cells: [1000000, 1000000]`", 1, config(lambda r: r["grid"].update(cells=[1000000, 1000000]))),
    ("the same with `--check`", 1, config(lambda r: r["grid"].update(cells=[1000000, 1000000]), "--check")),
    ("`grid.cells: [30000, 30000]`", 1, config(lambda r: r["grid"].update(cells=[30000, 30000]))),
    ("`particles_per_cell: 1000`", 1, config(lambda r: r["bodies"][0].update(particles_per_cell=1000))),
    ("`dt: 1e-12` with `end_time: 1`", 1, config(lambda r: r["time"].update(dt=1e-12, end_time=1.0))),
    ("`end_time: 1e300`", 1, config(lambda r: r["time"].update(end_time=1e300))),
    ("moduli `1e308`", 1, config(lambda r: r["materials"][M].update(youngs_modulus=1e308))),
    ("moduli `1e-300`", 1, config(lambda r: r["materials"][M].update(youngs_modulus=1e-300))),
    ("`-pimpm_preset cg-gamg -ksp_type nonsense`", 2, config(None, "-pimpm_preset", "cg-gamg", "-ksp_type", "nonsense")),
    ("`-pimpm_preset gmres-gamg -ksp_max_it abc`", 2, config(None, "-pimpm_preset", "gmres-gamg", "-ksp_max_it", "abc")),
    ("the same in the YAML `petsc:` block", 2, config(lambda r: r.update(solver={"preset": "gmres-gamg", "petsc": {"ksp_type": "nonsense"}}))),
    ("`-snes_max_it -3`", 1, config(None, "-snes_max_it", "-3")),
    ("`-ksp_rtol -5` (cg-gamg)", 1, config(None, "-pimpm_preset", "cg-gamg", "-ksp_rtol", "-5")),
    ("`-pc_factor_mat_solver_type nonsense`", 1, config(None, "-pc_factor_mat_solver_type", "nonsense")),
    ("`-snes_max_it abc`", 1, config(None, "-snes_max_it", "abc")),
    ("`-snes_rtol abc`", 1, config(None, "-snes_rtol", "abc")),
    ("`-snes_linesearch_type nonsense`", 1, config(None, "-snes_linesearch_type", "nonsense")),
    ("`-pimpm_fallback abc`", 1, config(None, "-pimpm_fallback", "abc")),
    ("`-options_file /nonexistent`", 1, config(None, "-options_file", "/nonexistent")),
    ("the input is a FIFO", 1, fifo),
    ("the input is /dev/zero", 1, lambda d: ["/dev/zero"]),
    ("overlapping deformable bodies", 1, config(lambda r: r["bodies"].insert(1, dict(r["bodies"][0], name="twin")))),
    ("a symlink `OUTDIR/particles.xdmf.tmp` to another file", 1, link("particles.xdmf.tmp")),
    ("a dangling symlink `OUTDIR/history.csv`", 1, link("history.csv", dangling=True)),
    ("a grid too small for the bulge (2 ranks)", 2, hopeless),
    # issue 32's defects
    ("1: `--restart` from a checkpoint whose `step` is -5", 1, restart(set_step)),
    ("1: `--restart` from a checkpoint with 4 bytes flipped", 1, restart(flip_bytes)),
    ("1: `--restart` after a garbage row in history.csv", 1, restart(appended("history.csv", "garbage,row\n"))),
    ("1: `--restart` with a results.h5 that is not HDF5", 1, restart(replaced("results.h5", "not HDF5\n"))),
    ("2: `--restart` with results.h5 a link to a file elsewhere", 1, restart(linked("results.h5"))),
    ("2: `--restart` with history.csv a link", 1, restart(linked("history.csv"))),
    ("3: an axisymmetric body at negative radius", 1, config(negative_radius)),
    ("3: `-snes_atol inf`", 1, config(None, "-snes_atol", "inf")),
    ("3: `-snes_rtol 1e400`", 1, config(None, "-snes_rtol", "1e400")),
    ("3: `solver.petsc.snes_rtol: 1e400`", 1, config(lambda r: r.update(solver={"petsc": {"snes_rtol": 1e400}}))),
    ("3: a hardening modulus that drives the yield stress below zero (strength floored at 0; Newton "
     "then fails, status 1)", 1,
     config(lambda r: r["materials"].update(elastic={"model": "j2_finite_strain", "youngs_modulus": 1000.0,
                                                     "poisson_ratio": 0.3, "density": 10.0, "yield_stress": 5.0,
                                                     "hardening_modulus": -2000.0}))),
    ("4: `dt_initial: 1e-200` with `ramp_factor: 1`", 1,
     config(lambda r: r["time"].update(dt_initial=1e-200, ramp_factor=1.0))),
    ("4: `max_cuts: 2000`", 1, config(lambda r: r["time"].update(max_cuts=2000))),
    ("4: `max_cuts: 10**30`", 1, config(lambda r: r["time"].update(max_cuts=10 ** 30))),
    ("5: `--set 'title=&a [*a]'`", 1, config(None, "--set", "title=&a [*a]")),
    ("5: `--set` 5000 levels deep", 1, config(None, "--set", "title=" + "[" * 5000 + "]" * 5000)),
    ("5: `--set` alias bomb (10 levels of 9, 400 characters)", 1, config(None, "--set", "title=" + set_bomb(10))),
    # issue 32's escapes
    ("`-pimpm_gw_displacement_tol -1`", 1, config(None, "-pimpm_gw_displacement_tol", "-1")),
    ("`-pimpm_gw_energy_tol nan`", 1, config(None, "-pimpm_gw_energy_tol", "nan")),
    ("`-mat_mumps_icntl_14 -100`", 1, config(None, "-mat_mumps_icntl_14", "-100")),
    ("`-ksp_type python` (no context)", 1, config(None, "-ksp_type", "python")),
    ("`-mat_mffd_err -1`", 1, config(None, "-mat_mffd_err", "-1")),
    ("`-snes_linesearch_damping nan`", 1, config(None, "-snes_linesearch_damping", "nan")),
    ("an options file with a line that is no option", 1,
     options_file("opts.txt", b"-snes_rtol 1e-6\nthis is not an option\n", "-options_file")),
    ("a YAML options file that is a list", 1, options_file("opts.yaml", b"- snes_rtol\n", "-options_file_yaml")),
    ("`solver.petsc.options_file` in the YAML", 1,
     config(lambda r: r.update(solver={"petsc": {"options_file": "opts.txt"}}))),
    ("an integer beyond the float range (`youngs_modulus: 10**400`)", 1,
     config(lambda r: r["materials"][M].update(youngs_modulus=10 ** 400))),
    ("a particle CSV with an over-long line", 1, particle_file("x,y,volume\n0.5,0.1," + "1" * 200000 + "\n")),
    ("a particle CSV starting with a byte-order mark (runs)", 1, particle_file("\ufeffx,y,volume\n0.5,0.1,0.01\n")),
    ("an output directory that cannot be written (needs a non-root user)", 1, unwritable_output),
    ("`-check` (one dash)", 1, config(None, "-check")),
    ("`-output elsewhere` (one dash)", 1, config(None, "-output", "elsewhere")),
    ("`--output ''`", 1, config(None, "--output", "")),
    ("`--check --restart` with no checkpoint", 1, config(None, "--check", "--restart")),
    ("a body name with a newline", 1, config(lambda r: r["bodies"][0].update(name="bar\nx"))),
    ("grid spacing 1e-300 (the spacing, not a modulus, overflows)", 1,
     config(lambda r: r["grid"].update(upper=[0.7e-300, 0.5e-300]))),
    ("valid YAML merge keys (runs)", 1, text(open(BAR).read().replace(
        "  elastic: {model: neo_hookean, youngs_modulus: 1000.0, poisson_ratio: 0.3, density: 10.0}",
        "  base: &base {model: neo_hookean, youngs_modulus: 500.0, poisson_ratio: 0.3, density: 10.0}\n"
        "  elastic: {<<: *base, youngs_modulus: 1000.0}").replace("bar_tension_output", "out"))),
    ("a 3D GIMP grid of 2 cells a side on 4 ranks", 4, small_3d),
]


def listing(d):
    """Every path under ``d`` with what it is: a link's target, a file's
    bytes (hashed), or a directory."""
    import hashlib
    found = {}
    for root, dirs, files in os.walk(d):
        for name in dirs + files:
            path = os.path.join(root, name)
            rel = os.path.relpath(path, d)
            if os.path.islink(path):
                found[rel] = "link " + os.readlink(path)
            elif os.path.isfile(path):
                with open(path, "rb") as f:
                    found[rel] = hashlib.sha256(f.read()).hexdigest()
            else:
                found[rel] = "directory"
    return found


def changes(before, after):
    """What a run wrote, changed or removed."""
    new = sorted(set(after) - set(before))
    changed = sorted(p for p in set(after) & set(before) if after[p] != before[p])
    removed = sorted(set(before) - set(after))
    return new + [f"{p} (changed)" for p in changed] + [f"{p} (removed)" for p in removed]


def command(ranks, args):
    python = [sys.executable, "-m", "pimpm"] + list(args)
    return python if ranks == 1 else ["mpiexec", "-n", str(ranks)] + python


def first_line(stderr):
    lines = [l for l in stderr.splitlines() if l.startswith("pimpm:")]
    return lines[0] if lines else (stderr.strip().splitlines() or [""])[-1]


def as_user(name, d):
    """Permissions do not bind root: a case that needs a non-root user runs
    as 'nobody' when this script runs as root."""
    if "non-root" not in name or os.geteuid() != 0:
        return {}
    os.chmod(d, 0o777)
    for path in os.listdir(d):
        if os.path.isfile(os.path.join(d, path)):
            os.chmod(os.path.join(d, path), 0o644)
    cache = tempfile.mkdtemp(prefix="pimpm-numba-")     # (nobody cannot write the checkout's cache)
    os.chmod(cache, 0o777)
    return {"user": 65534, "group": 65534, "extra_groups": [],
            "env": dict(ENV, HOME=cache, NUMBA_CACHE_DIR=cache)}


#: seconds a hostile input may run (a run that never ends is one of them)
TIMEOUT = 60
#: bytes of data a hostile input's processes may allocate (an alias bomb that
#: pimpm once expanded took 18 GB in 30 s, and ignored SIGTERM)
MEMORY = 8 * 2**30


def limit_memory():
    import resource
    resource.setrlimit(resource.RLIMIT_DATA, (MEMORY, MEMORY))


def hostile(only=None):
    rows = []
    for name, ranks, setup in HOSTILE:
        if only and not name.startswith(tuple(only)):
            continue
        with tempfile.TemporaryDirectory() as d:
            args = setup(d)
            before = listing(d)
            start = time.perf_counter()
            try:
                proc = subprocess.run(command(ranks, args), cwd=d, capture_output=True, text=True,
                                      timeout=TIMEOUT, preexec_fn=limit_memory,
                                      **dict({"env": ENV}, **as_user(name, d)))
                status, stderr = proc.returncode, proc.stderr
            except subprocess.TimeoutExpired as err:       # (the child is killed)
                status = f"still running after {TIMEOUT} s (killed)"
                stderr = err.stderr.decode() if isinstance(err.stderr, bytes) else (err.stderr or "")
            seconds = time.perf_counter() - start
            after = listing(d)
        rows.append({"input": name, "ranks": ranks, "status": status, "seconds": round(seconds, 1),
                     "message": first_line(stderr), "written": changes(before, after),
                     "traceback": "Traceback" in stderr})
        print(json.dumps(rows[-1]), flush=True)
    return rows


def slow_billet(d):
    with open(os.path.join(ROOT, "inputs", "billet.yaml")) as f:
        raw = yaml.safe_load(f)
    raw["grid"]["cells"] = [40, 21]
    raw["time"]["dt"] = 0.0005
    raw["output"] = {"directory": "out", "every": 20}
    with open(os.path.join(d, "in.yaml"), "w") as f:
        yaml.safe_dump(raw, f)


def wait_rows(d, rows):
    path = os.path.join(d, "out", "history.csv")
    while not os.path.exists(path) or sum(1 for _ in open(path)) <= rows:
        time.sleep(0.05)


def signals():
    cases = [("SIGTERM to mpiexec (2 ranks)", 2, "mpiexec", [signal.SIGTERM]),
             ("SIGINT to mpiexec (2 ranks)", 2, "mpiexec", [signal.SIGINT]),
             ("SIGTERM to rank 1 only (2 ranks)", 2, "rank", [signal.SIGTERM]),
             ("SIGINT to rank 1 only (2 ranks)", 2, "rank", [signal.SIGINT]),
             ("SIGINT (Ctrl-C), 1 rank without mpiexec", 1, "python", [signal.SIGINT]),
             ("SIGTERM twice, 1 rank without mpiexec", 1, "python", [signal.SIGTERM, signal.SIGTERM]),
             ("SIGHUP (the terminal closed), 1 rank without mpiexec", 1, "python", [signal.SIGHUP]),
             ("SIGHUP to rank 1 only (2 ranks)", 2, "rank", [signal.SIGHUP])]
    rows = []
    for name, ranks, target, sigs in cases:
        with tempfile.TemporaryDirectory() as d:
            slow_billet(d)
            proc = subprocess.Popen(command(ranks, ["in.yaml"]), cwd=d, env=ENV, stdout=subprocess.PIPE,
                                    stderr=subprocess.PIPE, text=True)
            wait_rows(d, 5)
            pid = proc.pid
            if target == "rank":
                pid = int(subprocess.run(["pgrep", "-P", str(proc.pid), "-f", "pimpm in.yaml"],
                                         capture_output=True, text=True).stdout.split()[-1])
            start = time.perf_counter()
            for i, sig in enumerate(sigs):
                if i:
                    time.sleep(0.05)             # the second while the first is being handled
                os.kill(pid, sig)
            _, err = proc.communicate(timeout=60)
            seconds = time.perf_counter() - start
            checkpoint = os.path.exists(os.path.join(d, "out", "checkpoint.h5"))
            again = subprocess.run(command(ranks, ["in.yaml", "--restart"]), cwd=d, env=ENV,
                                   capture_output=True, text=True, timeout=600) if checkpoint else None
        rows.append({"signal": name, "status": proc.returncode, "seconds": round(seconds, 1),
                     "message": first_line(err), "checkpoint": checkpoint,
                     "restart_status": again.returncode if again else None})
        print(json.dumps(rows[-1]), flush=True)
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", default=os.path.join(ROOT, "docs", "data", "reliability.json"))
    ap.add_argument("--pimpm", help="the checkout whose pimpm runs (default: this one)")
    ap.add_argument("--only", nargs="+", help="only the hostile rows whose names start so (no signals)")
    args = ap.parse_args()
    if args.pimpm:
        ENV["PYTHONPATH"] = os.path.abspath(args.pimpm)
    result = {"pimpm": ENV["PYTHONPATH"], "hostile_inputs": hostile(args.only),
              "signals": [] if args.only else signals()}
    print("\n| input | ranks | exit status | seconds | message | written |")
    print("|---|---|---|---|---|---|")
    for r in result["hostile_inputs"]:
        print(f"| {r['input']} | {r['ranks']} | {r['status']} | {r['seconds']} | `{r['message']}` | "
              f"{', '.join(r['written']) or 'nothing'}{' (traceback!)' if r['traceback'] else ''} |")
    print("\n| signal | exit status | seconds to exit | message | checkpoint | --restart |")
    print("|---|---|---|---|---|---|")
    for r in result["signals"]:
        print(f"| {r['signal']} | {r['status']} | {r['seconds']} | `{r['message']}` | "
              f"{'yes' if r['checkpoint'] else 'no'} | {r['restart_status']} |")
    with open(args.json, "w") as f:
        json.dump(result, f, indent=1)


if __name__ == "__main__":
    main()
