#!/usr/bin/env python3
"""The tables of docs/RELIABILITY.md, made by running pimpm as a user would:
every hostile input of issue 13's table, failures injected on one rank,
and signals (to one rank, to mpiexec, twice). For each: the exit status of
mpiexec (or python), the seconds until every process was gone, the
``pimpm: error``/``interrupted`` line, and whether anything was written.

    python scripts/reliability_table.py [--json docs/data/reliability.json]
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
           OMPI_MCA_rmaps_base_oversubscribe="1", PYTHONPATH=ROOT)


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
]


def listing(d):
    found = set()
    for root, dirs, files in os.walk(d):
        for name in dirs + files:
            found.add(os.path.relpath(os.path.join(root, name), d))
    return found


def command(ranks, args):
    python = [sys.executable, "-m", "pimpm"] + list(args)
    return python if ranks == 1 else ["mpiexec", "-n", str(ranks)] + python


def first_line(stderr):
    lines = [l for l in stderr.splitlines() if l.startswith("pimpm:")]
    return lines[0] if lines else (stderr.strip().splitlines() or [""])[-1]


def hostile():
    rows = []
    for name, ranks, setup in HOSTILE:
        with tempfile.TemporaryDirectory() as d:
            args = setup(d)
            before = listing(d)
            start = time.perf_counter()
            proc = subprocess.run(command(ranks, args), cwd=d, env=ENV, capture_output=True, text=True,
                                  timeout=300)
            seconds = time.perf_counter() - start
            after = listing(d)
        rows.append({"input": name, "ranks": ranks, "status": proc.returncode, "seconds": round(seconds, 1),
                     "message": first_line(proc.stderr), "written": sorted(after - before),
                     "traceback": "Traceback" in proc.stderr})
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
             ("SIGTERM twice, 1 rank without mpiexec", 1, "python", [signal.SIGTERM, signal.SIGTERM])]
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
    args = ap.parse_args()
    result = {"hostile_inputs": hostile(), "signals": signals()}
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
