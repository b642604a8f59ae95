#!/usr/bin/env python3
"""How tightly must backward Euler's linear system be solved? Error against the
true motion, not against a tight solve.

Scene: runs/hang.opts (1 m light cotton, two corners pinned) on N x N lattices, to
T = 0.5 s, frames every T/4. The reference is the true motion: RK4 at 0.5 x the
symplectic limit (its own error is far below the backward-Euler errors measured
here; scripts/work_precision.py shows RK4 references agreeing to 1e-12). For each
step h (a multiple of the symplectic limit) drape's backward Euler runs with CG
relative tolerances --rtols and with 1e-12 ("exact" linearised step). Error: max
over the particles and the frames of |x - x_ref|, relative to the 1 m cloth.

The solve's tolerance matters only where it changes this error: drape's default
(rtol 1e-4) was chosen where a tighter one changes it by less than 1 %. Each
tolerance runs twice: CG started from the last step's solution (drape's default)
and from zero (-ksp_initial_guess_nonzero 0); the test |r| < rtol |b| is the same.

Usage:
    python3 scripts/rtol_accuracy.py [--cases 64:10,64:2,128:10] [--out out/rtol_accuracy]
    python3 scripts/rtol_accuracy.py --quick
Output: rtol_accuracy.csv and rtol_accuracy.md in --out.
"""
import argparse
import os
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import drape_h5  # noqa: E402
from bench_common import machine, md_table, write_csv  # noqa: E402
from drape_run import ROOT, Drape  # noqa: E402

PROG = "rtol_accuracy"
T = 0.5


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cases", default="64:10,64:2,128:10", help="N:factor pairs: lattice side and h as a multiple of the symplectic limit")
    p.add_argument("--rtols", default="1e-2,1e-3,1e-4,1e-6", help="CG relative tolerances")
    p.add_argument("--solve-errors", default="0.1,0.5,1", help="-drape_solve_error fractions run at drape's rtol 1e-4, CG from the last step (empty: none)")
    p.add_argument("--quick", action="store_true", help="smoke run: 12 x 12, one case")
    p.add_argument("--out", default=str(ROOT / "out" / "rtol_accuracy"))
    p.add_argument("--build", default=os.environ.get("DRAPE_BUILD", "build"))
    a = p.parse_args()
    cases = [(12, 10.0)] if a.quick else [(int(c.split(":")[0]), float(c.split(":")[1])) for c in a.cases.split(",")]
    rtols = [float(t) for t in a.rtols.split(",") if t]
    etas = [float(t) for t in a.solve_errors.split(",") if t]
    drape = Drape(PROG, a.build)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    print(f"{PROG}: {machine()}", flush=True)
    with tempfile.TemporaryDirectory(prefix="rtol_") as tmp:
        for n, factor in cases:
            base = ["-options_file", "runs/hang.opts", "-da_grid_x", str(n), "-da_grid_y", str(n), "-ts_max_time", str(T),
                    "-output_interval", str(T / 4)]
            lim = drape.limits(base)["symplectic"]
            h = (T / 4) / max(1, round((T / 4) / (factor * lim)))  # frames land on the steps
            ref = Path(tmp) / "ref.h5"
            drape.must(base + ["-ts_type", "rk", "-ts_rk_type", "4", "-ts_dt", repr(0.5 * lim), "-output_file", ref], "the RK4 reference")
            xref = drape_h5.load(ref).positions[1:5]
            runs = [(1e-12, "zero", 0)] + [(t, s, 0) for t in rtols for s in ("last step", "zero")] + [(1e-4, "last step", e) for e in etas]
            for rtol, start, eta in runs:
                h5 = Path(tmp) / "be.h5"
                guess = ["-ksp_initial_guess_nonzero", "0"] if start == "zero" else []
                guess += ["-drape_solve_error", f"{eta:g}"] if eta else []
                # block IC throughout (-drape_mg_its 0): a switch to multigrid, made when CG's mean passes 25
                # iterations, would come at another step for each start and tolerance
                r = drape.must(base + ["-ts_type", "drapebe", "-ts_dt", repr(h), "-ksp_rtol", f"{rtol:g}", "-drape_mg_its", "0", "-output_file", h5] + guess,
                               f"backward Euler rtol {rtol:g}")
                steps, _, wall, its = r.summary()
                err = float(abs(drape_h5.load(h5).positions[1:5] - xref).max())
                rows.append({"case": f"{n}:{factor:g}", "N": n, "h_over_limit": f"{h / lim:.3g}", "h": f"{h:.4e}", "rtol": f"{rtol:g}", "solve_error": f"{eta:g}", "cg_start": start,
                             "cg_its_per_step": f"{its:.2f}", "wall_s": f"{wall:.3f}", "err_max": f"{err:.4e}"})
                print(f"  {n}^2 h = {h:.3e} s ({h / lim:.3g} x limit) rtol {rtol:g}, solve error {eta:g}, CG from {start}: error {err:.4e}, {its:.2f} CG its/step, {wall:.2f} s",
                      flush=True)
    write_csv(out / "rtol_accuracy.csv", rows)
    md = [f"Machine: {machine()}", ""]
    table = []
    for n, factor in cases:
        sub = [r for r in rows if r["case"] == f"{n}:{factor:g}"]
        exact = next(r for r in sub if r["rtol"] == "1e-12")
        for r in sub:
            change = float(r["err_max"]) / float(exact["err_max"]) - 1
            table.append([f"{n}²", r["h_over_limit"], r["rtol"], r["solve_error"], r["cg_start"], r["cg_its_per_step"], r["wall_s"], r["err_max"], f"{100 * change:+.2f} %"])
    md.append(md_table(["lattice", "h / limit", "rtol", "-drape_solve_error", "CG from", "CG its/step", "wall (s)", "error vs true motion", "vs rtol 1e-12"], table))
    (out / "rtol_accuracy.md").write_text("\n".join(md) + "\n")
    print(f"wrote {out / 'rtol_accuracy.csv'}, {out / 'rtol_accuracy.md'}")


if __name__ == "__main__":
    main()
