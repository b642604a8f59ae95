#!/usr/bin/env python3
"""The Cusick drape test as a laboratory does it: several specimens of each fabric,
and the drape coefficient as their mean (BS 5058 asks for at least two specimens,
each tested both ways up).

Why. A flat specimen on drape's lattice picks its fold pattern by the lattice's own
symmetry: the soft fabrics have several stable patterns of different DC (8 to 12
folds, spread 0.04-0.08; BENCHMARKS.md, "Cusick drape coefficients"), and a 61^2 and
an 81^2 lattice of the same fabric can pick different ones. A real specimen is never
quite flat, and its small waviness picks the pattern. Here each specimen k is the
same fabric with the initial imperfection of seed k (-cloth_imperfection A,
-cloth_imperfection_seed k: a smooth random out-of-plane displacement of rms A, a
function of the material point, so that specimen k is the same specimen on every
lattice). The resolution floor of issue 13 (DC within 0.03) is asked of the mean
over the specimens, as a laboratory's DC is a mean; the spread and each specimen's
own difference between lattices are reported beside it.

Both faces up are the same specimen in drape's model (no property tells the faces
apart), so a specimen is tested once.

Output in --out (default out/cusick_specimens): specimens.csv (one row per run,
written as the runs finish), specimens.md (one row per fabric: mean and standard
deviation of DC per lattice, folds, the floor on the means, the largest difference of
one specimen between lattices, the radial-strip bound), the runs' HDF5 files in h5/.

Usage:
    python3 scripts/cusick_specimens.py --fabrics camel-ponte-roma --seeds 1,2,3,4
    python3 scripts/cusick_specimens.py --seeds 1,2,3 --jobs 2    # ten fabrics, 61^2 and 81^2
    python3 scripts/cusick_specimens.py --quick --out /tmp/cs      # smoke run: 21^2, 25^2, 0.2 s
    python3 scripts/cusick_specimens.py --resume --fabrics polyester  # add runs to the CSV already in --out

With --resume the runs already in --out's specimens.csv (status ok, same amplitude and
lattices) are kept and not run again, and the table covers every fabric in the CSV: a
long study can be stopped and taken up again, or done a few fabrics at a time.
"""
import argparse
import concurrent.futures
import csv
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import cusick_fabrics as cf  # noqa: E402
from bench_common import md_table, write_csv  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
AMPLITUDE = 2e-4  # m, rms: a tenth of the scene's 2.5 mm gap to the pedestal, 4 % of its 5 mm spacing
CSV_COLUMNS = ["seed", "amplitude"] + cf.CSV_COLUMNS

MD_COLUMNS = ["fabric", "specimens", "DC {a}² mean ± sd", "DC {b}² mean ± sd", "difference of means", "within 0.03",
              "largest difference of one specimen", "folds {a}²", "folds {b}²", "radial-strip bound", "all above it", "all at rest"]


def read_rows(path):
    """The rows of a specimens.csv, with the types summarize() uses."""
    conv = {"seed": int, "amplitude": float, "grid": int, "drape_coefficient": float, "drape_folds": int, "t": float,
            "steps": int, "wall": float, "bound": float, "at_rest": lambda v: v == "True", "exceeds_bound": lambda v: v == "True"}
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        if r.get("status") == "ok":
            for k, fn in conv.items():
                r[k] = fn(r[k])
    return rows


def specimen_args(amplitude, seed):
    return ["-cloth_imperfection", repr(amplitude), "-cloth_imperfection_seed", str(seed)]


