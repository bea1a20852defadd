#!/usr/bin/env python3
"""Tools of any shape (pimpm.surfaces): the same tool given analytically and
as a mesh gives the same answer, and what a mesh tool costs.

1. The rigid plate that lets go (inputs/plate_release.yaml, frictionless, 1
   rank): the plate as a box, as a closed outline (`type: surface`), as a
   one-quad volume mesh (`type: mesh`) and as its bottom edge alone (an open
   line drawn the wrong way, turned by `flip_normals`): the largest
   difference of the plate force and contact area from the box's, over the
   whole history.
2. The billet with a frictional platen (inputs/billet.yaml, 0.5 cm cells,
   mu = 0.3, 50%, `mpiexec -n RANKS`): the platen as a box and as an outline
   whose bottom edge is divided into 1, 400 and 4000 segments: the force at
   50% and the median wall time of the whole process over --repeats rounds
   (variants alternating), against the box.

    python scripts/surface_tools.py [--ranks 2] [--repeats 2] [--json docs/data/surface_tools.json]
"""
import argparse
import json
import os
import statistics
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests", "mpi"))
from surface_shapes import write_surface  # noqa: E402

from pimpm_runs import run_pimpm  # noqa: E402


def run(input_path, overrides, ranks, out):
    wall, rows = run_pimpm(input_path, overrides, ranks, out)
    return wall, {k: np.array([float(r[k]) for r in rows]) for k in rows[0] if k != "wall_time"}


def outline(lower, upper, bottom_segments):
    """A box's counter-clockwise outline, its bottom edge in that many segments."""
    xs = np.linspace(lower[0], upper[0], bottom_segments + 1)
    points = np.concatenate([np.stack([xs, np.full_like(xs, lower[1])], axis=1),
                             [[upper[0], upper[1]], [lower[0], upper[1]]]])
    n = len(points)
    return points, np.stack([np.arange(n), (np.arange(n) + 1) % n], axis=1)


def plate(work):
    import meshio
    corners = np.array([[0.0, 0.8], [1.0, 0.8], [1.0, 0.9], [0.0, 0.9]])
    write_surface(os.path.join(work, "plate_outline.vtk"), corners, np.array([[0, 1], [1, 2], [2, 3], [3, 0]]))
    write_surface(os.path.join(work, "plate_bottom.vtk"), corners[[1, 0]], np.array([[0, 1]]))
    meshio.write_points_cells(os.path.join(work, "plate_quad.vtk"), np.pad(corners, ((0, 0), (0, 1))),
                              [("quad", np.array([[0, 1, 2, 3]]))])
    source = os.path.join(ROOT, "inputs", "plate_release.yaml")
    variants = {
        "box": [],
        "surface (outline)": [f"bodies[1].geometry={{type: surface, file: {work}/plate_outline.vtk}}"],
        "surface (bottom edge, flip_normals)":
            [f"bodies[1].geometry={{type: surface, file: {work}/plate_bottom.vtk, flip_normals: true}}"],
    }
    rows = {}
    for name, overrides in variants.items():
        wall, history = run(source, overrides, 1, os.path.join(work, "plate"))
        rows[name] = history
    # the quad mesh: a mesh body takes no particles_per_cell (an input of its own)
    with open(source) as f:
        text = f.read()
    text = text.replace("geometry: {type: box, lower: [0.0, 0.8], upper: [1.0, 0.9]}\n    particles_per_cell: 2",
                        f"geometry: {{type: mesh, file: {work}/plate_quad.vtk, particles_per_element: 2}}")
    quad_input = os.path.join(work, "plate_quad.yaml")
    with open(quad_input, "w") as f:
        f.write(text)
    rows["mesh (one quad)"] = run(quad_input, [], 1, os.path.join(work, "plate"))[1]
    box = rows["box"]
    table = []
    for name, history in rows.items():
        difference = max(float(np.max(np.abs(history[k] - box[k])) / np.max(np.abs(box[k])))
                         for k in ("plate_force_y", "plate_contact_area"))
        table.append({"tool": name, "steps": len(history["step"]),
                      "largest force": float(np.min(history["plate_force_y"])),
                      "force after release": float(history["plate_force_y"][-1]),
                      "difference from the box": difference})
    return table


def billet(work, ranks, repeats):
    lower, upper = (0.0, 20.0), (39.0, 20.5)
    friction = ["bodies[1].contact=friction", "bodies[1].friction_coefficient=0.3"]
    variants = {"box": friction}
    for segments in (1, 400, 4000):
        path = os.path.join(work, f"platen_{segments}.vtk")
        write_surface(path, *outline(lower, upper, segments))
        variants[f"surface, {segments + 3} segments"] = friction + [f"bodies[1].geometry={{type: surface, file: {path}}}"]
    source = os.path.join(ROOT, "inputs", "billet.yaml")
    walls = {name: [] for name in variants}
    results = {}
    for _ in range(repeats):
        for name, overrides in variants.items():
            wall, history = run(source, overrides, ranks, os.path.join(work, "billet"))
            walls[name].append(wall)
            results[name] = history
    box_wall = statistics.median(walls["box"])
    table = []
    for name, history in results.items():
        table.append({"tool": name, "steps": len(history["step"]), "step cuts": int(np.sum(history["step_cuts"])),
                      "newton": int(np.sum(history["newton_iterations"])),
                      "force at 50% (dyn per cm)": float(-history["platen_force_y"][-1]),
                      "force difference from the box": float(abs(history["platen_force_y"][-1]
                                                                 - results["box"]["platen_force_y"][-1])
                                                             / abs(results["box"]["platen_force_y"][-1])),
                      "wall (s, median)": statistics.median(walls[name]),
                      "wall / box": statistics.median(walls[name]) / box_wall})
    return table


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ranks", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--json")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as work:
        plate_rows = plate(work)
        print("| plate tool | steps | largest force (N per m) | force after release | difference from the box |")
        print("|---|---|---|---|---|")
        for r in plate_rows:
            print(f"| {r['tool']} | {r['steps']} | {r['largest force']:.6g} | {r['force after release']:.3g} | "
                  f"{r['difference from the box']:.1e} |")
        billet_rows = billet(work, args.ranks, args.repeats)
        print(f"\n| billet platen (mu 0.3, {args.ranks} ranks) | steps | cuts | Newton | force at 50% (dyn per cm) "
              f"| difference | wall (s) | / box |")
        print("|---|---|---|---|---|---|---|---|")
        for r in billet_rows:
            print(f"| {r['tool']} | {r['steps']} | {r['step cuts']} | {r['newton']} | "
                  f"{r['force at 50% (dyn per cm)']:.6g} | {r['force difference from the box']:.1e} | "
                  f"{r['wall (s, median)']:.1f} | {r['wall / box']:.2f} |")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"ranks": args.ranks, "repeats": args.repeats, "plate": plate_rows, "billet": billet_rows},
                      f, indent=1)
        print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
