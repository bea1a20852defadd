#!/usr/bin/env python3
"""What a velocity field per body costs (issue 30): Guilkey & Weiss's four
disks (inputs/four_disks.yaml, implicit, and inputs/four_disks_explicit.yaml)
with their one shared field and with a frictionless contact pair between
each two neighbouring disks (four fields), whole runs under
`mpiexec -n RANKS`, the variants alternating for --repeats rounds.

Prints a table (steps, Newton iterations, median wall time of the whole
process, ratio to the shared field) and writes JSON.

    python scripts/bench_contact_pairs.py [--ranks 2] [--repeats 3] [--end-time 2e-6]
                                          [--json docs/data/bench_contact_pairs.json]
"""
import argparse
import json
import os
import statistics
import tempfile

from pimpm_runs import run_pimpm

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PAIRS = ("contact=[{bodies: [disk1, disk2], law: frictionless}, {bodies: [disk2, disk3], law: frictionless}, "
         "{bodies: [disk3, disk4], law: frictionless}]")
CASES = {"implicit (Newmark)": "four_disks.yaml", "explicit": "four_disks_explicit.yaml"}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ranks", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--end-time", type=float, default=2e-6)
    ap.add_argument("--json", default=os.path.join(ROOT, "docs", "data", "bench_contact_pairs.json"))
    args = ap.parse_args()
    table = []
    with tempfile.TemporaryDirectory() as tmp:
        for case, input_name in CASES.items():
            runs = {"one shared field": [], "a field per disk": []}
            for _ in range(args.repeats):
                for variant, extra in (("one shared field", []), ("a field per disk", [PAIRS])):
                    wall, rows = run_pimpm(os.path.join(ROOT, "inputs", input_name),
                                           [f"time.end_time={args.end_time}"] + extra, args.ranks,
                                           os.path.join(tmp, "out"))
                    runs[variant].append({"wall": wall, "steps": len(rows),
                                          "newton": sum(int(r["newton_iterations"]) for r in rows)})
            shared = statistics.median(r["wall"] for r in runs["one shared field"])
            for variant, results in runs.items():
                wall = statistics.median(r["wall"] for r in results)
                table.append(dict(results[-1], case=case, variant=variant, wall=wall,
                                  walls=[r["wall"] for r in results], ratio=wall / shared))
    print(f"four disks to t = {args.end_time:g} s, {args.ranks} ranks, median of {args.repeats} alternating "
          "whole runs")
    print("| integrator | fields | steps | Newton | wall s | / one field |")
    print("|---|---|---|---|---|---|")
    for r in table:
        print(f"| {r['case']} | {r['variant']} | {r['steps']} | {r['newton']} | {r['wall']:.1f} | {r['ratio']:.2f} |")
    os.makedirs(os.path.dirname(args.json), exist_ok=True)
    with open(args.json, "w") as f:
        json.dump({"ranks": args.ranks, "repeats": args.repeats, "end_time": args.end_time, "rows": table}, f,
                  indent=1)
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
