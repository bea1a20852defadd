#!/usr/bin/env python3
"""Makes inputs/plate_with_hole.msh with Gmsh (the ``gmsh`` Python module:
Debian's python3-gmsh, or ``pip install gmsh``): a quarter of a plate 10 wide
and 20 long with a central circular hole of radius 1 (d/w = 0.2), the
quarter x in [0, 5], y in [0, 10] with the hole's centre at the origin;
linear triangles, 0.04 at the hole growing to 0.12 away from it, written in
Gmsh's MSH 4.1 format. The mesh is shipped, so running pimpm on it needs no
Gmsh; rerun this after changing the geometry.

    python scripts/make_plate_with_hole.py [--out inputs/plate_with_hole.msh] [--size-factor 1]

(--size-factor 0.5 --out /tmp/plate_fine.msh makes the finer mesh of the
40-cells-per-radius row of docs/VALIDATION.md.)
"""
import argparse
import os

import gmsh

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
HALF_WIDTH, HALF_LENGTH, RADIUS = 5.0, 10.0, 1.0
FINE, COARSE = 0.04, 0.12


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=os.path.join(ROOT, "inputs", "plate_with_hole.msh"))
    ap.add_argument("--size-factor", type=float, default=1.0, help="scales the element sizes")
    args = ap.parse_args()
    fine, coarse = FINE * args.size_factor, COARSE * args.size_factor
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("plate_with_hole")
    occ = gmsh.model.occ
    plate = occ.addRectangle(0.0, 0.0, 0.0, HALF_WIDTH, HALF_LENGTH)
    hole = occ.addDisk(0.0, 0.0, 0.0, RADIUS, RADIUS)
    occ.cut([(2, plate)], [(2, hole)])
    occ.synchronize()
    # element size: FINE on the hole, growing linearly to COARSE 3 radii away
    arc = [tag for dim, tag in gmsh.model.getEntities(1)
           if abs(gmsh.model.occ.getMass(1, tag) - 0.5 * 3.141592653589793 * RADIUS) < 1e-6]
    field = gmsh.model.mesh.field
    distance = field.add("Distance")
    field.setNumbers(distance, "CurvesList", arc)
    field.setNumber(distance, "NumPointsPerCurve", 200)
    threshold = field.add("Threshold")
    field.setNumber(threshold, "InField", distance)
    field.setNumber(threshold, "SizeMin", fine)
    field.setNumber(threshold, "SizeMax", coarse)
    field.setNumber(threshold, "DistMin", 0.0)
    field.setNumber(threshold, "DistMax", 3.0 * RADIUS)
    field.setAsBackgroundMesh(threshold)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
    group = gmsh.model.addPhysicalGroup(2, [tag for _, tag in gmsh.model.getEntities(2)])
    gmsh.model.setPhysicalName(2, group, "plate")
    gmsh.model.mesh.generate(2)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 0)
    gmsh.write(args.out)
    nodes = len(gmsh.model.mesh.getNodes()[0])
    gmsh.finalize()
    print(f"written: {args.out} ({nodes} nodes, {os.path.getsize(args.out) / 1e6:.1f} MB)")


if __name__ == "__main__":
    main()
