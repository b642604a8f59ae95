#!/usr/bin/env python3
"""The Cusick drape test (runs/cusick.opts: 30 cm specimen, 18 cm pedestal) for the ten
measured fabrics, to rest, at two lattice resolutions, against the radial-strip
lower bound.

The radial-strip bound. The overhang of a Cusick specimen, L = R_o - R_p (15 - 9 =
6 cm), leaves the pedestal's edge horizontally: inside the edge the specimen lies
flat, held by the sticky contact, and bending rigidity forbids a kink, so the edge
is a horizontal clamp. Cut the overhang into radial strips and let each hang on its
own: a strip of rigidity B per unit width and weight w = rho g per unit area is the
heavy elastica of scripts/elastica.py with lambda = w L^3 / B, whose tip reaches
`reach` beyond the edge (reach / L falls monotonically from 1 at lambda = 0 to
sqrt(2 / lambda) for a limp strip, which hangs straight down after a bend of length
(B / (w L))^(1/2) at the clamp, where the whole strip's weight pulls). If every strip
reached at least `reach`, the shadow would cover the disc of radius R_p + reach and

    DC = (A_shadow - A_p) / (A_o - A_p) >= ((R_p + reach)^2 - R_p^2) / (R_o^2 - R_p^2).

Why the strips of the specimen reach at least that far. Joined to its neighbours a
radial strip cannot hang as the free one does: the circle of radius r of the flat
specimen, 2 pi r long, must fit at a smaller radius when the skirt goes down, so the
hoops either compress (membrane energy, stiff) or buckle into folds, and folds bend
the fabric across the radius, which the free strips do not pay for; a fold's
curved cross-section also stiffens the radial section it runs along (a tape
measure's curved section). Every effect the hoop adds holds the skirt up; none helps
it down. And the shadow is the outer envelope of the draped specimen at each angle,
so a fold's trough, which dips inside the crests, does not shrink it. This is a
physical argument, not a theorem (issue 13 asks for the bound "that every Cusick DC
must exceed", and this script and tests/test_cusick_fabrics.py check it on drape).

Which B. The strips run in every direction phi to the warp. The sheet is inextensible
against bending (membrane rigidities of 1e1-1e3 N/m against B of 1e-5 N m), so it
bends developably, with one curvature direction at a time, and a strip along phi
bends with the directional (cylindrical) rigidity of an orthotropic sheet,

    B(phi) = Bw c^4 + Bf s^4 + (4 Bb - Bw - Bf) c^2 s^2,   c = cos phi, s = sin phi,

the three parameters being its values along the warp (Bw), the weft (Bf) and at 45
degrees (Bb): drape's model is calibrated to exactly this form (its thread and
diagonal triples sum to Bw c^4 + Bf s^4 + 3 k c^2 s^2, fixed by B(45) = Bb), and
the paper's model, thread triples only, is the same with Bb = (Bw + Bf)/4, which
drape reports as its bend_bias under -cloth_model paper. (A narrow free rod could
also twist; the developable sheet cannot, which is why the rigidity is the
cylindrical one.) reach grows with B, so the softest direction bounds every strip:
B_min = min over phi of B(phi). That is not always min(Bw, Bf, Bb): B is a quadratic
in u = c^2, convex when Bb < (Bw + Bf)/2, and then its minimum can fall between the
sampled directions, below all three (Bw = 2, Bf = Bb = 1 gives 0.875 at u = 1/4, 60
degrees; of the measured fabrics ivory-rib-knit is softest at 34 degrees, 7.17 against
its 8.1, 11.6, 7.5e-6 N m, and navy-sparkle-sweat at 37 degrees, 9.76 against 11.4,
14.9, 10.0); softest_rigidity() finds it. Taking the warp's, the mean or the largest rigidity
would overstate the reach of the softest strips and the "bound" could exceed a valid
drape. Only B_min gives a lower bound.

On the lattice. The bound is the continuum model's. drape's lattice bends a clamped
25 mm bias strip at 0.94-0.96 of Bb (a narrow strip's edges curl; BENCHMARKS.md,
"Bending on the bias"), so for a fabric whose softest direction is near the bias the
discrete strips are a few per cent softer than B_min; the margin DC - bound covers
that.

What the runs give. For each fabric and lattice (-da_grid_x = -da_grid_y = N on the
same 30 cm specimen), runs/cusick.opts to rest (-drape_rest_tol; a run that reaches
-ts_max_time first says "NO" in the at-rest column) with only the first and last
frames written; every number comes from the run's report (-drape_json): DC, folds,
at_rest, t, wall, density and the rigidities the bound uses. The resolution floor
(issue 13): DC within 0.03 between the resolutions. Differences from measured DCs
come from the model: no self-contact (folds may pass through each other), bending
linear in curvature (no stiffening at large curvature), no bending hysteresis
(friction between fibres holds real folds wider), only zero-strain rigidities.

Output in --out (default out/cusick_fabrics): cusick_fabrics.csv (one row per run,
CSV_COLUMNS), cusick_fabrics.md (one row per fabric and model, MD_COLUMNS), and
cusick_<fabric>.png (cusick_<fabric>_paper.png) of the last frame at the finest
lattice, seen from above, from render.py; the runs' HDF5 files in h5/.

Usage:
    python3 scripts/cusick_fabrics.py                         # ten fabrics, 61^2 and 81^2 (about 20 min)
    python3 scripts/cusick_fabrics.py --paper                 # and the paper's model at 61^2
    python3 scripts/cusick_fabrics.py --fabrics denim --grids 41,61,81
    python3 scripts/cusick_fabrics.py --offset 0.0005 --out out/cusick_offset   # specimen 0.5 mm off centre
    python3 scripts/cusick_fabrics.py --quick --out /tmp/cq   # smoke run: 2 fabrics, 21^2 and 25^2, 0.3 s
    import cusick_fabrics; cusick_fabrics.radial_strip_bound(0.324, 16.0e-6)
"""
import argparse
import math
import os
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import drape_run  # noqa: E402
import elastica  # noqa: E402
from bench_common import md_table, write_csv  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "runs" / "cusick.opts"
G = 9.81  # drape's default gravity (m/s^2)
FLOOR = 0.03  # issue 13: DC within 0.03 between two resolutions

