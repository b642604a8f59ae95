#!/usr/bin/env python3
"""The measured fabrics' bending tables (-cloth_bend_table) as moment laws.

drape's -cloth_bend_table gives each thread or diagonal triple the secant rigidity of
its fabric's table, B b(k), b piecewise linear through the samples at k = 0, 10, ...,
40 1/m and held at the last beyond (ARCSim's bending_stiffness): the moment is
M(k) = B b(k) k. A material's moment should not fall as it bends further (a falling
moment is a negative tangent rigidity: the strip would snap to a kink, Drucker's
stability). On a segment b = a + s k, so dM/dk = a + 2 s k, and M falls where that is
negative. This script asks drape for every fabric's table (one step on a tiny lattice,
the table as drape prints it) and reports, per row, the relative rigidities and the
curvatures where the moment falls.

    python3 scripts/bend_tables.py [--build build] [--fabrics denim,...]
"""
import argparse
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import drape_run  # noqa: E402
from cusick_fabrics import FABRICS, drape_path  # noqa: E402

LINE = re.compile(r"relative rigidity at 0, ([0-9.eE+-]+), \.\.\., ([0-9.eE+-]+) 1/m, held beyond: (.*)$", re.MULTILINE)


def table(drape, fabric):
    """(dk, {row: [b_0, b_1, ...]}) of `fabric` as drape prints it with -cloth_bend_table."""
    r = drape_run.run(drape, ["-cloth_fabric", fabric, "-cloth_bend_table", "-da_grid_x", "4", "-da_grid_y", "4", "-ts_max_steps", "1"])
    m = LINE.search(r.stdout)
    if r.returncode != 0 or not m:
        sys.exit(f"bend_tables: drape printed no bending table for {fabric} (exit {r.returncode}):\n{r.stdout}{r.stderr}")
    tokens = m.group(3).split()
    rows = {tokens[i]: [float(v) for v in tokens[i + 1].split(",")] for i in range(0, len(tokens), 2)}
    return float(m.group(1)), rows


def falling(dk, b):
    """The curvature intervals (k0, k1) within the table where M = b(k) k decreases."""
    out = []
    for i in range(len(b) - 1):
        k0, s = i * dk, (b[i + 1] - b[i]) / dk
        a = b[i] - s * k0
        # dM/dk = a + 2 s k < 0 on [k0, k0 + dk]
        lo, hi = k0, k0 + dk
        if s == 0:
            neg = (lo, hi) if a < 0 else None
        else:
            kz = -a / (2 * s)
            if s > 0:
                neg = (lo, min(hi, kz)) if kz > lo else None
            else:
                neg = (max(lo, kz), hi) if kz < hi else None
        if neg and neg[1] > neg[0] + 1e-12:
            if out and abs(out[-1][1] - neg[0]) < 1e-12:
                out[-1] = (out[-1][0], neg[1])
            else:
                out.append(neg)
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--fabrics", default=",".join(FABRICS))
    p.add_argument("--build", default=None, help="build directory (default $DRAPE_BUILD or build)")
    a = p.parse_args()
    drape = drape_path(a.build)
    if not drape.exists():
        sys.exit(f"bend_tables: error: drape is not built ({drape} is missing): run 'make all' first")
    print("| fabric | row | b at 0, 10, 20, 30, 40 1/m | moment falls at (1/m) |")
    print("|---|---|---|---|")
    nfall = nrows = 0
    for fabric in a.fabrics.split(","):
        dk, rows = table(drape, fabric)
        for name, b in rows.items():
            f = falling(dk, b)
            nrows += 1
            nfall += bool(f)
            print(f"| {fabric} | {name} | {', '.join(f'{v:.2f}' for v in b)} | {', '.join(f'{x:.1f}-{y:.1f}' for x, y in f) or '—'} |")
    print(f"\nThe moment falls somewhere in {nfall} of {nrows} rows.")


if __name__ == "__main__":
    main()