def summarize(rows, grids):
    """One markdown row per fabric (MD_COLUMNS) and the verdicts (floor on the means, bound)."""
    a, b = grids
    out, floor, bound = [], [], []
    for fabric in dict.fromkeys(r["fabric"] for r in rows):
        ok = [r for r in rows if r["fabric"] == fabric and r["status"] == "ok"]
        by = {n: sorted((r for r in ok if r["grid"] == n), key=lambda r: r["seed"]) for n in (a, b)}

        def stats(n):
            dcs = [r["drape_coefficient"] for r in by[n]]
            if not dcs:
                return None, "—"
            sd = statistics.stdev(dcs) if len(dcs) > 1 else 0.0
            return statistics.mean(dcs), f"{statistics.mean(dcs):.3f} ± {sd:.3f}"

        ma, ta = stats(a)
        mb, tb = stats(b)
        diff = None if ma is None or mb is None else abs(ma - mb)
        if diff is not None:
            floor.append(diff <= cf.FLOOR)
        pairs = {r["seed"]: r["drape_coefficient"] for r in by[a]}
        one = [abs(pairs[r["seed"]] - r["drape_coefficient"]) for r in by[b] if r["seed"] in pairs]
        bound += [r["exceeds_bound"] for r in ok]
        seeds = sorted({r["seed"] for r in ok})
        failed = [r for r in rows if r["fabric"] == fabric and r["status"] != "ok"]
        out.append([fabric, f"{len(seeds)}" + (f" ({len(failed)} runs failed)" if failed else ""), ta, tb,
                    "—" if diff is None else f"{diff:.3f}", "—" if diff is None else ("yes" if diff <= cf.FLOOR else "**no**"),
                    "—" if not one else f"{max(one):.3f}",
                    ", ".join(str(r["drape_folds"]) for r in by[a]), ", ".join(str(r["drape_folds"]) for r in by[b]),
                    "—" if not ok else f"{ok[0]['bound']:.3f}", "—" if not ok else ("yes" if all(r["exceeds_bound"] for r in ok) else "**no**"),
                    "—" if not ok else ("yes" if all(r["at_rest"] for r in ok) else "**no**")])
    return out, floor, bound


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--fabrics", default=",".join(cf.FABRICS), help="-cloth_fabric names, comma-separated")
    p.add_argument("--grids", default="61,81", help="two lattices N (N x N on the same 30 cm specimen)")
    p.add_argument("--seeds", default="1,2,3", help="the specimens: -cloth_imperfection_seed values, comma-separated")
    p.add_argument("--amplitude", type=float, default=AMPLITUDE, help="-cloth_imperfection rms amplitude (m); its wavelength is drape's default, a quarter of the specimen's 30 cm")
    p.add_argument("--max-time", type=float, default=None, help="-ts_max_time (default: the scene's)")
    p.add_argument("--jobs", type=int, default=1, help="runs at a time (one rank each)")
    p.add_argument("--out", default=None, help="output directory (default out/cusick_specimens)")
    p.add_argument("--build", default=None, help="build directory (default $DRAPE_BUILD or build)")
    p.add_argument("--resume", action="store_true", help="keep the runs already in --out's specimens.csv and run only the others")
    p.add_argument("--quick", action="store_true", help="smoke run: denim, 21^2 and 25^2, seeds 1,2, 0.2 s (not at rest)")
    a = p.parse_args()
    if a.quick:
        a.fabrics, a.grids, a.seeds = "denim", "21,25", "1,2"
        a.max_time = 0.2 if a.max_time is None else a.max_time
    fabrics = [f for f in a.fabrics.split(",") if f]
    unknown = [f for f in fabrics if f not in cf.FABRICS]
    if unknown:
        p.error(f"unknown fabric(s) {', '.join(unknown)}: choose from {', '.join(cf.FABRICS)}")
    try:
        grids = [int(n) for n in a.grids.split(",") if n]
        seeds = [int(s) for s in a.seeds.split(",") if s]
    except ValueError:
        p.error("--grids and --seeds take integers, comma-separated")
    if len(grids) != 2 or not seeds or min(seeds) < 0 or a.jobs < 1:
        p.error("--grids takes two lattices, --seeds one or more integers >= 0, --jobs at least 1")
    out = Path(a.out or ROOT / "out" / "cusick_specimens")
    (out / "h5").mkdir(parents=True, exist_ok=True)
    drape = cf.drape_path(a.build)
    if not drape.exists():
        sys.exit(f"cusick_specimens: error: drape is not built ({drape} is missing): run 'make all' first")
    print(f"cusick_specimens: {cf.SCENE.relative_to(ROOT)}, lattices {grids}, specimens (seeds) {seeds}, "
          f"imperfection {1e3 * a.amplitude:g} mm rms, {a.jobs} at a time", flush=True)

    def one(job):
        fabric, n, seed = job
        row = cf.run_one(drape, fabric, n, "drape", a.max_time, out / "h5" / f"{fabric}_{n}_s{seed}.h5", extra=specimen_args(a.amplitude, seed))
        row.update(seed=seed, amplitude=a.amplitude)
        return row

    rows = []
    csv_path = out / "specimens.csv"
    if a.resume and csv_path.exists():
        try:
            rows = [r for r in read_rows(csv_path) if r["status"] == "ok"]
        except (KeyError, ValueError) as e:
            sys.exit(f"cusick_specimens: error: {csv_path} is not a specimens CSV ({e}): remove it or run without --resume")
        other = {(r["amplitude"], r["grid"]) for r in rows if r["amplitude"] != a.amplitude or r["grid"] not in grids}
        if other:
            sys.exit(f"cusick_specimens: error: {csv_path} holds runs of another amplitude or lattice {sorted(other)}: "
                     f"--resume adds only runs of amplitude {a.amplitude:g} m on lattices {grids}")
    done = {(r["fabric"], r["grid"], r["seed"]) for r in rows}
    jobs = [(f, n, s) for f in fabrics for s in seeds for n in grids if (f, n, s) not in done]
    if done:
        print(f"cusick_specimens: {len(done)} runs kept from {csv_path}, {len(jobs)} to run", flush=True)
    with concurrent.futures.ThreadPoolExecutor(max_workers=a.jobs) as pool:
        for row in pool.map(one, jobs):
            rows.append(row)
            write_csv(csv_path, rows, CSV_COLUMNS)
            what = (f"DC {row['drape_coefficient']:.4f}, {row['drape_folds']} folds, {'at rest' if row['at_rest'] else 'NOT at rest'}, wall {row['wall']:.0f} s"
                    if row["status"] == "ok" else row["status"])
            print(f"  {row['fabric']:20s} {row['grid']:3d}² specimen {row['seed']}: {what}", flush=True)
    table, floor, bound = summarize(rows, grids)
    cols = [c.format(a=grids[0], b=grids[1]) for c in MD_COLUMNS]
    text = md_table(cols, table) + "\n"
    if floor:
        text += f"\nResolution floor on the specimens' mean (|difference| <= {cf.FLOOR}): met for {sum(floor)} of {len(floor)}."
    if bound:
        text += f"\nDC above the radial-strip bound: {sum(bound)} of {len(bound)} runs.\n"
    (out / "specimens.md").write_text(text)
    print()
    print(text)
    print(f"wrote {out}/specimens.csv, specimens.md")


if __name__ == "__main__":
    main()