# The ten measured fabrics (-cloth_fabric) and their use and fibre, from the source's README
# (Wang, Ramamoorthi & O'Brien 2011, as distributed with ARCSim; docs/model.md, "Measured fabrics").
FABRICS = {
    "denim": "jeans, 99% cotton 1% spandex",
    "polyester": "tablecloth, 100% polyester",
    "royal-target": "pants, 65% cotton 35% polyester",
    "gray-interlock": "t-shirt knit, 60% cotton 40% polyester",
    "ivory-rib-knit": "underwear knit, 95% cotton 5% spandex",
    "pink-ribbon-brown": "blanket, 100% polyester",
    "tango-red-jet-set": "jacket, 100% polyester",
    "camel-ponte-roma": "jacket knit, 60% polyester 40% rayon",
    "navy-sparkle-sweat": "sweater, 96% polyester 4% spandex",
    "white-swim-solid": "swimsuit, 87% nylon 13% spandex",
}

CSV_COLUMNS = ["fabric", "use", "model", "grid", "status", "drape_coefficient", "drape_folds", "at_rest", "t", "steps", "wall",
               "strain_max", "density", "bend_warp", "bend_weft", "bend_bias", "b_min", "b_min_angle", "lam", "reach", "bound",
               "exceeds_bound"]


def md_columns(grids):
    """Header of the markdown table for lattices `grids` (N of N x N)."""
    return (["fabric", "use", "model"] + [f"DC {n}²" for n in grids] + ["abs. difference", f"within {FLOOR}",
            "folds", "B_min 1e-6 N m (deg)", "lambda", "radial-strip bound", "DC > bound", "at rest (t s)", "wall s"])


MD_COLUMNS = md_columns((61, 81))  # the default study's


# ---------------------------------------------------------------- the bound

def directional_rigidity(phi, bw, bf, bb):
    """Cylindrical bending rigidity of an orthotropic sheet along direction phi (rad from the
    warp), from its warp, weft and 45-degree values: Bw c^4 + Bf s^4 + (4 Bb - Bw - Bf) c^2 s^2."""
    c2, s2 = math.cos(phi) ** 2, math.sin(phi) ** 2
    return bw * c2 * c2 + bf * s2 * s2 + (4 * bb - bw - bf) * c2 * s2


def softest_rigidity(bw, bf, bb):
    """(B_min, angle in degrees from the warp): the minimum over all directions of
    directional_rigidity, in closed form (a quadratic a u^2 + b u + bf in u = cos^2 phi)."""
    k = 4 * bb - bw - bf
    a, b = bw + bf - k, k - 2 * bf
    cands = [(bf, 0.0), (bw, 1.0)]  # (B, u): u = 0 is the weft, u = 1 the warp
    if a > 0:
        u = -b / (2 * a)
        if 0 < u < 1:
            cands.append((a * u * u + b * u + bf, u))
    bmin, u = min(cands)
    return bmin, math.degrees(math.acos(math.sqrt(u)))


