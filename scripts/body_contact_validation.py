"""The benchmarks of docs/VALIDATION.md "Bodies that collide, slide and
separate" (issue 30: one grid velocity field per body, contact between the
fields), refined in h: Nairn's block pushed along a deformable plane
(``inputs/block_on_plane.yaml``, acceleration against the exact one),
two elastic disks colliding head-on along a grid axis (momentum, the time
they touch, their closest approach, the coefficient of restitution),
Sulsky & Kaul's diagonal collision (``inputs/colliding_disks_contact.yaml``),
three stacked blocks pushed sideways (``inputs/stacked_blocks.yaml``: the
interface Coulomb's law picks slips) and a disk on a 45 degree slope
(``inputs/disk_on_slope.yaml``: rolling and sliding accelerations).
Explicit, and implicit (the pairs inside Newton, with Newton's
iterations per step) at 5 to 1000 times the explicit step. Prints a table
per benchmark and writes the numbers as JSON.

    python scripts/body_contact_validation.py [--json docs/data/validation_body_contact.json]

Serial (tests/test_body_contact.py checks 2 ranks); about ten minutes.
tests/test_body_contact.py runs the same functions."""
import argparse
import json
import os
import sys
import time

import numpy as np
import petsc4py

petsc4py.init(sys.argv[:1])
from mpi4py import MPI  # noqa: E402

from pimpm.config import load_config, validate  # noqa: E402
from pimpm.errors import StepFailed  # noqa: E402
from pimpm.simulation import Simulation  # noqa: E402
from pimpm.step_control import TimeStepControl  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
INPUTS = os.path.join(os.path.dirname(HERE), "inputs")
#: Nairn's test: the forces (N, for a 5 mm thickness) and the block's mass (kg)
PRESS, PUSH, BLOCK_MASS = 35.293, 35.294, 0.003


def block_acceleration_exact(mu):
    """The block's acceleration after the ramp: (push - mu press) / mass."""
    return (PUSH - mu * PRESS) / BLOCK_MASS


def implicit_overrides(integrator, dt):
    """The ``--set`` overrides of an implicit run at step ``dt`` (HHT with
    alpha = -0.3); none for ``integrator`` None (the input's explicit one)."""
    if not integrator:
        return []
    return [f"time.integrator={integrator}", f"time.dt={dt}"] + (["time.alpha=-0.3"] if integrator == "hht" else [])


def block_on_plane_config(h=2.5e-3, law="friction", mu=0.5, shape=None, end_time=None, integrator=None, dt=None):
    """``inputs/block_on_plane.yaml`` at cells of ``h`` (m); ``law`` None:
    no contact pair (one shared field); ``integrator``, ``dt``: an implicit
    one at that step instead of the explicit one."""
    overrides = [f"grid.cells=[{int(round(0.140 / h))}, {int(round(0.045 / h))}]"]
    overrides += implicit_overrides(integrator, dt)
    if law is None:
        overrides.append("contact=null")
    else:
        pair = f"{{bodies: [block, plane], law: {law}" + (f", friction_coefficient: {mu}}}" if law == "friction"
                                                         else "}")
        overrides.append(f"contact=[{pair}]")
    if shape:
        overrides.append(f"grid.shape_functions={shape}")
    if end_time:
        overrides.append(f"time.end_time={end_time}")
    return load_config(os.path.join(INPUTS, "block_on_plane.yaml"), overrides)


def body_sums(sim, body):
    """Mass, momentum and first moment of body ``body``'s particles (summed over ranks)."""
    p = sim.particles
    mine = p["body"] == body
    m = p["mass"][mine]
    local = np.concatenate([[np.sum(m)], m @ p["v"][mine], m @ p["x"][mine]])
    return sim.comm.allreduce(local)


def track(sim, bodies):
    """Run ``sim`` to its end time (:func:`march`), keeping after every step
    the bodies' mean velocity and centre of mass: (times (steps,),
    velocities and centres (steps, len(bodies), dim), the steps' infos)."""
    dim = sim.dim
    t, v, x, infos = [], [], [], []
    for info, _ in march(sim, sim.config["time"]["end_time"]):
        infos.append(info)
        sums = np.array([body_sums(sim, b) for b in bodies])
        t.append(sim.time)
        v.append(sums[:, 1:1 + dim] / sums[:, :1])
        x.append(sums[:, 1 + dim:] / sums[:, :1])
    return np.array(t), np.array(v), np.array(x), infos


