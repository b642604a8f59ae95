#!/usr/bin/env python3
"""The Cusick drape across lattices: does the drape coefficient converge as the
lattice approaches the fabric's thread count? (issue 27; not a test)

One fabric (default denim) on the 30 cm Cusick specimen of runs/cusick.opts, run to
rest with drape's defaults (backward Euler, self-contact) on each lattice of --grids,
as the flat specimen and as the imperfect specimens of --seeds
(-cloth_imperfection --amplitude -cloth_imperfection_seed k: a smooth out-of-plane
waviness that is a function of the material point, the same specimen on every
lattice; scripts/cusick_specimens.py says why). A flat specimen takes its folds from
the lattice's own symmetry, so its DC may jump between lattices with its fold
pattern; an imperfect specimen takes them from its waviness.

Per run: DC, folds, simulated time at rest, steps, CG iterations a step, CPU and
wall seconds (the report's), peak resident set (MB). Per lattice: the specimens'
mean DC and its distance from the finest lattice's mean (within 0.01: the issue's
test of convergence).

Output in --out (default out/cusick_lattices): lattices.csv (one row per run, written
as the runs finish), lattices.md (one row per lattice), lattices.png (DC against the
lattice spacing, one line per specimen and the mean), the runs' HDF5 (first and last
frames) in h5/.

    python3 scripts/cusick_lattices.py --grids 81,121,161 --seeds flat,1,2 --jobs 2   # about 12 min here
    python3 scripts/cusick_lattices.py --quick --out /tmp/cl                           # smoke run: seconds
"""
import argparse
import concurrent.futures
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import cusick_fabrics as cf  # noqa: E402
import drape_run  # noqa: E402
from bench_common import machine, md_table, write_csv  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
PROG = "cusick_lattices"
AMPLITUDE = 2e-4  # m rms, scripts/cusick_specimens.py's
CONVERGED = 0.01  # issue 27: DC within 0.01 of the finest lattice's
COLUMNS = ["fabric", "grid", "specimen", "status", "drape_coefficient", "drape_folds", "at_rest", "t", "steps", "cg_per_step",
           "cpu", "wall", "peak_mb"]


def specimen_args(specimen, amplitude):
    return [] if specimen == "flat" else ["-cloth_imperfection", repr(amplitude), "-cloth_imperfection_seed", specimen]


def run_one(drape, fabric, grid, specimen, amplitude, max_time, h5):
    """One run to rest; its CSV row (COLUMNS)."""
    args = cf.cusick_args(fabric, grid, "drape", max_time, h5, extra=specimen_args(specimen, amplitude))
    r = drape_run.run(drape, args, timeout=6 * 3600)
    row = {"fabric": fabric, "grid": grid, "specimen": specimen}
    rep = r.report
    if r.returncode != 0 or rep is None or rep.get("drape_coefficient") is None:
        row["status"] = r.error() or f"failed (exit {r.returncode})"
        return row
    row.update(status="ok", drape_coefficient=rep["drape_coefficient"], drape_folds=rep["drape_folds"], at_rest=rep["at_rest"],
               t=rep["t"], steps=rep["steps"], cg_per_step=rep.get("cg_per_step", 0), cpu=rep["cpu"], wall=rep["wall"],
               peak_mb=round(r.maxrss / 1e6, 1))
    return row


