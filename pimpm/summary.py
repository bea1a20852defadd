"""The problem summary printed by ``--check`` and at the start of a run."""
import math
import os

import numpy as np

from . import resources
from .seeding import body_volumes, particles_per_body


def step_count(end_time, dt):
    """Steps of dt to reach end_time (a shorter last one counted; a sliver
    of less than 1e-9 dt not)."""
    n = max(1, math.ceil(end_time / dt - 1e-9))
    return n - 1 if n > 1 and end_time - dt * (n - 1) <= 1e-9 * dt else n


def explicit_time_step(sim):
    """Explicit CFL step dx / c for the stiffest material (MPM intro)."""
    h = float(np.min(sim.grid.spacing))
    return h / max(m.wave_speed() for m in sim.materials)


def summary(sim, config):
    """Problem summary lines (printed by --check and at the start of a run)."""
    comm = sim.comm
    counts = particles_per_body(config, sim.particles, sim.rigid, comm)
    t = config["time"]
    steps = step_count(t["end_time"], t["dt"]) if t["dt"] is not None else 0
    cells = "x".join(str(int(c)) for c in sim.grid.cells)
    lines = [
        f"pimpm: {config.get('title') or 'untitled'}",
        f"  grid      {cells} cells, spacing {', '.join(f'{h:g}' for h in sim.grid.spacing)}, "
        f"{int(np.prod(sim.grid.nodes)) * sim.dim} unknowns, {config['kinematics']}, "
        f"{config['grid']['shape_functions']} shape functions",
        f"  ranks     {comm.size} (process grid {'x'.join(str(int(p)) for p in sim.grid.proc_sizes)})",
    ]
    volumes = body_volumes(config, sim.particles, comm)
    for b, n, v in zip(config["bodies"], counts, volumes):
        kind = "rigid" if b.get("rigid") else f"material {b['material']}, volume {v:.10g}"
        source = ""
        g = b["geometry"]
        if g["type"] in ("mesh", "particles"):
            # particles per cell on average: a quasi-static solve needs a few per cell
            # and axis (2^dim per cell, like the default particles_per_cell 2)
            per_cell = n * sim.grid.cell_volume / g["volume"] if g["volume"] > 0 else 0.0
            source = (f", {g['elements']} elements x {g['particles_per_element']}^{sim.dim}"
                      if g["type"] == "mesh" else "")
            source += f" from {os.path.basename(g['file'])}, {per_cell:.3g} per cell"
            if per_cell < 2 ** sim.dim:
                source += (f" (fewer than {2 ** sim.dim}: a quasi-static solve may not converge; "
                           + ("raise particles_per_element)" if g["type"] == "mesh" else
                              "use a denser cloud)"))
        lines.append(f"  body      {b['name']}: {int(n)} particles ({kind}{source})")
    for pair in config.get("contact", []):
        mu = f", mu = {pair['friction_coefficient']:g}" if pair["law"] == "friction" else ""
        lines.append(f"  contact   {pair['bodies'][0]} - {pair['bodies'][1]}: {pair['law']}{mu} "
                     f"({sim.fields.count} grid velocity fields)")
    averaged = {name: m for name, m in config["materials"].items() if m.get("f_bar")}
    if averaged:                 # every averaged material averages the same way (pimpm.config)
        over = "per cell" if next(iter(averaged.values()))["f_bar"] == "cells" else "on the nodes"
        shares = ", ".join(f"{name} (the particle's own share {m['f_bar_blend']:g})" for name, m in averaged.items())
        lines.append(f"  f-bar     volume change averaged {over}: {shares} (docs/INPUT.md)")
    dt_explicit = explicit_time_step(sim)
    if t["dt"] is None:
        lines.append(f"  time      explicit, automatic dt = {t['cfl']:g} x CFL step "
                     f"(now {t['cfl'] * dt_explicit:.3g}), end {t['end_time']:g}")
    else:
        parameters = ", ".join(f"{k} {t[k]:g}" for k in sim.integrator.parameters)
        scheme = t["integrator"] + (f" ({parameters})" if parameters else "") \
            + (" (momentum formulation)" if t["formulation"] == "momentum" else "")
        lines.append(f"  time      {scheme}, dt {t['dt']:g} ({t['dt'] / dt_explicit:.3g} x "
                     f"explicit CFL step {dt_explicit:.3g}), end {t['end_time']:g}, "
                     f"{steps} steps")
    lines.append(f"  output    {config['output']['directory']} every {config['output']['every']} steps")
    lines.append(resources.summary_line(sim))
    if sim.solver is not None:
        lines.append(f"  solver    {sim.solver.describe()}")
    else:
        lines.append(f"  solver    explicit ({t['stress_update'].upper()}), no linear solves")
    return lines