def block_on_plane(config, comm=MPI.COMM_WORLD):
    """Run it; the block's acceleration fitted to its mean velocity after
    the ramp (t >= 0.2 ms), the time its velocity line crosses zero, the
    energy balance (kinetic + strain + frictional dissipation over the
    external work) and the steps."""
    sim = Simulation(config, comm)
    t, v, _, infos = track(sim, [sim.body_names.index("block")])
    v = v[:, 0, 0]
    late = t >= 0.2e-3
    a, b = np.polyfit(t[late], v[late], 1)
    info = infos[-1]
    dissipation = info.get("frictional_dissipation", 0.0)
    balance = (info["kinetic_energy"] + info["strain_energy"] + dissipation) / info["external_work"]
    return {"acceleration": float(a), "start": float(-b / a), "energy_balance": float(balance),
            "steps": sim.step_index, **newton_counts(infos)}


def step_size(sim):
    """The explicit CFL step, or the input's dt (implicit)."""
    return sim.stable_time_step() if sim.integrator.explicit else sim.config["time"]["dt"]


def march(sim, end):
    """Advance ``sim`` to ``end``, yielding each step's info and its size:
    explicit at the CFL step; implicit at the input's dt with the run's
    step control (a step Newton does not finish is cut in half and
    retried, as ``python -m pimpm`` does: pimpm.step_control)."""
    if sim.integrator.explicit:
        while sim.time < end * (1 - 1e-12):
            dt = min(step_size(sim), end - sim.time)
            yield sim.advance(dt), dt
        return
    control = TimeStepControl(dict(sim.config["time"], end_time=end))
    while not control.done(sim.time):
        dt = control.next_dt(sim.time)
        try:
            info = sim.advance(dt)
        except StepFailed:
            if control.failed():
                continue
            raise
        info["step_cuts"] = control.succeeded(info["newton_iterations"])
        yield info, dt


def newton_counts(infos):
    """Newton iterations per step (mean, largest) and step cuts of an implicit run's step infos
    (a step in free flight takes none); nothing for an explicit run."""
    counts = [i["newton_iterations"] for i in infos]
    return {"newton_mean": float(np.mean(counts)), "newton_max": int(max(counts)),
            "cuts": int(sum(i.get("step_cuts", 0) for i in infos))} if any(counts) else {}


def _disks_raw(cells, shape, speed, end_time, integrator, dt):
    """The raw input of :func:`disks_config` without a contact pair."""
    raw = {"grid": {"lower": [0, 0], "upper": [1, 1], "cells": [cells, cells], "shape_functions": shape},
           "materials": {"elastic": {"model": "neo_hookean", "youngs_modulus": 1000.0, "poisson_ratio": 0.3,
                                     "density": 1000.0}},
           "bodies": [{"name": "left", "material": "elastic", "particles_per_cell": 2, "velocity": [speed, 0],
                       "geometry": {"type": "ball", "center": [0.275, 0.5], "radius": 0.2}},
                      {"name": "right", "material": "elastic", "particles_per_cell": 2, "velocity": [-speed, 0],
                       "geometry": {"type": "ball", "center": [0.725, 0.5], "radius": 0.2}}],
           "time": {"integrator": integrator, "end_time": end_time}}
    if dt:
        raw["time"]["dt"] = dt
    return raw


def disks_config(cells=20, law="frictionless", shape="linear", speed=0.01, end_time=8.0, integrator="explicit",
                 dt=None):
    """Two elastic disks (Sulsky & Kaul 3.1.1's, diameter 0.4) colliding
    head-on along x at 2 x ``speed``, their surfaces 0.05 apart at the start
    and on a particle-domain boundary at every resolution (centres at 0.275
    and 0.725): they touch at t = 0.05 / (2 speed). ``law`` None: one shared
    field."""
    raw = _disks_raw(cells, shape, speed, end_time, integrator, dt)
    if law:
        raw["contact"] = [{"bodies": ["left", "right"], "law": law}]
    return validate(raw)


def mirror_config(cells=20, shape="linear", speed=0.01, end_time=8.0, integrator="explicit", dt=None):
    """The mirror image of :func:`disks_config` with a frictionless pair:
    the left disk alone, meeting a rigid frictionless wall (a half-space
    tool, ``contact: frictionless``, found at the particles' domains like
    the pair) on the symmetry plane x = 0.5 between the two disks. Two equal
    disks meeting head-on without friction move as each one against that
    wall, so this is the same impact with an independent contact."""
    raw = _disks_raw(cells, shape, speed, end_time, integrator, dt)
    raw["bodies"][1] = {"name": "wall", "rigid": True, "contact": "frictionless", "particles_per_cell": 2,
                        "geometry": {"type": "half_space", "point": [0.5, 0.5], "normal": [-1.0, 0.0]}}
    return validate(raw)


