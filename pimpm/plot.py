"""``python -m pimpm.plot OUTDIR [--into DIR]``: figures of a run's
``history.csv`` (matplotlib, PNG), written to ``OUTDIR/plots`` by default:

* ``force_displacement.png``: for each rigid body and each load, its force
  against its displacement along the axis it moves most (the axis of the
  largest force if it does not move), one panel each;
* ``energies.png``: kinetic, strain and total energy and the external work
  against time, and below, total minus external work (what the run
  dissipated, or gained numerically if it grows);
* ``newton.png``: Newton iterations, the initial and final residual norms
  per step;
* ``dt.png``: the time step per step (step cuts show as dips);
* ``contact.png`` (runs with tools in unilateral contact): each tool's
  normal and tangential force, and its contact area (length in 2D), against
  time. With contact, the energy balance also adds the frictional
  dissipation back (total - external work + dissipation: zero but for the
  integrator's own error and the penalty's stored energy).

Serial; reads nothing but ``history.csv``, so it works on a run in progress,
an interrupted one, or a copy of the file. A missing or unreadable history
is one ``pimpm.plot: error: ...`` line and exit status 2.
"""
import argparse
import csv
import math
import os
import re
import sys

FIGURES = ("force_displacement.png", "energies.png", "newton.png", "dt.png")
PAIR = re.compile(r"^(?P<name>.+)_force_(?P<axis>[xyz])$")


class PlotError(Exception):
    """A history that cannot be plotted (the message names the file)."""


def read_history(path):
    """(columns, {column: [float, ...]}) of a history.csv."""
    try:
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
    except FileNotFoundError:
        raise PlotError(f"{path}: not found: expected the history.csv of a pimpm run "
                        f"(python -m pimpm.plot OUTDIR)") from None
    except (OSError, UnicodeDecodeError) as err:
        raise PlotError(f"{path}: cannot be read ({err})") from None
    if not rows or "step" not in rows[0] or "time" not in rows[0]:
        raise PlotError(f"{path}: no header with 'step' and 'time': expected the history.csv "
                        f"of a pimpm run")
    columns = rows[0]
    data = {c: [] for c in columns}
    for number, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) != len(columns):
            raise PlotError(f"{path}:{number}: {len(row)} values: expected {len(columns)}")
        try:
            values = [float(v) for v in row]
        except ValueError as err:
            raise PlotError(f"{path}:{number}: {err}") from None
        for c, v in zip(columns, values):
            data[c].append(v)
    if not data["step"]:
        raise PlotError(f"{path}: no steps yet: expected at least one row after the header")
    return columns, data


def force_displacement_pairs(columns, data):
    """[(name, axis, displacement, force)] for every rigid body and load: the
    axis along which it moves most (of largest force if it does not move)."""
    names = []
    for c in columns:
        m = PAIR.match(c)
        if m and m["name"] not in names and f"{m['name']}_displacement_{m['axis']}" in data:
            names.append(m["name"])
    pairs = []
    for name in names:
        axes = [a for a in "xyz" if f"{name}_force_{a}" in data]

        def spread(values):
            return max(values) - min(values) if values else 0.0
        moves = {a: spread(data[f"{name}_displacement_{a}"]) for a in axes}
        pushes = {a: max(abs(f) for f in data[f"{name}_force_{a}"]) for a in axes}
        axis = max(axes, key=lambda a: (moves[a], pushes[a]))
        if moves[axis] == 0.0:
            axis = max(axes, key=lambda a: pushes[a])
        pairs.append((name, axis, data[f"{name}_displacement_{axis}"],
                      data[f"{name}_force_{axis}"]))
    return pairs


