#!/usr/bin/env python3
"""Two ranks against one at 512^2 (issue 26; not a test): alternating runs, medians.

Each round runs every variant once, in the order given (1 rank, 2 ranks, ...), so a
change of load falls on all of them alike; --rounds rounds. A variant is
NAME:RANKS[:OPTIONS[:BUILD]] (OPTIONS a space-separated string added to the base
command; BUILD a build directory other than --build, e.g. another commit's).
The base command is drapebe's hanging cloth of BENCHMARKS.md's "Two ranks at 512^2":

    drape -da_grid_x 512 -da_grid_y 512 -cloth_pin edge_corners -ts_type drapebe
          -ts_dt 3.3e-4 -ts_max_steps 40 -drape_stability_its 0

Printed per variant: the time loop's wall time (drape's report), the CPU time of
all ranks (user + system; on two ranks MPI's busy waits count), CG iterations a
step (load-independent), each the median of the rounds with its range, and the
speed-up of the wall-time medians over the first variant's.

    python3 scripts/two_ranks.py                     # 1 and 2 ranks, 3 rounds (about 2 min quiet)
    python3 scripts/two_ranks.py --variant one:1 --variant two:2 --variant 'bj:2:-drape_pc_overlap 0'
    python3 scripts/two_ranks.py --variant new1:1 --variant new2:2 --variant old1:1::OLD/build  (OLD: another commit's tree, built)
"""
import argparse
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import machine, median  # noqa: E402
from drape_run import Drape, fail  # noqa: E402

PROG = "two_ranks"
BASE = "-da_grid_x {n} -da_grid_y {n} -cloth_pin edge_corners -ts_type drapebe -ts_dt 3.3e-4 -ts_max_steps {steps} -drape_stability_its 0"


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--variant", action="append", help="NAME:RANKS[:OPTIONS[:BUILD]] (default: one:1 and two:2)")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--size", type=int, default=512, help="lattice side N")
    p.add_argument("--steps", type=int, default=40)
    p.add_argument("--build", default=os.environ.get("DRAPE_BUILD", "build"))
    a = p.parse_args()
    variants = []
    for v in a.variant or ["one:1", "two:2"]:
        parts = v.split(":", 3)
        if len(parts) < 2 or not parts[1].isdigit() or int(parts[1]) < 1:
            fail(PROG, f"--variant takes NAME:RANKS[:OPTIONS[:BUILD]] with RANKS a positive integer, not '{v}'")
        variants.append((parts[0], int(parts[1]), parts[2].split() if len(parts) > 2 else [], parts[3] if len(parts) > 3 and parts[3] else a.build))
    base = BASE.format(n=a.size, steps=a.steps).split()
    print(f"# {PROG} on {machine()}, {a.rounds} rounds, load {os.getloadavg()[0]:.2f} at the start", flush=True)
    res = {name: [] for name, _, _, _ in variants}
    for k in range(a.rounds):
        for name, np_, opts, build in variants:
            r = Drape(PROG, build, np_).must(base + opts, f"{name} ({np_} ranks)")
            rep = r.report
            res[name].append((rep["wall"], rep["cpu"], rep["cg_per_step"]))
            print(f"round {k + 1} {name:>12} {np_} ranks: wall {rep['wall']:.2f} s, CPU {rep['cpu']:.2f} s, CG {rep['cg_per_step']:.3f} a step", flush=True)
    print(f"# load {os.getloadavg()[0]:.2f} at the end")
    print("| variant | ranks | wall (time loop) | CPU (all ranks) | CG a step | speed-up (wall medians) |")
    print("|---|---|---|---|---|---|")
    first = median([w for w, _, _ in res[variants[0][0]]])
    for name, np_, opts, build in variants:
        w, c, g = zip(*res[name])
        print(f"| {name} {' '.join(opts)}{'' if build == a.build else ' (' + build + ')'} | {np_} | {median(w):.2f} s ({min(w):.2f}-{max(w):.2f}) | {median(c):.2f} s ({min(c):.2f}-{max(c):.2f}) | {median(g):.3f} | {first / median(w):.2f} |")


if __name__ == "__main__":
    main()