def radial_strip_bound(density, b, r_pedestal=0.09, r_specimen=0.15, g=G):
    """Radial-strip lower bound of a Cusick test: a strip of rigidity b (N m, per unit width)
    and areal density `density` (kg/m^2) clamped horizontally at the pedestal's edge
    (radius r_pedestal, m) with the overhang r_specimen - r_pedestal as free length.

    Returns a dict: lam = w L^3 / b, reach and drop of its tip (m, from the edge),
    radius = r_pedestal + reach and dc = (radius^2 - r_p^2) / (r_o^2 - r_p^2), the
    drape coefficient below which no specimen of this rigidity can hang (module
    docstring). Pass the softest rigidity (softest_rigidity) for a bound."""
    if not (b > 0 and density > 0 and 0 < r_pedestal < r_specimen):
        raise ValueError(f"need b > 0, density > 0 and 0 < r_pedestal < r_specimen, not {b}, {density}, {r_pedestal}, {r_specimen}")
    L = r_specimen - r_pedestal
    lam = density * g * L ** 3 / b
    e = elastica.solve_tip(lam)
    radius = r_pedestal + e.reach * L
    return {"lam": lam, "reach": e.reach * L, "drop": e.drop * L, "radius": radius,
            "dc": (radius ** 2 - r_pedestal ** 2) / (r_specimen ** 2 - r_pedestal ** 2)}


def bound_from_report(report, r_pedestal):
    """The radial-strip bound of one run, from its report: density, bend_warp, bend_weft,
    bend_bias (the model's own 45-degree value) and the specimen's size (the circle
    inscribed in size_warp x size_weft)."""
    bmin, angle = softest_rigidity(report["bend_warp"], report["bend_weft"], report["bend_bias"])
    r_o = min(report["size_warp"], report["size_weft"]) / 2
    out = radial_strip_bound(report["density"], bmin, r_pedestal, r_o)
    out.update(b_min=bmin, b_min_angle=angle)
    return out


# ---------------------------------------------------------------- the runs

def scene_option(name, path=SCENE):
    """Value (str) of option -name in an options file (comments after '#'), or None."""
    tokens = []
    for line in Path(path).read_text().splitlines():
        tokens += line.split("#", 1)[0].split()
    for i, tok in enumerate(tokens):
        if tok == "-" + name and i + 1 < len(tokens):
            return tokens[i + 1]
    return None


def drape_path(build=None):
    """The drape executable of `build` (default $DRAPE_BUILD or build/)."""
    return ROOT / (build or os.environ.get("DRAPE_BUILD", "build")) / "drape"


def cusick_args(fabric, grid, model="drape", max_time=None, h5=None, offset=0.0, extra=()):
    """drape's arguments for the Cusick scene with `fabric` on a grid x grid lattice and
    `model` ("drape", "paper", or "table": drape's with -cloth_bend_table, the bending
    rigidity varying with curvature as the fabric's table), to rest or -ts_max_time
    `max_time` (default the scene's), writing only the first and last frames to `h5` if
    given; `offset` (m) moves the specimen off the pedestal's centre along the warp (a
    centring error); `extra`: more drape options, last."""
    t_max = max_time if max_time is not None else float(scene_option("ts_max_time"))
    args = ["-options_file", str(SCENE), "-cloth_fabric", fabric, "-cloth_model", "drape" if model == "table" else model,
            "-da_grid_x", str(grid), "-da_grid_y", str(grid), "-ts_max_time", repr(t_max), "-output_interval", repr(t_max)]
    if model == "table":
        args += ["-cloth_bend_table"]
    if offset:
        x, y, z = (float(v) for v in scene_option("cloth_center").split(","))
        args += ["-cloth_center", f"{x + offset!r},{y!r},{z!r}"]
    return args + (["-output_file", str(h5)] if h5 else []) + list(extra)


