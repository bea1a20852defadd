"""Do two processes slow each other down on this machine?

Runs a compute-bound and a memory-bound numba loop in one process, then in
two processes started together, and prints the median times (and writes
them to docs/data/core_check.json). On independent cores the two-process times
equal the one-process ones; on hyperthreads of one core (or a shared
memory bus) they grow. docs/PERFORMANCE.md uses it to tell a solver that
does not scale from a machine that cannot.

    python scripts/core_check.py
"""
import json
import os
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def worker(start_at):
    import numba

    @numba.njit
    def compute(n):
        s, x = 0.0, 1.0
        for _ in range(n):
            x = x * 1.0000001 + 1e-9
            s += x * x - s * 1e-7
        return s

    @numba.njit
    def stream(a, b, reps):
        for _ in range(reps):
            for i in range(a.size):
                b[i] = a[i] * 1.0001 + b[i]
        return b[0]

    a = np.random.default_rng(0).random(2_000_000)      # 16 MB each: beyond the caches
    b = np.zeros_like(a)
    compute(10)
    stream(a, b, 1)
    while time.time() < start_at:
        pass
    times = {"compute_ms": [], "stream_ms": []}
    for _ in range(8):
        t = time.perf_counter()
        compute(20_000_000)
        times["compute_ms"].append(1e3 * (time.perf_counter() - t))
        t = time.perf_counter()
        stream(a, b, 10)
        times["stream_ms"].append(1e3 * (time.perf_counter() - t))
    print(json.dumps({k: float(np.median(v)) for k, v in times.items()}))


def run(copies):
    start_at = time.time() + 5.0            # every copy compiles first, then they start together
    procs = [subprocess.Popen([sys.executable, __file__, "--worker", str(start_at)], stdout=subprocess.PIPE,
                              text=True) for _ in range(copies)]
    return [json.loads(p.communicate()[0]) for p in procs]


def main():
    if len(sys.argv) > 2 and sys.argv[1] == "--worker":
        worker(float(sys.argv[2]))
        return
    result = {"one": run(1), "two": run(2)}
    print("| processes | compute loop (ms) | memory loop (ms) |")
    print("|---|---|---|")
    for label, rows in result.items():
        for r in rows:
            print(f"| {label} | {r['compute_ms']:.1f} | {r['stream_ms']:.1f} |")
    path = os.path.join(ROOT, "docs", "data", "core_check.json")
    with open(path, "w") as f:
        json.dump(result, f, indent=1)
    print(f"\nwritten: {path}")


if __name__ == "__main__":
    main()