def disk_against_wall(config, comm=MPI.COMM_WORLD):
    """Run :func:`mirror_config`'s disk against the wall; returns what
    :func:`disks` returns of it, for the pair's mirror image: the closest
    approach of the centres (twice the centre's of the wall), the
    coefficient of restitution and the total energy after over before."""
    sim = Simulation(config, comm)
    energy0 = sim.kinetic_energy() + sim.strain_energy()
    start = body_sums(sim, 0)
    v0 = start[1] / start[0]
    closest, infos = np.inf, []
    wall = config["bodies"][1]["geometry"]["point"][0]
    for info, _ in march(sim, config["time"]["end_time"]):
        infos.append(info)
        sums = body_sums(sim, 0)
        closest = min(closest, 2.0 * (wall - sums[3] / sums[0]))
    return {"closest": float(closest), "restitution": float(-sums[1] / sums[0] / v0),
            "energy_ratio": float((info["kinetic_energy"] + info["strain_energy"]) / energy0),
            "steps": sim.step_index, **newton_counts(infos)}


def disks(config, comm=MPI.COMM_WORLD):
    """Run two colliding disks (bodies 0 and 1); returns the largest change
    of the total momentum over the run relative to one disk's initial
    momentum, the first time the pair was in contact and the gap closed per
    step then, the closest approach of the centres, the coefficient of
    restitution (the relative velocity of the centres after over before),
    the total energy after over before, and how far apart along the line
    of centres the two disks' nearest particles are at the end."""
    sim = Simulation(config, comm)
    pair = sim.fields.names[0] if sim.fields.names else None

    def state():
        a, b = body_sums(sim, 0), body_sums(sim, 1)
        dim = sim.dim
        return (a[1:1 + dim] + b[1:1 + dim], a[1 + dim:] / a[0], b[1 + dim:] / b[0],
                a[1:1 + dim] / a[0], b[1:1 + dim] / b[0], np.linalg.norm(a[1:1 + dim]))

    momentum0, ca, cb, va0, vb0, reference = state()
    line = (cb - ca) / np.linalg.norm(cb - ca)
    energy0 = sim.kinetic_energy() + sim.strain_energy()
    drift, closest, touch, closing, infos = 0.0, np.inf, None, None, []
    for info, dt in march(sim, config["time"]["end_time"]):
        infos.append(info)
        momentum, ca, cb, va, vb, _ = state()
        drift = max(drift, float(np.max(np.abs(momentum - momentum0))) / reference)
        closest = min(closest, float(np.linalg.norm(cb - ca)))
        if touch is None and pair and info["contact"][pair]["contact_points"] > 0:
            touch, closing = sim.time - dt, float((va - vb) @ line * dt)
    p = sim.particles
    along = p["x"] @ line
    first = comm.allreduce(float(np.max(along[p["body"] == 0], initial=-np.inf)), op=MPI.MAX)
    second = comm.allreduce(float(np.min(along[p["body"] == 1], initial=np.inf)), op=MPI.MIN)
    return {"momentum_drift": drift, "touch": touch, "closing_per_step": closing, "closest": closest,
            "restitution": float(-((va - vb) @ line) / ((va0 - vb0) @ line)),
            "energy_ratio": float((info["kinetic_energy"] + info["strain_energy"]) / energy0),
            "apart": second - first, "steps": sim.step_index, **newton_counts(infos)}


def stacked_blocks_config(h=0.01, mus=(0.5, 0.1, 0.8), end_time=None, integrator=None, dt=None):
    """``inputs/stacked_blocks.yaml`` at cells of ``h`` with the coefficients
    ``mus`` of the floor-a, a-b and b-c interfaces; ``integrator``, ``dt``:
    an implicit one at that step instead of the explicit one."""
    pairs = ", ".join(f"{{bodies: [{lower}, {upper}], law: friction, friction_coefficient: {mu}}}"
                      for (lower, upper), mu in zip((("floor", "a"), ("a", "b"), ("b", "c")), mus))
    overrides = [f"grid.cells=[{int(round(0.5 / h))}, {int(round(0.3 / h))}]", f"contact=[{pairs}]"]
    overrides += implicit_overrides(integrator, dt)
    if end_time:
        overrides.append(f"time.end_time={end_time}")
    return load_config(os.path.join(INPUTS, "stacked_blocks.yaml"), overrides)


