#!/usr/bin/env python3
"""The plate with a hole of inputs/plate_with_hole.yaml (Gmsh mesh
inputs/plate_with_hole.msh) against Heywood's stress concentration factor
(docs/VALIDATION.md, "Plate with a hole"), at the shipped grid (h = 0.05,
20 cells per hole radius) and at h = 0.1 and 0.025 (with --fine-mesh FILE,
a mesh of half the element size made by make_plate_with_hole.py, for the
finest grid so that it keeps several particles per cell).

The peak hoop stress is sigma_yy at the hole's edge on the ligament,
extrapolated from the particles next to it (pimpm.measures.hole_peak_stress),
over the applied traction; Heywood: Kt = 3.14 for d/w = 0.2.

    python scripts/plate_hole_validation.py [--ranks 2] [--cells-per-radius 10 20]
        [--fine-mesh /tmp/fine.msh] [--json docs/data/plate_hole_validation.json]
"""
import argparse
import json
import os
import sys
import tempfile

import numpy as np
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests"))
from helpers import last_particles, run_pimpm  # noqa: E402
from pimpm.measures import hole_peak_stress  # noqa: E402
from pimpm.reference import heywood_kt  # noqa: E402

INPUT = os.path.join(ROOT, "inputs", "plate_with_hole.yaml")
RADIUS, WIDTH = 1.0, 10.0


def run(cells_per_radius, ranks, workdir, mesh=None):
    """Run the input with h = radius / cells_per_radius; returns the row."""
    with open(INPUT) as f:
        raw = yaml.safe_load(f)
    h = RADIUS / cells_per_radius
    cells = [int(round(u / h)) for u in raw["grid"]["upper"]]
    traction = raw["loads"][0]["traction"][1]
    out = os.path.join(workdir, f"h{cells_per_radius}-{ranks}")
    args = [INPUT, "--overwrite", "--output", out, "--set", f"grid.cells=[{cells[0]},{cells[1]}]"]
    if mesh:
        args += ["--set", f"bodies[0].geometry.file={os.path.abspath(mesh)}"]
    proc = run_pimpm(ranks, args)
    if proc.returncode != 0:
        raise RuntimeError(proc.stdout[-2000:] + proc.stderr[-2000:])
    particles, _ = last_particles(os.path.join(out, "results.h5"))
    x0 = particles["position"] - particles["displacement"]
    peak, largest, fitted = hole_peak_stress(x0, particles["stress"], RADIUS)
    kt = heywood_kt(2.0 * RADIUS, WIDTH)
    return {"cells_per_radius": cells_per_radius, "h": h, "mesh": os.path.basename(mesh or "plate_with_hole.msh"),
            "particles": int(len(x0)), "kt": peak / traction, "largest_particle": largest / traction,
            "fitted": fitted, "heywood": kt, "difference": peak / traction / kt - 1.0}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--cells-per-radius", type=int, nargs="+", default=[10, 20])
    ap.add_argument("--fine-mesh", help="a finer mesh for one more run at 40 cells per radius")
    ap.add_argument("--json", default=os.path.join(ROOT, "docs", "data", "plate_hole_validation.json"))
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as workdir:
        for n in args.cells_per_radius:
            rows.append(run(n, args.ranks, workdir))
            print(json.dumps(rows[-1]), flush=True)
        if args.fine_mesh:
            rows.append(run(40, args.ranks, workdir, args.fine_mesh))
            print(json.dumps(rows[-1]), flush=True)
    print("\n| cells per hole radius | mesh | particles | Kt (extrapolated to the edge) | largest particle value "
          "| Heywood | difference |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['cells_per_radius']} | {r['mesh']} | {r['particles']} | {r['kt']:.3f} | "
              f"{r['largest_particle']:.3f} | {r['heywood']:.3f} | {r['difference']:+.2%} |")
    with open(args.json, "w") as f:
        json.dump(rows, f, indent=1)
    print(f"\nwritten: {args.json}")


if __name__ == "__main__":
    main()
