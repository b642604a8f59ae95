#!/usr/bin/env python3
"""Cost of assembling the implicit matrix, by how the summed rows reach PETSc.

drape sums the element Hessians into its own row buffer (one block row per owned
particle); -drape_mat_assembly says how the rows reach the matrix:
  csr   copied into AIJ's own value arrays (the default for AIJ; on one rank the
        buffer is AIJ's array)
  coo   MatSetPreallocationCOO once, MatSetValuesCOO per assembly (AIJ's default
        before; a map of 16 bytes per nonzero)
  rows  one MatSetValuesBlocked per block row (the default for SBAIJ, BAIJ, dense;
        PETSc 3.18 has COO for these only through MatSetValue per entry)
Every case runs the stiff hang (drapebe, h = 1e-4 s, Jacobi-preconditioned CG so
that the solve stays small) and reads the DrapeJacobian event of -log_view: the
time of one assembly (element Hessians, row buffer, hand-off, MatAssembly), max
over ranks, median of --repeat runs. --baseline BUILD adds the same runs with
another build's default assembly (e.g. a build of an older commit).

    .venv/bin/python scripts/bench_assembly.py --sizes 64,128,256 --np 1,2
    .venv/bin/python scripts/bench_assembly.py --baseline /path/to/old/build
    .venv/bin/python scripts/bench_assembly.py --quick      # smoke run (the test suite's)
"""
import argparse
import os
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import machine, md_table, median, write_csv  # noqa: E402
from drape_run import Drape, fail  # noqa: E402

PROG = "bench_assembly.py"
EVENT = re.compile(r"^(DrapeJacobian|MatSetValuesCOO|MatSetPreallCOO)\s+(\d+)\s+\S+\s+(\S+)", re.M)
CASES = [("aij", "csr"), ("aij", "coo"), ("aij", "rows"), ("sbaij", "rows"), ("sbaij", "coo")]


def events(stdout):
    """{event: (count, max time over ranks in s)} from -log_view's table."""
    return {m.group(1): (int(m.group(2)), float(m.group(3))) for m in EVENT.finditer(stdout)}


def run_once(drape, n, mat, mode, steps):
    """(s per assembly, s per MatSetValuesCOO or NaN, s of MatSetPreallocationCOO or NaN, peak RSS) of one run."""
    args = ["-options_file", "runs/hang.opts", "-da_grid_x", n, "-da_grid_y", n, "-ts_max_steps", steps, "-ts_dt", "1e-4",
            "-drape_stability_its", "0", "-pc_type", "jacobi", "-drape_mat_type", mat, "-log_view"]
    if mode != "default":
        args += ["-drape_mat_assembly", mode]
    r = drape.run(args)
    ev = events(r.stdout)
    if r.returncode or "DrapeJacobian" not in ev:
        fail(PROG, f"{mat}/{mode} at {n}^2 failed (exit {r.returncode}):\n{r.tail()}")
    nan = float("nan")
    handoff = ev["MatSetValuesCOO"][1] / ev["MatSetValuesCOO"][0] if "MatSetValuesCOO" in ev else nan
    return ev["DrapeJacobian"][1] / ev["DrapeJacobian"][0], handoff, ev.get("MatSetPreallCOO", (0, nan))[1], r.maxrss


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--build", default=os.environ.get("DRAPE_BUILD", "build"), help="drape build directory (default: $DRAPE_BUILD or build)")
    p.add_argument("--baseline", help="another build directory: its default assembly is measured too")
    p.add_argument("--sizes", default="64,128,256", help="lattice sizes N (N x N particles)")
    p.add_argument("--np", default="1,2", help="rank counts")
    p.add_argument("--steps", type=int, default=40, help="steps per run (one assembly each)")
    p.add_argument("--repeat", type=int, default=5, help="runs per case; the median is reported")
    p.add_argument("--out", default="out/bench_assembly", help="directory for bench_assembly.csv")
    p.add_argument("--quick", action="store_true", help="smoke run: 12^2, one rank, 3 steps, one run per case")
    a = p.parse_args()
    if a.quick:
        a.sizes, a.np, a.steps, a.repeat = "12", "1", 3, 1
    try:
        sizes = [int(s) for s in a.sizes.split(",")]
        nps = [int(s) for s in a.np.split(",")]
    except ValueError:
        fail(PROG, f"--sizes and --np take comma-separated integers; got {a.sizes!r}, {a.np!r}")
    if a.steps < 1 or a.repeat < 1 or min(sizes) < 4 or min(nps) < 1:
        fail(PROG, "--steps and --repeat must be at least 1, --sizes at least 4, --np at least 1")
    rows = []
    for np_ in nps:
        builds = [("this build", Drape(PROG, a.build, np_), CASES)]
        if a.baseline:
            builds.append(("baseline", Drape(PROG, a.baseline, np_), [("aij", "default"), ("sbaij", "default")]))
        for n in sizes:
            cases = [(label, d, mat, mode) for label, d, cs in builds for mat, mode in cs]
            samples = {c[0] + c[2] + c[3]: [] for c in cases}
            for _ in range(a.repeat):  # the cases interleaved: a busy machine slows them alike
                for label, d, mat, mode in cases:
                    samples[label + mat + mode].append(run_once(d, n, mat, mode, a.steps))
            for label, d, mat, mode in cases:
                t, h, s, rss = (median([x[k] for x in samples[label + mat + mode]]) for k in range(4))
                rows.append({"build": label, "np": np_, "n": n, "mat": mat, "assembly": mode, "ms_per_assembly": 1e3 * t,
                             "ms_handoff": 1e3 * h, "ms_coo_setup": 1e3 * s, "peak_rss_mb": rss / 2**20})
                print(f"  np {np_} {n}^2 {label:10s} {mat:5s} {mode:7s} {1e3 * t:8.2f} ms/assembly", flush=True)
    Path(a.out).mkdir(parents=True, exist_ok=True)
    write_csv(Path(a.out) / "bench_assembly.csv", rows)
    print(f"\n{machine()}; {a.steps} steps, median of {a.repeat} runs; DrapeJacobian per call (max over ranks)\n")
    print(md_table(["ranks", "N^2", "build", "matrix", "assembly", "ms per assembly", "of which MatSetValuesCOO", "COO set-up ms", "peak RSS MB (rank 0)"],
                   [[r["np"], r["n"], r["build"], r["mat"], r["assembly"], f"{r['ms_per_assembly']:.2f}",
                     "-" if r["ms_handoff"] != r["ms_handoff"] else f"{r['ms_handoff']:.2f}",
                     "-" if r["ms_coo_setup"] != r["ms_coo_setup"] else f"{r['ms_coo_setup']:.1f}", f"{r['peak_rss_mb']:.0f}"] for r in rows]))


if __name__ == "__main__":
    main()