def row_from_result(r, fabric, grid, model="drape"):
    """A CSV row (CSV_COLUMNS) of one run's drape_run.Result: the numbers of its report and
    the radial-strip bound of its material; status 'ok', or why there is no report."""
    row = {"fabric": fabric, "use": FABRICS.get(fabric, ""), "model": model, "grid": grid}
    rep = r.report
    if r.returncode != 0 or rep is None or rep.get("drape_coefficient") is None:
        row["status"] = r.error() or ("killed (timeout)" if r.returncode < 0 else f"failed (exit {r.returncode})")
        return row
    row.update(status="ok", drape_coefficient=rep["drape_coefficient"], drape_folds=rep["drape_folds"], at_rest=rep["at_rest"],
               t=rep["t"], steps=rep["steps"], wall=rep["wall"], strain_max=rep["strain_max"], density=rep["density"],
               bend_warp=rep["bend_warp"], bend_weft=rep["bend_weft"], bend_bias=rep["bend_bias"])
    bd = bound_from_report(rep, float(scene_option("cusick_pedestal_radius")))
    row.update(b_min=bd["b_min"], b_min_angle=bd["b_min_angle"], lam=bd["lam"], reach=bd["reach"], bound=bd["dc"],
               exceeds_bound=rep["drape_coefficient"] > bd["dc"])
    return row


def run_one(drape, fabric, grid, model="drape", max_time=None, h5=None, offset=0.0, timeout=1800, extra=()):
    """One Cusick run (cusick_args); returns its CSV row (row_from_result)."""
    r = drape_run.run(drape, cusick_args(fabric, grid, model, max_time, h5, offset, extra), timeout=timeout)
    return row_from_result(r, fabric, grid, model)


def render(h5, png, dpi, elev=90.0, azim=-90.0):
    """render.py's picture of the last frame (seen from above by default); False if it failed."""
    p = subprocess.run([sys.executable, str(ROOT / "scripts" / "render.py"), str(h5), "-o", str(png), "--dpi", str(dpi),
                        "--elev", str(elev), "--azim", str(azim)], capture_output=True, text=True)
    if p.returncode != 0:
        print(f"cusick_fabrics: render.py failed on {h5}: {p.stderr.strip()}", file=sys.stderr)
    return p.returncode == 0


