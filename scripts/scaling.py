#!/usr/bin/env python3
"""Scaling with the lattice: time per step, time per simulated second and memory (not a test).

The hanging cloth (1 m light cotton, two corners pinned, drape's defaults), one
rank, each scheme at the same factor of its own limit as scripts/bench_core.py:

  symplectic   -ts_type basicsymplectic at 0.5 x its printed limit
  explicit     -ts_type euler at 0.9 x its own (damping-set) printed limit
  beuler       -ts_type drapebe at 10 x the symplectic limit (drape's default solver)

on N x N lattices, N in --sizes (32..512) and, for the explicit schemes only,
--big (1024). Step counts shrink with the size (about --work particle-steps per
explicit run, 1/40 of that for backward Euler, at least 3 steps). Time per step =
drape's wall time of the time loop (its report) / steps, median of --repeat
runs; time per simulated second = time per step / h (h shrinks with the
lattice spacing, so this grows faster than the particle count).

Memory: the peak resident set (ru_maxrss of the drape process, read with
os.wait4) of each run, minus the peak of a tiny run of the same scheme (8 x 8:
the MPI, PETSc and HDF5 libraries and their buffers). Bytes per particle is the
least-squares slope of (peak - baseline) against particles over the sizes of at
least --fit-from particles (the small sizes are noise on the baseline). The
largest lattice fitting in --budget-gb (20 GB) is extrapolated as
(budget - baseline) / (bytes per particle), assuming memory stays linear in the
particle count, one rank, and nothing else resident (no output buffers: these
runs write no HDF5 frames; the start-up stability estimate's vectors included).

Output in --out (default out/scaling): scaling.csv, memory.csv, scaling.md,
scaling.png (time per step and peak memory against particles).

    python3 scripts/scaling.py                      # about 6 minutes
    python3 scripts/scaling.py --quick --out /tmp/sc    # smoke run, < 30 s
"""
import argparse
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import machine, md_table, median, write_csv  # noqa: E402
from drape_run import ROOT, Drape, fail  # noqa: E402

PROG = "scaling"
# (name, options, step as a multiple of the limit, which printed limit, explicit?)
SCHEMES = [("symplectic", ["-ts_type", "basicsymplectic"], 0.5, "symplectic", True), ("explicit", ["-ts_type", "euler"], 0.9, "explicit", True),
           ("beuler", ["-ts_type", "drapebe"], 10.0, "symplectic", False)]