def summarize(rows, grids, specimens):
    """The markdown rows: one per lattice, the specimens' DC (folds), their mean and its
    distance from the finest lattice's mean."""
    ok = {(r["grid"], r["specimen"]): r for r in rows if r["status"] == "ok"}

    def mean(n):
        dcs = [ok[(n, s)]["drape_coefficient"] for s in specimens if (n, s) in ok]
        return statistics.fmean(dcs) if dcs else None
    finest = mean(grids[-1])
    table = []
    for n in grids:
        m = mean(n)
        cells = [f"{n}²", f"{0.30 / (n - 1) * 1e3:.2f}"]
        for s in specimens:
            r = ok.get((n, s))
            cells.append(f"{r['drape_coefficient']:.4f} ({r['drape_folds']})" if r else "-")
        d = abs(m - finest) if m is not None and finest is not None else None
        first = [ok[(n, s)] for s in specimens if (n, s) in ok]
        cells += [f"{m:.4f}" if m is not None else "-", f"{d:.4f}" if d is not None else "-",
                  ("yes" if d <= CONVERGED else "no") if d is not None else "-",
                  f"{statistics.fmean(r['cpu'] for r in first):.1f}" if first else "-",
                  f"{statistics.fmean(r['cg_per_step'] for r in first):.2f}" if first else "-",
                  f"{max(r['peak_mb'] for r in first):.0f}" if first else "-",
                  "all" if first and all(r["at_rest"] for r in first) else "not all"]
        table.append(cells)
    return table