def summary_rows(rows, grids):
    """One markdown row per (fabric, model) from the per-run CSV rows."""
    out, verdict = [], {"floor": [], "bound": []}
    keys = list(dict.fromkeys((r["fabric"], r["model"]) for r in rows))
    for fabric, model in keys:
        runs = {r["grid"]: r for r in rows if r["fabric"] == fabric and r["model"] == model}
        ok = [runs[n] for n in grids if n in runs and runs[n]["status"] == "ok"]

        def cell(n, fmt):
            r = runs.get(n)
            if r is None:
                return "—"
            return fmt(r) if r["status"] == "ok" else f"failed: {r['status']}"

        dcs = [r["drape_coefficient"] for r in ok]
        diff = max(dcs) - min(dcs) if len(dcs) >= 2 else None
        if diff is not None:
            verdict["floor"].append(diff <= FLOOR)
        verdict["bound"] += [r["exceeds_bound"] for r in ok]
        last = ok[-1] if ok else None
        out.append([fabric, FABRICS.get(fabric, ""), model] + [cell(n, lambda r: f"{r['drape_coefficient']:.3f}") for n in grids]
                   + ["—" if diff is None else f"{diff:.3f}", "—" if diff is None else ("yes" if diff <= FLOOR else "**no**"),
                      " / ".join(cell(n, lambda r: str(r["drape_folds"])) for n in grids if n in runs),
                      "—" if last is None else f"{1e6 * last['b_min']:.2f} ({last['b_min_angle']:.0f})",
                      "—" if last is None else f"{last['lam']:.1f}",
                      "—" if last is None else f"{last['bound']:.3f}",
                      "—" if not ok else ("yes" if all(r["exceeds_bound"] for r in ok) else "**no**"),
                      " / ".join(cell(n, lambda r: f"{'yes' if r['at_rest'] else '**NO**'} ({r['t']:.2f})") for n in grids if n in runs),
                      " / ".join(cell(n, lambda r: f"{r['wall']:.1f}") for n in grids if n in runs)])
    return out, verdict


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--fabrics", default=",".join(FABRICS), help="-cloth_fabric names, comma-separated")
    p.add_argument("--grids", default="61,81", help="lattices N (N x N on the same 30 cm specimen); the first two are compared")
    p.add_argument("--paper", action="store_true", help="also run -cloth_model paper (at --paper-grids)")
    p.add_argument("--paper-grids", default=None, help="lattices for the paper's model (default: the first of --grids)")
    p.add_argument("--table", action="store_true", help="also run drape's model with -cloth_bend_table (model 'table', at --table-grids)")
    p.add_argument("--table-grids", default=None, help="lattices for -cloth_bend_table (default: the first of --grids)")
    p.add_argument("--max-time", type=float, default=None, help="-ts_max_time (default: the scene's)")
    p.add_argument("--offset", type=float, default=0.0, help="move the specimen this far (m) off the pedestal's centre, along the warp")
    p.add_argument("--out", default=None, help="output directory (default out/cusick_fabrics, out/cusick_fabrics_quick with --quick)")
    p.add_argument("--dpi", type=int, default=80, help="resolution of the pictures")
    p.add_argument("--no-pictures", action="store_true")
    p.add_argument("--build", default=None, help="build directory (default $DRAPE_BUILD or build)")
    p.add_argument("--quick", action="store_true", help="smoke run: denim and gray-interlock, 21^2 and 25^2, 0.3 s (not at rest)")
    a = p.parse_args()
    if a.quick:
        a.fabrics, a.grids, a.max_time = "denim,gray-interlock", "21,25", 0.3 if a.max_time is None else a.max_time
    fabrics = [f for f in a.fabrics.split(",") if f]
    unknown = [f for f in fabrics if f not in FABRICS]
    if unknown:
        p.error(f"unknown fabric(s) {', '.join(unknown)}: choose from {', '.join(FABRICS)}")
    grids = [int(n) for n in a.grids.split(",") if n]
    paper_grids = [int(n) for n in (a.paper_grids or str(grids[0])).split(",") if n] if a.paper else []
    table_grids = [int(n) for n in (a.table_grids or str(grids[0])).split(",") if n] if a.table else []
    out = Path(a.out or ROOT / "out" / ("cusick_fabrics_quick" if a.quick else "cusick_fabrics"))
    (out / "h5").mkdir(parents=True, exist_ok=True)
    drape = drape_path(a.build)
    if not drape.exists():
        sys.exit(f"cusick_fabrics: error: drape is not built ({drape} is missing): run 'make all' first")
    r_p = float(scene_option("cusick_pedestal_radius"))
    print(f"cusick_fabrics: {SCENE.relative_to(ROOT)}, pedestal radius {r_p} m, lattices {grids}"
          + (f", paper's model at {paper_grids}" if paper_grids else "") + (f", -cloth_bend_table at {table_grids}" if table_grids else "")
          + (f", -ts_max_time {a.max_time}" if a.max_time else "")
          + (f", specimen {1e3 * a.offset:g} mm off centre" if a.offset else ""), flush=True)
    rows = []
    for fabric in fabrics:
        for model, gs in (("drape", grids), ("paper", paper_grids), ("table", table_grids)):
            for n in gs:
                h5 = out / "h5" / f"{fabric}_{model}_{n}.h5"
                row = run_one(drape, fabric, n, model, a.max_time, h5, a.offset)
                rows.append(row)
                if row["status"] == "ok":
                    print(f"  {fabric:20s} {model:5s} {n:3d}²: DC {row['drape_coefficient']:.4f}, {row['drape_folds']} folds, bound {row['bound']:.4f}, "
                          f"{'at rest' if row['at_rest'] else 'NOT at rest'} at t = {row['t']:.2f} s, wall {row['wall']:.1f} s", flush=True)
                else:
                    print(f"  {fabric:20s} {model:5s} {n:3d}²: {row['status']}", flush=True)
            if gs and not a.no_pictures:
                h5 = out / "h5" / f"{fabric}_{model}_{max(gs)}.h5"
                png = out / (f"cusick_{fabric}.png" if model == "drape" else f"cusick_{fabric}_{model}.png")
                if h5.exists():
                    render(h5, png, a.dpi)
    write_csv(out / "cusick_fabrics.csv", rows, CSV_COLUMNS)
    all_grids = grids + [n for n in dict.fromkeys(paper_grids + table_grids) if n not in grids]
    table, verdict = summary_rows(rows, all_grids)
    text = md_table(md_columns(all_grids), table) + "\n"
    if verdict["floor"]:
        text += (f"\nResolution floor (|DC {grids[0]}² - DC {grids[1] if len(grids) > 1 else grids[0]}²| <= {FLOOR}): met for "
                 f"{sum(verdict['floor'])} of {len(verdict['floor'])}.")
    if verdict["bound"]:
        text += f"\nDC above the radial-strip bound: {sum(verdict['bound'])} of {len(verdict['bound'])} runs.\n"
    (out / "cusick_fabrics.md").write_text(text)
    print()
    print(text)
    print(f"wrote {out}/cusick_fabrics.csv, cusick_fabrics.md" + ("" if a.no_pictures else ", cusick_<fabric>.png"))


if __name__ == "__main__":
    main()