def plot(outdir, into=None):
    """Write the figures of ``outdir/history.csv`` into ``into`` (default
    ``outdir/plots``); returns their paths."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    columns, data = read_history(os.path.join(outdir, "history.csv"))
    into = into or os.path.join(outdir, "plots")
    if os.path.islink(into):
        raise PlotError(f"{into}: is a symbolic link: expected a directory to write the figures to")
    try:
        os.makedirs(into, exist_ok=True)
    except OSError as err:
        raise PlotError(f"{into}: cannot be created ({err.strerror})") from None
    title = os.path.basename(os.path.normpath(outdir))
    step, time = data["step"], data["time"]
    written = []

    def save(fig, name):
        path = os.path.join(into, name)
        tmp = os.path.join(into, "." + name + ".tmp.png")
        if os.path.islink(path) or os.path.islink(tmp):
            raise PlotError(f"{path}: is a symbolic link: refusing to write through it")
        fig.savefig(tmp, dpi=120)
        plt.close(fig)
        os.replace(tmp, path)
        written.append(path)

    pairs = force_displacement_pairs(columns, data)
    ncols = min(len(pairs), 3) or 1
    nrows = max(1, math.ceil(len(pairs) / ncols))
    fig, axes = plt.subplots(nrows, ncols, figsize=(5 * ncols, 4 * nrows), squeeze=False)
    for ax, (name, axis, u, f) in zip(axes.flat, pairs):
        ax.plot([0.0] + u, [0.0] + f, "-", color="0.7", lw=0.8)
        ax.plot(u, f, ".-", ms=3)
        ax.set_xlabel(f"{name} displacement {axis}")
        ax.set_ylabel(f"{name} force {axis}")
        ax.set_title(name)
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[len(pairs):]:
        ax.axis("off")
    if not pairs:
        axes[0, 0].text(0.5, 0.5, "no rigid bodies or loads", ha="center", va="center")
    fig.suptitle(f"{title}: force against displacement")
    fig.tight_layout()
    save(fig, "force_displacement.png")

    fig, (ax, balance) = plt.subplots(2, 1, figsize=(7, 6.5), sharex=True,
                                      gridspec_kw=dict(height_ratios=[2, 1]))
    for column, label, style in (("kinetic_energy", "kinetic", "-"),
                                 ("strain_energy", "strain", "-"),
                                 ("total_energy", "total (kinetic + strain)", "-"),
                                 ("external_work", "external work", "--")):
        ax.plot(time, data[column], style, label=label)
    ax.set_ylabel("energy")
    ax.set_title(f"{title}: energies")
    ax.grid(alpha=0.3)
    ax.legend()
    balance.plot(time, [e - w for e, w in zip(data["total_energy"], data["external_work"])],
                 color="C4", label="total - external work")
    if "frictional_dissipation" in data:
        balance.plot(time, [e - w + d for e, w, d in zip(data["total_energy"], data["external_work"],
                                                          data["frictional_dissipation"])],
                     color="C5", label="... + frictional dissipation")
        balance.legend()
    balance.axhline(0.0, color="0.5", lw=0.8)
    balance.set_ylabel("total - external work")
    balance.set_xlabel("time")
    balance.grid(alpha=0.3)
    fig.tight_layout()
    save(fig, "energies.png")

    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    top.bar(step, data["newton_iterations"], width=1.0, color="C0")
    top.set_ylabel("Newton iterations")
    top.set_title(f"{title}: Newton")
    top.grid(alpha=0.3)
    for column, label, style in (("residual_initial", "initial", "-"),
                                 ("residual_final", "final", ".-")):
        residual = [r if r > 0 else float("nan") for r in data[column]]
        bottom.semilogy(step, residual, style, ms=3, label=label,
                        color="0.6" if column == "residual_initial" else "C3")
    bottom.set_ylabel("residual norm")
    bottom.legend()
    bottom.set_xlabel("step")
    bottom.grid(alpha=0.3, which="both")
    fig.tight_layout()
    save(fig, "newton.png")

    tools = [c[:-len("_contact_area")] for c in columns if c.endswith("_contact_area")]
    if tools:
        fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
        for name in tools:
            top.plot(time, data[f"{name}_normal_force"], "-", label=f"{name} normal")
            top.plot(time, data[f"{name}_tangential_force"], "--", label=f"{name} tangential")
            bottom.plot(time, data[f"{name}_contact_area"], ".-", ms=3, label=name)
        top.set_ylabel("contact force")
        top.set_title(f"{title}: contact")
        top.legend()
        top.grid(alpha=0.3)
        bottom.set_ylabel("contact area (length in 2D)")
        bottom.set_xlabel("time")
        bottom.grid(alpha=0.3)
        fig.tight_layout()
        save(fig, "contact.png")

    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(step, data["dt"], ".-", ms=3)
    if max(data["dt"]) > 100.0 * min(data["dt"]):
        ax.set_yscale("log")  # step cuts of many halvings
    else:
        ax.set_ylim(0.0, 1.1 * max(data["dt"]))
    ax.set_xlabel("step")
    ax.set_ylabel("dt")
    ax.set_title(f"{title}: time step")
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    save(fig, "dt.png")
    return written


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m pimpm.plot",
                                     description="Figures of a pimpm run's history.csv.")
    parser.add_argument("outdir", help="the run's output directory (holds history.csv)")
    parser.add_argument("--into", help="where to write the PNGs (default OUTDIR/plots)")
    args = parser.parse_args(argv)
    try:
        for path in plot(args.outdir, args.into):
            print(path)
    except PlotError as err:
        print(f"pimpm.plot: error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