def plot(rows, grids, specimens, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    ok = {(r["grid"], r["specimen"]): r for r in rows if r["status"] == "ok"}
    for s in specimens:
        pts = [(0.30 / (n - 1) * 1e3, ok[(n, s)]["drape_coefficient"]) for n in grids if (n, s) in ok]
        if pts:
            ax.plot(*zip(*pts), "o-" if s != "flat" else "s--", label="flat" if s == "flat" else f"specimen {s}")
    means = []
    for n in grids:
        dcs = [ok[(n, s)]["drape_coefficient"] for s in specimens if (n, s) in ok]
        if dcs:
            means.append((0.30 / (n - 1) * 1e3, statistics.fmean(dcs)))
    if means:
        ax.plot(*zip(*means), "k^-", lw=2, label="mean")
        ax.axhspan(means[-1][1] - CONVERGED, means[-1][1] + CONVERGED, color="0.85", label=f"finest mean ± {CONVERGED}")
    ax.set_xscale("log")
    ax.set_xticks([0.30 / (n - 1) * 1e3 for n in grids])
    ax.set_xticklabels([f"{0.30 / (n - 1) * 1e3:.2f}\n{n}²" for n in grids])
    ax.minorticks_off()
    ax.invert_xaxis()
    ax.set_xlabel("lattice spacing (mm; finer to the right)")
    ax.set_ylabel("drape coefficient")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"Cusick DC across lattices ({rows[0]['fabric']})")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--fabric", default="denim", help="-cloth_fabric")
    p.add_argument("--grids", default="81,121,161", help="lattices N (N x N on the same 30 cm specimen), coarse to fine")
    p.add_argument("--seeds", default="flat,1,2", help="specimens: flat, or -cloth_imperfection_seed values, comma-separated")
    p.add_argument("--amplitude", type=float, default=AMPLITUDE, help="-cloth_imperfection rms amplitude (m)")
    p.add_argument("--max-time", type=float, default=None, help="-ts_max_time (default: the scene's)")
    p.add_argument("--jobs", type=int, default=1, help="runs at a time (one rank each)")
    p.add_argument("--out", default=str(ROOT / "out" / "cusick_lattices"))
    p.add_argument("--build", default=None, help="build directory (default $DRAPE_BUILD or build)")
    p.add_argument("--quick", action="store_true", help="smoke run: 21^2 and 25^2, flat and specimen 1, 0.2 s (not at rest)")
    p.add_argument("--from-csv", default="", help="comma-separated lattices.csv files: the table and plot of their runs (those of --grids and --seeds), nothing run")
    a = p.parse_args()
    if a.quick:
        a.grids, a.seeds = "21,25", "flat,1"
        a.max_time = 0.2 if a.max_time is None else a.max_time
    if a.fabric not in cf.FABRICS:
        p.error(f"unknown fabric {a.fabric}: choose from {', '.join(cf.FABRICS)}")
    try:
        grids = sorted(int(n) for n in a.grids.split(",") if n)
    except ValueError:
        p.error("--grids takes integers, comma-separated")
    specimens = [s for s in a.seeds.split(",") if s]
    if not grids or min(grids) < 8 or not specimens or a.jobs < 1 or not all(s == "flat" or (s.isdigit()) for s in specimens):
        p.error("--grids takes lattices of at least 8, --seeds 'flat' or integers >= 0, --jobs at least 1")
    if not 0 < a.amplitude < 0.01:
        p.error("--amplitude is an rms waviness in m, between 0 and 0.01")
    out = Path(a.out)
    (out / "h5").mkdir(parents=True, exist_ok=True)
    drape = cf.drape_path(a.build)
    if not drape.exists():
        drape_run.fail(PROG, f"drape is not built ({drape} is missing): run 'make all' first")
    print(f"{PROG}: {a.fabric}, lattices {grids}, specimens {specimens}, imperfection {1e3 * a.amplitude:g} mm rms, "
          f"{a.jobs} at a time, {machine()}", flush=True)

    jobs = [(n, s) for n in reversed(grids) for s in specimens]  # the longest first
    rows = []
    if a.from_csv:
        import csv
        conv = {"grid": int, "drape_coefficient": float, "drape_folds": int, "at_rest": lambda v: v == "True", "t": float, "steps": int,
                "cg_per_step": float, "cpu": float, "wall": float, "peak_mb": float}
        for name in a.from_csv.split(","):
            try:
                with open(name, newline="") as f:
                    for r in csv.DictReader(f):
                        if r["status"] == "ok":
                            r.update({k: fn(r[k]) for k, fn in conv.items()})
                        else:
                            r["grid"] = int(r["grid"])
                        if r["grid"] in grids and r["specimen"] in specimens:
                            rows.append(r)
            except (OSError, KeyError, ValueError) as e:
                drape_run.fail(PROG, f"cannot read {name} as a lattices.csv: {e}")
        rows.sort(key=lambda r: (r["grid"], specimens.index(r["specimen"])))
        write_csv(out / "lattices.csv", rows, COLUMNS)
        jobs = []
    with concurrent.futures.ThreadPoolExecutor(max_workers=a.jobs) as pool:
        futures = [pool.submit(run_one, drape, a.fabric, n, s, a.amplitude, a.max_time, out / "h5" / f"{a.fabric}_{n}_{s}.h5") for n, s in jobs]
        for f in concurrent.futures.as_completed(futures):
            row = f.result()
            rows.append(row)
            rows.sort(key=lambda r: (r["grid"], specimens.index(r["specimen"])))
            write_csv(out / "lattices.csv", rows, COLUMNS)
            what = (f"DC {row['drape_coefficient']:.4f}, {row['drape_folds']} folds, {'at rest' if row['at_rest'] else 'NOT at rest'} "
                    f"at {row['t']:.2f} s, {row['cpu']:.0f} CPU s" if row["status"] == "ok" else row["status"])
            print(f"  {row['grid']:4d}² {row['specimen']:>5s}: {what}", flush=True)
    cols = ["lattice", "spacing (mm)"] + [("DC flat (folds)" if s == "flat" else f"DC specimen {s} (folds)") for s in specimens]
    cols += ["mean", f"from the {grids[-1]}² mean", f"within {CONVERGED}", "CPU s a run (time loop)", "CG a step", "peak MB", "at rest"]
    text = md_table(cols, summarize(rows, grids, specimens)) + "\n"
    (out / "lattices.md").write_text(text)
    print()
    print(text)
    if any(r["status"] == "ok" for r in rows):
        plot(rows, grids, specimens, out / "lattices.png")
    bad = [r for r in rows if r["status"] != "ok"]
    if bad:
        drape_run.fail(PROG, f"{len(bad)} run(s) failed: " + "; ".join(f"{r['grid']}² {r['specimen']}: {r['status']}" for r in bad))
    print(f"wrote {out}/lattices.csv, lattices.md, lattices.png")


if __name__ == "__main__":
    main()
