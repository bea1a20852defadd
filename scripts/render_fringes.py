#!/usr/bin/env python3
"""Photoelastic fringe images (Guilkey & Weiss 2003, eq. 22) from a pimpm
results.h5: F = cos(2 pi f_no (sigma_1 - sigma_2) / max(sigma_1 - sigma_2)),
with the in-plane principal stress difference that pimpm writes as the
particle field ``principal_stress_difference``.

    python scripts/render_fringes.py OUTDIR/results.h5 [OUTDIR2/results.h5 ...] \\
        --times 1.9 4.8 6.7 --time-unit 9.8e-7 [--labels implicit explicit] \\
        [--fringes 7] [--pixel SIZE] [--out fringes.png]

Several results files are drawn side by side (one column each).

``--time-unit`` makes the times non-dimensional (the wave transit time
across one disk for the four-disk problem); the nearest output step is used.
"""
import argparse

import h5py
import numpy as np


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results", nargs="+")
    ap.add_argument("--labels", nargs="+", help="one title per results file")
    ap.add_argument("--pixel", type=float, default=None,
                    help="pixel size (default: about the particle spacing)")
    ap.add_argument("--times", type=float, nargs="+", required=True)
    ap.add_argument("--time-unit", type=float, default=1.0)
    ap.add_argument("--fringes", type=float, default=7.0, help="f_no of eq. 22")
    ap.add_argument("--out", default="fringes.png")
    args = ap.parse_args()
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    labels = args.labels or [""] * len(args.results)
    if len(labels) != len(args.results):
        ap.error("give one --labels entry per results file")
    ncol = len(args.results)
    fig, axes = plt.subplots(len(args.times), ncol, figsize=(10 * ncol, 2.6 * len(args.times)),
                             squeeze=False)
    for col, (path, label) in enumerate(zip(args.results, labels)):
        with h5py.File(path, "r") as f:
            steps = sorted(f["steps"])
            times = np.array([f["steps"][s].attrs["time"] for s in steps]) / args.time_unit
            for ax, t in zip(axes[:, col], args.times):
                k = int(np.argmin(np.abs(times - t)))
                g = f["steps"][steps[k]]["particles"]
                x = g["position"][:, :2]
                diff = g["principal_stress_difference"][...]
                material = diff > 0
                fringe = np.cos(2 * np.pi * args.fringes * diff / max(diff.max(), 1e-300))   # eq. 22
                ax.imshow(pixels(x[material], fringe[material], args.pixel), origin="lower",
                          cmap="gray", vmin=-1, vmax=1, interpolation="nearest",
                          extent=extent(x[material], args.pixel))
                ax.set_aspect("equal")
                ax.set_title(f"{label + ': ' if label else ''}t = {times[k]:.2f} "
                             f"(eq. 22, f_no = {args.fringes:g})")
                ax.set_xticks([])
                ax.set_yticks([])
    fig.tight_layout()
    fig.savefig(args.out, dpi=90)
    print("wrote", args.out)


def _pixel_size(x, pixel):
    """The given size, or about the particle spacing: sqrt(box area / n)."""
    if pixel is not None:
        return pixel
    span = np.ptp(x, axis=0)
    return float(np.sqrt(np.prod(span) / len(x))) if len(x) > 1 and np.all(span > 0) else 1.0


def extent(x, pixel):
    h = _pixel_size(x, pixel)
    lo = x.min(axis=0) - h / 2
    n = np.floor((x.max(axis=0) - lo) / h).astype(int) + 1
    return [lo[0], lo[0] + n[0] * h, lo[1], lo[1] + n[1] * h]


def pixels(x, values, pixel):
    """Average particle values over square pixels (NaN where empty): the
    image of a particle field."""
    h = _pixel_size(x, pixel)
    lo = x.min(axis=0) - h / 2
    ij = np.floor((x - lo) / h).astype(int)
    n = ij.max(axis=0) + 1
    flat = ij[:, 1] * n[0] + ij[:, 0]
    total = np.bincount(flat, weights=values, minlength=n[0] * n[1])
    count = np.bincount(flat, minlength=n[0] * n[1])
    with np.errstate(invalid="ignore"):
        image = total / count
    return image.reshape(n[1], n[0])


if __name__ == "__main__":
    main()