def stacked_blocks_expected(mus, push=0.5):
    """Coulomb's answer for the stack: the interface that slips (1: floor-a,
    2: a-b, 3: b-c; the weakest, which carries k = 4 - i blocks and holds mu
    k m g), and the acceleration of the blocks above it over g."""
    capacity = [mu * (3 - i) for i, mu in enumerate(mus)]
    weakest = int(np.argmin(capacity))
    return weakest + 1, (push - capacity[weakest]) / (3 - weakest)


def stacked_blocks(config, comm=MPI.COMM_WORLD):
    """Run the stack: each body's displacement along x at the end and its
    acceleration over g fitted after the push is applied (t >= 80 ms)."""
    sim = Simulation(config, comm)
    t, _, x, infos = track(sim, range(4))
    x = x[:, :, 0]
    late = t >= 0.08
    g = -config["time"]["gravity"][1]
    return {"displacement": (x[-1] - x[0]).tolist(),
            "acceleration": [float(2 * np.polyfit(t[late], x[late, b], 2)[0] / g) for b in range(4)],
            "steps": sim.step_index, **newton_counts(infos)}


def disk_on_slope_config(h=0.01, mu=0.5, shape=None, end_time=None, integrator=None, dt=None, modulus=None):
    """``inputs/disk_on_slope.yaml`` at cells of ``h`` with friction ``mu``
    (``integrator``, ``dt``: an implicit one at that step; ``modulus``: the
    bodies' Young's modulus instead of the input's 10 MPa)."""
    rows = int(np.ceil(0.35 / h - 1e-9))          # square cells: the grid's top at or above the input's
    overrides = [f"grid.cells=[{int(round(1.0 / h))}, {rows}]", f"grid.upper=[1.0, {rows * h:.12g}]",
                 f"contact=[{{bodies: [disk, plate], law: friction, friction_coefficient: {mu}}}]"]
    overrides += implicit_overrides(integrator, dt)
    if end_time:
        overrides.append(f"time.end_time={end_time}")
    if shape:
        overrides.append(f"grid.shape_functions={shape}")
    if modulus:
        overrides.append(f"materials.elastic.youngs_modulus={modulus}")
    return load_config(os.path.join(INPUTS, "disk_on_slope.yaml"), overrides)


def disk_on_slope_expected(mu, theta=np.pi / 4, g=9.81):
    """Rolling without slip, (2/3) g sin(theta), while mu >= tan(theta) / 3;
    sliding at g (sin(theta) - mu cos(theta)) otherwise."""
    if mu >= np.tan(theta) / 3:
        return 2.0 / 3.0 * g * np.sin(theta)
    return g * (np.sin(theta) - mu * np.cos(theta))


