#!/usr/bin/env python3
"""HHT-alpha's controllable high-frequency damping on the vibrating bar of
tests/test_integrators.py (plane strain, 25 cells, fixed at x = 0, free at
x = 1), 1 rank, dt = 0.0025 (3.7x the explicit step). The bar starts in its
fundamental mode (omega dt = 0.14) or in its third mode (5x the frequency,
omega dt = 0.72) and runs for two fundamental periods with pimpm's own loop.
Prints the energy lost by the trapezoidal rule (the particle-grid
transfers' own loss) and, for each alpha, the loss beyond it next to the
loss of the HHT oscillator at the mode's omega dt (the scheme's
amplification matrix).

    python scripts/hht_damping.py [--alpha -0.05 -0.1 -0.2 -0.3]
"""
import argparse
import os
import sys

import petsc4py
petsc4py.init([])
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests"))
from test_integrators import DT, hht_oscillator_energy, vibrate_mode   # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--alpha", type=float, nargs="+", default=[-0.05, -0.1, -0.2, -0.3])
    args = ap.parse_args()
    print("| mode | omega dt | trapezoidal (alpha 0) loss | "
          + " | ".join(f"alpha {a:g}: loss beyond alpha 0 (oscillator)" for a in args.alpha) + " |")
    print("|---|---|---|" + "---|" * len(args.alpha))
    for mode in (0, 2):
        periods = 2.0 * (2 * mode + 1)             # two fundamental periods
        ref_sim, period, ref = vibrate_mode("hht", mode, periods, alpha=0.0)
        ref_sim.solver.destroy()
        omega_dt = 2.0 * np.pi / period * DT
        cells = []
        for alpha in args.alpha:
            sim, _, energy = vibrate_mode("hht", mode, periods, alpha=alpha)
            loss = 1.0 - (energy[-1] / energy[0]) / (ref[-1] / ref[0])
            predicted = 1.0 - hht_oscillator_energy(omega_dt, alpha, sim.step_index)
            cells.append(f"{loss:.3%} ({predicted:.3%})")
            sim.solver.destroy()
        print(f"| {mode + 1} ({2 * mode + 1}x the fundamental) | {omega_dt:.3f} | {1.0 - ref[-1] / ref[0]:.3%} | " + " | ".join(cells) + " |",
              flush=True)


if __name__ == "__main__":
    main()
