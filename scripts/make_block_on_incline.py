#!/usr/bin/env python3
"""Write inputs/block_on_incline.csv: the particles of a 20 x 20 mm block
resting on a ramp inclined at 30 degrees (inputs/block_on_incline.yaml), a
square lattice of 16 x 16 particles (1.25 mm apart, the 2 x 2 particles per
2.5 mm cell of inputs/block_on_ramp.yaml) turned by -30 degrees so that the
block's bottom face lies along the ramp.

The ramp is the half-space below the line through (0, 0.05) with normal
n = (sin 30, cos 30). A particle's GIMP domain stays axis-aligned (a square
of the particle's volume), so a bottom particle's lowest domain corner reaches
(s / 2)(sin 30 + cos 30) below its centre along n, not s / 2: the block is
lifted along n by (s / 2)(sin 30 + cos 30 - 1) so that those corners just
touch the ramp (any deeper and the first step's penalty would throw the block
off the ramp).

    python scripts/make_block_on_incline.py [--output inputs/block_on_incline.csv]
"""
import argparse
import os

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ANGLE = np.radians(30.0)
POINT = np.array([0.0, 0.05])            # on the ramp's surface
SIDE, COUNT, START = 0.02, 16, 0.005     # the block's side, particles per side, its start along the ramp


def particles():
    tangent = np.array([np.cos(ANGLE), -np.sin(ANGLE)])      # down the ramp
    normal = np.array([np.sin(ANGLE), np.cos(ANGLE)])        # out of the ramp
    spacing = SIDE / COUNT
    lift = 0.5 * spacing * (np.sin(ANGLE) + np.cos(ANGLE) - 1.0)
    a, b = np.meshgrid((np.arange(COUNT) + 0.5) * spacing, (np.arange(COUNT) + 0.5) * spacing, indexing="ij")
    x = POINT + (START + a.ravel())[:, None] * tangent + (lift + b.ravel())[:, None] * normal
    return x, np.full(len(x), spacing ** 2)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--output", default=os.path.join(ROOT, "inputs", "block_on_incline.csv"))
    args = ap.parse_args()
    x, volume = particles()
    with open(args.output, "w") as f:
        f.write("# written by scripts/make_block_on_incline.py\nx,y,volume\n")
        for (px, py), v in zip(x, volume):
            f.write(f"{float(px)!r},{float(py)!r},{float(v)!r}\n")
    print(f"wrote {args.output} ({len(x)} particles)")


if __name__ == "__main__":
    main()