def disk_on_slope(config, comm=MPI.COMM_WORLD):
    """The disk's centre acceleration along the slope, fitted after the
    gravity ramp (t >= 50 ms)."""
    sim = Simulation(config, comm)
    t, _, x, infos = track(sim, [sim.body_names.index("disk")])
    x = x[:, 0, 0]
    late = t >= 0.05
    return {"acceleration": float(2 * np.polyfit(t[late], x[late], 2)[0]), "steps": sim.step_index,
            **newton_counts(infos)}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", help="write the numbers here")
    args = parser.parse_args()
    out = {"block_on_plane": [], "disks": [], "disks_diagonal": []}
    start = time.perf_counter()
    print("Nairn's block on a deformable plane (explicit): acceleration after the ramp")
    print(f"{'h (mm)':>7} {'law':>13} {'a (m/s^2)':>11} {'exact':>9} {'error':>8} {'v=0 at (ms)':>11} "
          f"{'energy':>7} {'steps':>6}")
    for h in (5e-3, 2.5e-3, 1.25e-3):
        for law, mu in (("friction", 0.5), ("frictionless", 0.0), (None, 0.0)):
            r = block_on_plane(block_on_plane_config(h, law, mu))
            exact = block_acceleration_exact(mu) if law else block_acceleration_exact(mu)
            r.update(h=h, law=law or "one field", mu=mu, exact=exact)
            out["block_on_plane"].append(r)
            print(f"{h * 1e3:7.2f} {r['law']:>13} {r['acceleration']:11.1f} {exact:9.1f} "
                  f"{r['acceleration'] / exact - 1:+8.2%} {r['start'] * 1e3:11.4f} {r['energy_balance']:7.4f} "
                  f"{r['steps']:6d}")
    print("\nThe same inside Newton (trapezoidal rule) at 10, 100 and 1000 times the explicit step (1000x: "
          "friction only, to 5.2 ms: four steps at 5 mm); Newton iterations per step")
    print(f"{'h (mm)':>7} {'law':>13} {'dt':>9} {'a (m/s^2)':>11} {'exact':>9} {'error':>8} {'energy':>7} "
          f"{'steps':>6} {'newton':>7} {'max':>4} {'cuts':>5}")
    explicit_dt = {5e-3: 1.3e-6, 2.5e-3: 6.5e-7}
    out["block_on_plane_implicit"] = []
    for h in (5e-3, 2.5e-3):
        for factor in (10, 100, 1000):
            for law, mu in (("friction", 0.5), ("frictionless", 0.0)):
                if factor == 1000 and law == "frictionless":
                    continue                    # twice as fast, it would leave the plane by 5.2 ms
                dt = factor * explicit_dt[h]
                r = block_on_plane(block_on_plane_config(h, law, mu, integrator="newmark", dt=dt,
                                                         end_time=5.2e-3 if factor == 1000 else None))
                exact = block_acceleration_exact(mu)
                r.update(h=h, law=law, mu=mu, dt=dt, factor=factor, exact=exact)
                out["block_on_plane_implicit"].append(r)
                print(f"{h * 1e3:7.2f} {law:>13} {f'{factor}x':>9} {r['acceleration']:11.1f} {exact:9.1f} "
                      f"{r['acceleration'] / exact - 1:+8.2%} {r['energy_balance']:7.4f} {r['steps']:6d} "
                      f"{r['newton_mean']:7.2f} {r['newton_max']:4d} {r['cuts']:5d}")
    print("\nTwo disks colliding head-on (explicit, frictionless pair; touching at t = 2.5)")
    print(f"{'cells':>5} {'shape':>6} {'law':>12} {'touch':>7} {'closest':>8} {'restitution':>11} "
          f"{'energy':>7} {'momentum':>9} {'steps':>6}")
    for shape in ("linear", "gimp"):
        for cells in (20, 40, 80):
            for law in ("frictionless", None):
                if law is None and cells > 20:
                    continue
                r = disks(disks_config(cells, law, shape))
                r.update(cells=cells, shape=shape, law=law or "one field")
                out["disks"].append(r)
                touch = f"{r['touch']:7.3f}" if r["touch"] is not None else f"{'-':>7}"
                print(f"{cells:5d} {shape:>6} {r['law']:>12} {touch} {r['closest']:8.5f} {r['restitution']:11.4f} "
                      f"{r['energy_ratio']:7.4f} {r['momentum_drift']:9.1e} {r['steps']:6d}")
    print("\nThe same inside Newton (trapezoidal rule, linear, frictionless pair)")
    out["disks_implicit"] = []
    for cells, dt in ((20, 0.02), (20, 0.1), (20, 0.2), (40, 0.05)):
        r = disks(disks_config(cells, integrator="newmark", dt=dt))
        r.update(cells=cells, dt=dt)
        out["disks_implicit"].append(r)
        print(f"{cells:5d} dt {dt:4.2f} {r['touch']:7.3f} {r['closest']:8.5f} {r['restitution']:11.4f} "
              f"{r['energy_ratio']:7.4f} {r['momentum_drift']:9.1e} {r['steps']:6d} newton {r['newton_mean']:.2f} "
              f"(max {r['newton_max']}, cuts {r['cuts']})")
    print("\nSulsky & Kaul's disks, diagonal (inputs/colliding_disks_contact.yaml, to t = 150)")
    for law in ("frictionless", None):
        overrides = [] if law else ["contact=null"]
        r = disks(load_config(os.path.join(INPUTS, "colliding_disks_contact.yaml"), overrides))
        r.update(law=law or "one field")
        out["disks_diagonal"].append(r)
        print(f"{r['law']:>12}: closest {r['closest']:.4f}, restitution {r['restitution']:.4f}, energy after/before "
              f"{r['energy_ratio']:.4f}, momentum drift {r['momentum_drift']:.1e}, {r['steps']} steps")
    print("\nStacked blocks pushed sideways by half the top block's weight (explicit): which interface slips")
    print(f"{'h (m)':>6} {'mu floor-a, a-b, b-c':>22} {'slips (Coulomb)':>16} {'displacements a, b, c (mm)':>30} "
          f"{'a/g moving':>10} {'Coulomb':>8}")
    out["stacked_blocks"] = []
    for h in (0.02, 0.01, 0.005):
        for mus in ((0.5, 0.1, 0.8), (0.05, 0.6, 0.8), (0.5, 0.6, 0.2)):
            r = stacked_blocks(stacked_blocks_config(h, mus))
            layer, expected = stacked_blocks_expected(mus)
            moving = np.mean(r["acceleration"][layer:])
            r.update(h=h, mus=list(mus), layer=layer, expected=expected, moving=float(moving))
            out["stacked_blocks"].append(r)
            names = ("floor-a", "a-b", "b-c")
            print(f"{h:6.3f} {str(mus):>22} {names[layer - 1]:>16} "
                  f"{' '.join(f'{1e3 * d:9.2f}' for d in r['displacement'][1:]):>30} {moving:10.4f} {expected:8.4f}")
    print("\nA disk on a 45 degree slope (explicit): centre acceleration")
    out["disk_on_slope"] = []
    # the last: rolling with bodies 16 times softer (the test's, a 4 times longer step)
    for h, mu, modulus in ((0.02, 0.5, None), (0.02, 0.1, None), (0.01, 0.5, None), (0.01, 0.1, None),
                           (0.01, 0.5, 6.25e5)):
        r = disk_on_slope(disk_on_slope_config(h, mu, modulus=modulus))
        exact = disk_on_slope_expected(mu)
        r.update(h=h, mu=mu, exact=float(exact), youngs_modulus=modulus or 1e7)
        out["disk_on_slope"].append(r)
        print(f"h {h:6.3f} mu {mu:4.2f} E {(modulus or 1e7) / 1e6:5.3f} MPa: {r['acceleration']:.4f} m/s^2 against "
              f"{'rolling' if mu >= 1 / 3 else 'sliding'} {exact:.4f} ({r['acceleration'] / exact - 1:+.2%}), "
              f"{r['steps']} steps")
    print("\nInside Newton (trapezoidal rule), mu = 0.5, 0.1, 0.8: the stack at 0.01 m cells and 5, 10 and 30 "
          "times the explicit step (1.4e-4 s); the disk on the slope at 10 and 100 times (8.6e-5 s at 0.02 m, "
          "4.3e-5 s at 0.01 m)")
    out["stacked_blocks_implicit"], out["disk_on_slope_implicit"] = [], []
    mus = (0.5, 0.1, 0.8)
    layer, expected = stacked_blocks_expected(mus)
    for factor in (5, 10, 30):
        dt = factor * 1.4e-4
        r = stacked_blocks(stacked_blocks_config(0.01, mus, integrator="newmark", dt=dt))
        moving = np.mean(r["acceleration"][layer:])
        r.update(h=0.01, mus=list(mus), dt=dt, factor=factor, layer=layer, expected=expected, moving=float(moving))
        out["stacked_blocks_implicit"].append(r)
        print(f"stack {factor:4d}x: displacements a, b, c (mm) "
              f"{' '.join(f'{1e3 * d:7.2f}' for d in r['displacement'][1:])}, b and c at {moving:.4f} g "
              f"(Coulomb {expected:.4f}), newton {r['newton_mean']:.2f} (max {r['newton_max']}, cuts {r['cuts']})")
    for h, explicit in ((0.02, 8.6e-5), (0.01, 4.3e-5)):
        for factor in (10, 100):
            for mu in (0.5, 0.1):
                dt = factor * explicit
                r = disk_on_slope(disk_on_slope_config(h, mu, integrator="newmark", dt=dt))
                exact = disk_on_slope_expected(mu)
                r.update(h=h, mu=mu, dt=dt, factor=factor, exact=float(exact))
                out["disk_on_slope_implicit"].append(r)
                print(f"slope h {h:5.3f} {factor:4d}x mu {mu:4.2f}: {r['acceleration']:.4f} m/s^2 against "
                      f"{'rolling' if mu >= 1 / 3 else 'sliding'} {exact:.4f} ({r['acceleration'] / exact - 1:+.2%}), "
                      f"{r['steps']} steps, newton {r['newton_mean']:.2f} (max {r['newton_max']}, cuts {r['cuts']})")
    print(f"\n{time.perf_counter() - start:.0f} s")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