def base(n):
    return ["-da_grid_x", str(n), "-da_grid_y", str(n), "-cloth_pin", "edge_corners", "-ts_max_time", "1e9"]


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", default="32,64,128,256,512", help="lattice sides N for every scheme")
    p.add_argument("--big", default="1024", help="extra lattice sides for the explicit schemes only ('' for none)")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--work", type=float, default=2e7, help="particle-steps per explicit run (backward Euler: 1/40)")
    p.add_argument("--fit-from", type=int, default=16384, help="fit bytes/particle over sizes with at least this many particles")
    p.add_argument("--budget-gb", type=float, default=20.0)
    p.add_argument("--out", default=str(ROOT / "out" / "scaling"))
    p.add_argument("--build", default=os.environ.get("DRAPE_BUILD", "build"))
    p.add_argument("--quick", action="store_true", help="smoke run: sizes 16,32 (+96 explicit, whose memory the fit needs: at 48^2 the page-level noise gave 100-410 B a particle), 1 repeat (< 30 s)")
    a = p.parse_args()
    if a.quick:
        a.sizes, a.big, a.repeat, a.work, a.fit_from = "16,32", "96", 1, 2e5, 256
    try:
        sizes = [int(s) for s in a.sizes.split(",") if s]
        big = [int(s) for s in a.big.split(",") if s]
    except ValueError:
        fail(PROG, f"--sizes and --big take comma-separated integers, not '{a.sizes}' / '{a.big}'")
    drape = Drape(PROG, a.build)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    print(f"# {PROG} on {machine()}, 1 rank, median of {a.repeat}", flush=True)

    baseline = {}
    for name, opts, factor, which, _ in SCHEMES:
        lim = drape.limits(base(8))
        r = drape.must(base(8) + opts + ["-ts_dt", repr(factor * lim[which]), "-ts_max_steps", "3"], f"the 8 x 8 baseline run of {name}")
        baseline[name] = r.maxrss
    print("  baseline peak RSS (8 x 8): " + ", ".join(f"{k} {v / 2**20:.1f} MiB" for k, v in baseline.items()), flush=True)

    rows = []
    for n in sorted(set(sizes + big)):
        lim = drape.limits(base(n))
        for name, opts, factor, which, explicit in SCHEMES:
            if n not in sizes and not explicit:
                continue
            dt = factor * lim[which]
            work = a.work if explicit else a.work / 40
            steps = int(max(3, min(20000, work // (n * n))))
            walls, rss = [], []
            for _ in range(a.repeat):
                r = drape.must(base(n) + opts + ["-ts_dt", f"{dt:.6e}", "-ts_max_steps", str(steps), "-drape_stability_its", "0"],
                               f"the {name} run at {n} x {n}")
                st, _, wall, its = r.summary()
                walls.append(wall)
                rss.append(r.maxrss)
            w = median(walls)
            row = {"scheme": name, "N": n, "particles": n * n, "dt": f"{dt:.4e}", "steps": st, "wall_s": f"{w:.4g}",
                   "s_per_step": f"{w / st:.4e}", "s_per_simulated_s": f"{w / st / dt:.4e}",
                   "particle_steps_per_s": f"{n * n * st / w:.4g}" if w > 0 else "", "cg_its_per_step": f"{its:.2f}" if its else "",
                   "peak_rss_bytes": max(rss), "rss_over_baseline_bytes": max(rss) - baseline[name],
                   "bytes_per_particle": f"{(max(rss) - baseline[name]) / (n * n):.1f}"}
            rows.append(row)
            print(f"  {name:10s} {n:5d}^2 dt={row['dt']} steps={st:6d} {row['s_per_step']} s/step {row['s_per_simulated_s']} s per simulated s, "
                  f"peak {max(rss) / 2**20:8.1f} MiB ({row['bytes_per_particle']} B/particle over baseline)", flush=True)
    write_csv(out / "scaling.csv", rows)

    mem = []
    for name, *_ in SCHEMES:
        pts = [(r["particles"], r["rss_over_baseline_bytes"]) for r in rows if r["scheme"] == name and r["particles"] >= a.fit_from]
        if len(pts) < 2:
            pts = [(r["particles"], r["rss_over_baseline_bytes"]) for r in rows if r["scheme"] == name][-2:]
        x, y = np.array(pts, dtype=float).T
        slope, icpt = np.polyfit(x, y, 1)
        nmax = (a.budget_gb * 1e9 - baseline[name]) / slope if slope > 0 else float("inf")
        mem.append({"scheme": name, "baseline_bytes": baseline[name], "bytes_per_particle": f"{slope:.1f}", "fit_intercept_bytes": f"{icpt:.4g}",
                    "fit_points": len(pts), "max_particles_in_budget": f"{nmax:.4g}", "max_lattice_side": int(np.sqrt(nmax)) if np.isfinite(nmax) else "",
                    "budget_gb": a.budget_gb})
    write_csv(out / "memory.csv", mem)
    plot(rows, out / "scaling.png")

    md = [f"# Scaling with the lattice (drape, {machine()}, 1 rank, medians of {a.repeat})", "",
          "Time per step (s) and per simulated second (s), hanging cloth; symplectic at 0.5 x, explicit Euler at 0.9 x its limit, "
          "backward Euler at 10 x the symplectic limit:", ""]
    ns = sorted({r["N"] for r in rows})
    hdr = ["scheme"] + [f"{n}²" for n in ns]
    for key, label in (("s_per_step", "s/step"), ("s_per_simulated_s", "s per simulated s"), ("particle_steps_per_s", "particle-steps/s")):
        md += [f"{label}:", "", md_table(hdr, [[name] + [next((r[key] for r in rows if r["scheme"] == name and r["N"] == n), "")
                                                           for n in ns] for name, *_ in SCHEMES]), ""]
    md += [f"Memory: peak RSS over the 8 x 8 baseline, slope fitted over sizes >= {a.fit_from} particles; largest lattice in "
           f"{a.budget_gb:g} GB = (budget - baseline) / slope (linear in particles, one rank, no output buffers):", "",
           md_table(["scheme", "baseline (MiB)", "bytes/particle", f"particles in {a.budget_gb:g} GB", "lattice"],
                    [[m["scheme"], f"{m['baseline_bytes'] / 2**20:.1f}", m["bytes_per_particle"], m["max_particles_in_budget"],
                      f"{m['max_lattice_side']}²"] for m in mem]), ""]
    text = "\n".join(md) + "\n"
    (out / "scaling.md").write_text(text)
    print()
    print(text)
    print(f"wrote {out}/scaling.csv, memory.csv, scaling.md, scaling.png")


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.5))
    for name, *_ in SCHEMES:
        mine = [r for r in rows if r["scheme"] == name]
        n = [r["particles"] for r in mine]
        a1.loglog(n, [float(r["s_per_step"]) for r in mine], "o-", label=name)
        a2.loglog(n, [r["peak_rss_bytes"] / 2**20 for r in mine], "o-", label=name)
    a1.set_xlabel("particles")
    a1.set_ylabel("wall time per step (s)")
    a2.set_xlabel("particles")
    a2.set_ylabel("peak RSS (MiB)")
    for ax in (a1, a2):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("drape: time per step and memory against lattice size (1 rank)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    main()
