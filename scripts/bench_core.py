#!/usr/bin/env python3
"""Benchmark the three paper schemes: particle-steps per second (not a test).

For each lattice N x N and each scheme, drape runs the hanging cloth (two pinned
corners) for a fixed number of steps:
  symplectic Euler   -ts_type basicsymplectic at 0.5 x its stability limit (the
                     printed limit is for the unloaded sheet; tension raises
                     Omega as the cloth hangs, and 0.9 x diverges in long runs)
  explicit Euler     -ts_type euler at 0.9 x its own (damping-set) stability limit
  backward Euler     -ts_type drapebe at 10 x the symplectic limit
The limit is the one drape reports at start-up. Each timed run is repeated and the
median of drape's own "particle-steps/s" (wall time of the time loop) is reported,
with CG iterations per step for backward Euler.

    python3 scripts/bench_core.py [--sizes 64,128,256] [--repeat 3] [--np 1] [--out out/bench_core.csv]
    python3 scripts/bench_core.py --quick      # smoke run, tiny sizes
"""
import argparse
import csv
import os
import statistics
from pathlib import Path

from bench_common import machine
from drape_run import ROOT, Drape

PROG = "bench_core"
# (name, options, step as a multiple of the limit, which printed limit)
SCHEMES = [("symplectic", "-ts_type basicsymplectic", 0.5, "symplectic"), ("explicit", "-ts_type euler", 0.9, "explicit"),
           ("beuler", "-ts_type drapebe", 10.0, "symplectic")]


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", default="64,128,256")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--np", type=int, default=1)
    p.add_argument("--steps", type=int, default=0, help="steps per run (0: about 2e7 particle-steps explicit, 1/20 of that implicit)")
    p.add_argument("--out", default=str(ROOT / "out" / "bench_core.csv"))
    p.add_argument("--build", default=os.environ.get("DRAPE_BUILD", "build"))
    p.add_argument("--quick", action="store_true", help="smoke run: sizes 16,24, 20 steps, 1 repeat")
    a = p.parse_args()
    if a.quick:
        a.sizes, a.repeat, a.steps = "16,24", 1, 20
    drape = Drape(PROG, a.build, a.np)
    sizes = [int(s) for s in a.sizes.split(",")]
    rows = []
    print(f"# drape core benchmark on {machine()}, {a.np} rank(s), median of {a.repeat}")
    for n in sizes:
        base = ["-da_grid_x", str(n), "-da_grid_y", str(n), "-cloth_pin", "edge_corners", "-ts_max_time", "1e9"]
        limits = drape.limits(base)
        for name, args, factor, which in SCHEMES:
            dt = factor * limits[which]
            steps = a.steps or max(20, int(2e7 // (n * n)) // (20 if name == "beuler" else 1))
            rates, its, status = [], [], "ok"
            for _ in range(a.repeat):
                res = drape.run(base + args.split() + ["-ts_dt", f"{dt:.6e}", "-ts_max_steps", str(steps)])
                if res.returncode:
                    status = res.status()
                    break
                rates.append(res.report["particle_steps_per_s"])
                its.append(res.report["cg_per_step"])
            row = {"scheme": name, "N": n, "particles": n * n, "dt": f"{dt:.3e}", "steps": steps,
                   "median_particle_steps_per_s": f"{statistics.median(rates):.4g}" if rates else "",
                   "cg_its_per_step": f"{statistics.median(its):.2f}" if its and name == "beuler" else "",
                   "runs": len(rates), "status": status}
            rows.append(row)
            print(f"  {name:10s} N={n:4d} dt={row['dt']} steps={steps:6d} {row['median_particle_steps_per_s'] or status:>10s} particle-steps/s"
                  + (f", {row['cg_its_per_step']} CG its/step" if row["cg_its_per_step"] else ""), flush=True)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    with open(a.out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print("\n| scheme | N | particles | dt (s) | steps | particle-steps/s (median) | CG its/step | status |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['scheme']} | {r['N']} | {r['particles']} | {r['dt']} | {r['steps']} | {r['median_particle_steps_per_s']} | {r['cg_its_per_step']} | {r['status']} |")
    print(f"\nwrote {a.out}")


if __name__ == "__main__":
    main()
