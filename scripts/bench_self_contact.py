#!/usr/bin/env python3
"""Cost of self-contact (-contact_self) on the sphere scene, by lattice size.

Runs runs/sphere.opts (drapebe, h = 2 ms) for --time s of simulated time (the fall,
the landing and the folding) with and without -contact_self on n x n lattices of
the same 1 m cloth, and reports the wall time of each, their ratio, the share of a
run spent in the self-contact filter (the DrapeSelfContact event of -log_view:
gathering the cloth, the broad phase, proximity and collision passes), the filter's
time per step and how often the candidate list was rebuilt. Medians of --repeat
runs, one after the other on an otherwise idle machine.

    .venv/bin/python scripts/bench_self_contact.py --sizes 41,61,81 --repeat 3
    .venv/bin/python scripts/bench_self_contact.py --quick      # smoke run (the test suite's)
"""
import argparse
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import machine, md_table, median  # noqa: E402
from drape_run import Drape, fail  # noqa: E402

PROG = "bench_self_contact.py"
EVENT = re.compile(r"^DrapeSelfContact\s+(\d+)\s+\S+\s+(\S+)", re.M)


def one(drape, n, t, self_contact):
    args = ["-options_file", "runs/sphere.opts", "-da_grid_x", n, "-da_grid_y", n, "-ts_max_time", t,
            "-contact_self", "1" if self_contact else "0", "-log_view"]
    r = drape.run(args)
    if r.returncode:
        fail(PROG, f"the run failed:\n{r.tail()}")
    m = EVENT.search(r.stdout)
    return r.report, float(m.group(2)) if m else 0.0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="41,61,81", help="lattice sizes n (n x n), comma-separated")
    ap.add_argument("--time", type=float, default=1.0, help="simulated time of each run (s)")
    ap.add_argument("--repeat", type=int, default=3, help="runs per case (medians)")
    ap.add_argument("--build", default="build")
    ap.add_argument("--quick", action="store_true", help="one 21^2 run of 0.4 s each way (a smoke test)")
    a = ap.parse_args()
    if a.quick:
        a.sizes, a.time, a.repeat = "21", 0.4, 1
    try:
        sizes = [int(s) for s in a.sizes.split(",")]
    except ValueError:
        fail(PROG, f"--sizes takes integers separated by commas; got {a.sizes!r}")
    if any(n < 3 or n > 1025 for n in sizes) or a.repeat < 1 or not 0 < a.time <= 100:
        fail(PROG, "--sizes must lie in 3..1025, --repeat be at least 1 and --time in (0, 100] s")
    drape = Drape(PROG, a.build)
    rows = []
    for n in sizes:
        off, on, share = [], [], []
        for _ in range(a.repeat):
            rep0, _ = one(drape, n, a.time, False)
            rep1, ev = one(drape, n, a.time, True)
            off.append(rep0["wall"])
            on.append(rep1["wall"])
            share.append(ev / rep1["wall"])
        steps = rep1["steps"]
        rows.append([f"{n}^2", f"{median(off):.2f}", f"{median(on):.2f}", f"{median(on) / median(off):.2f}",
                     f"{100 * median(share):.0f} %", f"{1e3 * median(share) * median(on) / steps:.2f}",
                     f"{rep1['self_broad_phases']} / {steps}", str(rep1["self_collisions"]), str(rep1["self_failsafe"])])
    print(f"# {machine()}")
    print(f"# sphere scene, {a.time:g} s simulated, medians of {a.repeat}")
    print(md_table(["lattice", "wall without (s)", "with (s)", "ratio", "filter share", "filter ms/step",
                    "candidate lists / steps", "collisions", "fail-safe"], rows))


if __name__ == "__main__":
    main()
