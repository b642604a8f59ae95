#!/usr/bin/env python3
"""The backward-Euler linear solve: preconditioners, and the Blender shortcut (not a test).

Scene: the hanging cloth (1 m light cotton, two corners pinned, drape's defaults)
from rest, -ts_type drapebe at 10 x the symplectic limit drape prints at start-up
(the step of scripts/bench_core.py), one rank.

Part 1, preconditioners for CG (-ksp_type cg, rtol 1e-6: tighter than drape's
default 1e-4, so that the preconditioners' differences show) on N x N lattices, N
in --sizes (128, 256), on drape's default matrix (SBAIJ; AIJ for gamg):

  none      -pc_type none
  jacobi    -pc_type jacobi
  bjacobi   -pc_type bjacobi (drape's default: one block per rank, ICC(0))
  icc       -pc_type icc (ICC(0); on one rank the same factor as bjacobi's)
  gamg      -pc_type gamg (smoothed aggregation, PETSc's default smoother)
  hypre     -pc_type hypre -pc_hypre_type boomeramg

CG iterations per step and wall time per step (drape's report, median of
--repeat); a run that drape stops because the solve failed is recorded with the
KSP reason drape prints (e.g. DIVERGED_INDEFINITE_PC) and no time.

Part 2, the Blender shortcut: unpreconditioned CG capped at 100 iterations with
rtol 1e-2, started from zero as Blender does, accepted whatever the residual:

  -pc_type none -ksp_max_it 100 -ksp_rtol 1e-2 -ksp_initial_guess_nonzero 0 -ksp_converged_maxits

A solve that reaches -ksp_max_it is KSP_DIVERGED_ITS, whatever SNES says (so
-snes_max_linear_solve_fail alone does not help): drape rejects the step and retries
it at a quarter of the step (TSAdapt), or stops the run with -ts_max_reject 0;
-ksp_converged_maxits (KSPConvergedDefaultSetConvergedMaxits) makes reaching max_it
a convergence (KSP_CONVERGED_ITS), which drape accepts as the step. The script
checks this: the capped solve is run without the flag (retried), without it and
with -ts_max_reject 0 (stopped), and with it, and the outcomes recorded. Accuracy cost: positions after --acc-steps steps on the
--acc-size lattice against a run with the same step solved tightly (drape's PC,
rtol 1e-10): RMS and max over the particles of |x - x_ref|, relative to the 1 m
cloth (the solver's error only: the time-discretisation error is the same in
both). drape's default PC is then run with rtol loosened (1e-2 ... 1e-6), and the
loosest rtol whose max error does not exceed the shortcut's is compared with it
in time: "equal accuracy".

Output in --out (default out/solver_study): pcs.csv, shortcut.csv, flags.csv,
solver_study.md, pcs.png.

    python3 scripts/solver_study.py                  # about 10 minutes on a quiet machine
    python3 scripts/solver_study.py --quick --out /tmp/ss    # smoke run, < 30 s
"""
import argparse
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import drape_h5  # noqa: E402
from bench_common import machine, md_table, median, write_csv  # noqa: E402
from drape_run import ROOT, Drape, fail  # noqa: E402

PROG = "solver_study"
PCS = [("none", ["-pc_type", "none"]), ("jacobi", ["-pc_type", "jacobi"]), ("bjacobi", ["-pc_type", "bjacobi"]),
       ("icc", ["-pc_type", "icc"]), ("gamg", ["-pc_type", "gamg"]), ("hypre", ["-pc_type", "hypre", "-pc_hypre_type", "boomeramg"])]
# Blender's test is relative to the right-hand side only: -ksp_atol 0 keeps drape's
# absolute floor (rtol h |M g|, for a cloth near rest) out of it
BLENDER = ["-pc_type", "none", "-ksp_max_it", "100", "-ksp_rtol", "1e-2", "-ksp_atol", "0", "-ksp_initial_guess_nonzero", "0"]
ACCEPT_MAXITS = ["-ksp_converged_maxits"]
CLOTH_SIZE = 1.0


def base(n):
    return ["-da_grid_x", str(n), "-da_grid_y", str(n), "-cloth_pin", "edge_corners", "-ts_max_time", "1e9", "-ts_type", "drapebe"]


def timed(drape, args, repeat):
    """(status, median wall, summary of the last run, Result of the last run); failures are not repeated."""
    walls, r = [], None
    for _ in range(repeat):
        r = drape.run(args)
        st = r.status()
        if st != "ok":
            if st == "failed":
                fail(PROG, f"a run failed unexpectedly:\n{r.tail()}")
            return st, None, None, r
        walls.append(r.summary()[2])
    return "ok", median(walls), r.summary(), r


def part1(drape, a):
    rows = []
    for n in a.sizes:
        lim = drape.limits(base(n))
        dt = 10 * lim["symplectic"]
        steps = a.steps.get(n, max(3, int(6.5e5 // (n * n))))
        args = base(n) + ["-ts_dt", f"{dt:.6e}", "-ts_max_steps", str(steps), "-drape_stability_its", "0", "-ksp_rtol", "1e-6"]
        for name, opts in PCS:
            st, wall, s, r = timed(drape, args + opts, a.repeat)
            row = {"N": n, "particles": n * n, "dt": f"{dt:.4e}", "steps": steps, "pc": name, "status": st,
                   "cg_its_per_step": f"{s[3]:.2f}" if s else "", "s_per_step": f"{wall / s[0]:.4e}" if s else "",
                   "particle_steps_per_s": f"{n * n * s[0] / wall:.4g}" if s and wall > 0 else ""}
            rows.append(row)
            print(f"  {n:4d}^2 {name:8s} {st:24s} {row['cg_its_per_step']:>7s} its/step {row['s_per_step'] or '-':>11s} s/step", flush=True)
    for n in a.sizes:
        ref = next(r for r in rows if r["N"] == n and r["pc"] == "bjacobi")
        for r in rows:
            if r["N"] == n:
                r["speed_vs_bjacobi"] = f"{float(ref['s_per_step']) / float(r['s_per_step']):.3g}" if r["s_per_step"] and ref["s_per_step"] else ""
    return rows


def part2(drape, a, tmp):
    n, steps = a.acc_size, a.acc_steps
    lim = drape.limits(base(n))
    dt = 10 * lim["symplectic"]
    args = base(n) + ["-ts_dt", f"{dt:.6e}", "-ts_max_steps", str(steps), "-drape_stability_its", "0", "-output_interval", "1e6"]
    h5ref = Path(tmp) / "ref.h5"
    ref = drape.must(args + ["-ksp_rtol", "1e-10", "-output_file", h5ref], "the tightly solved reference run (rtol 1e-10)")
    ref_run = drape_h5.load(h5ref)
    xref, tref = ref_run.positions[-1], ref_run.time[-1]
    print(f"  {n}^2, h = {dt:.4e} s, {steps} steps to t = {tref:g} s; reference rtol 1e-10: {ref.summary()[3]:.1f} its/step", flush=True)

    # how drape reacts to a solve stopped by max_it: a cap of 5 iterations, 3 steps, three ways
    capped = ["-pc_type", "none", "-ksp_max_it", "5", "-ksp_rtol", "1e-2", "-ksp_atol", "0", "-ts_max_steps", "3"]

    def outcome(r):
        st = r.status()
        return f"ok, {r.report['steps_retried']} steps retried" if st == "ok" and r.report["steps_retried"] else st

    flags = {name: outcome(drape.run(args + capped + extra)) for name, extra in
             (("no flag", []), ("no flag, -ts_max_reject 0", ["-ts_max_reject", "0"]),
              ("-snes_max_linear_solve_fail 1000, -ts_max_reject 0", ["-snes_max_linear_solve_fail", "1000", "-ts_max_reject", "0"]),
              ("-ksp_converged_maxits", ACCEPT_MAXITS))}
    if flags["-ksp_converged_maxits"] != "ok":
        fail(PROG, f"-ksp_converged_maxits did not let drape accept a solve stopped at max_it ({flags})")
    print("  a solve stopped at -ksp_max_it 5: " + ", ".join(f"{k}: {v}" for k, v in flags.items()), flush=True)

    configs = [("Blender shortcut", BLENDER + ACCEPT_MAXITS, "")]
    configs += [(f"drape default PC, rtol {t:g}", ["-ksp_rtol", f"{t:g}"], t) for t in a.rtols]
    rows = []
    for k, (name, opts, rtol) in enumerate(configs):
        h5 = Path(tmp) / f"run{k}.h5"
        st, wall, s, r = timed(drape, args + opts, a.repeat)
        if st != "ok":
            fail(PROG, f"the run '{name}' failed ({st}):\n{r.tail()}")
        drape.must(args + opts + ["-output_file", h5], f"the run '{name}' with output")
        run = drape_h5.load(h5)
        x, t = run.positions[-1], run.time[-1]
        if abs(t - tref) > 1e-12:
            fail(PROG, f"run '{name}' ended at t = {t} s, the reference at {tref} s")
        d = np.linalg.norm(x - xref, axis=-1) / CLOTH_SIZE
        rows.append({"config": name, "options": " ".join(opts), "rtol": rtol, "N": n, "dt": f"{dt:.4e}", "steps": s[0], "T": f"{tref:.5g}",
                     "wall_s": f"{wall:.4g}", "s_per_step": f"{wall / s[0]:.4e}", "cg_its_per_step": f"{s[3]:.2f}",
                     "err_rms": f"{float(np.sqrt(np.mean(d**2))):.3e}", "err_max": f"{float(d.max()):.3e}"})
        print(f"  {name:32s} {rows[-1]['cg_its_per_step']:>7s} its/step {rows[-1]['s_per_step']} s/step "
              f"err RMS {rows[-1]['err_rms']} max {rows[-1]['err_max']}", flush=True)
    return rows, flags


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4.5))
    names = [name for name, _ in PCS]
    ns = sorted({r["N"] for r in rows})
    w = 0.8 / len(ns)
    for i, n in enumerate(ns):
        vals = [next((float(r["s_per_step"]) for r in rows if r["N"] == n and r["pc"] == p and r["s_per_step"]), 0.0) for p in names]
        bars = ax.bar(np.arange(len(names)) + i * w, vals, w, label=f"{n}²")
        for b, p in zip(bars, names):
            st = next(r["status"] for r in rows if r["N"] == n and r["pc"] == p)
            if st != "ok":
                ax.text(b.get_x() + w / 2, 0.03, st, rotation=90, ha="center", va="bottom", fontsize=7, color="red",
                        transform=ax.get_xaxis_transform())
    ax.set_xticks(np.arange(len(names)) + w * (len(ns) - 1) / 2)
    ax.set_xticklabels(names)
    ax.set_yscale("log")
    ax.set_ylabel("wall time per backward-Euler step (s)")
    ax.set_title("CG preconditioners, backward Euler at 10 x the symplectic limit")
    ax.grid(True, axis="y", which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def part1_report(rows1, a):
    md = [md_table(["lattice", "PC", "status", "CG its/step", "s/step", "speed vs bjacobi"],
                   [[f"{r['N']}²", r["pc"], r["status"], r["cg_its_per_step"], r["s_per_step"], r["speed_vs_bjacobi"]] for r in rows1])]
    best = {}
    for n in a.sizes:
        ok = [r for r in rows1 if r["N"] == n and r["s_per_step"]]
        best[n] = min(ok, key=lambda r: float(r["s_per_step"]))["pc"] if ok else "none worked"
    failed = sorted({f"{r['pc']} ({r['status']})" for r in rows1 if r["status"] != "ok"})
    md += ["", "Fastest PC per lattice: " + ", ".join(f"{n}²: {p}" for n, p in best.items()) + "."
           + (" Failed: " + ", ".join(failed) + "." if failed else ""), ""]
    return md


def report(rows1, rows2, plain_status, a):
    md = [f"# Backward-Euler linear solve (drape, {machine()}, 1 rank, medians of {a.repeat})", ""]
    if rows1:
        md += ["## CG preconditioners (rtol 1e-6), hanging cloth, h = 10 x the symplectic limit", ""]
        md += part1_report(rows1, a)
    if rows2:
        bl = rows2[0]
        md += [f"## The Blender shortcut ({rows2[0]['N']}², {rows2[0]['steps']} steps of {rows2[0]['dt']} s to t = {rows2[0]['T']} s)", "",
               "Error = |x - x_ref| at the end over the particles, relative to the 1 m cloth; x_ref: drape's PC at rtol 1e-10, same step.", "",
               md_table(["configuration", "CG its/step", "s/step", "err RMS", "err max"],
                        [[r["config"], r["cg_its_per_step"], r["s_per_step"], r["err_rms"], r["err_max"]] for r in rows2]), ""]
        for key, label in (("err_max", "max"), ("err_rms", "RMS")):
            e = float(bl[key])
            match = [r for r in rows2[1:] if float(r[key]) <= e]
            if match:
                m = max(match, key=lambda r: r["rtol"])
                f = float(bl["s_per_step"]) / float(m["s_per_step"])
                md.append(f"At equal accuracy ({label} error <= the shortcut's {e:.2e}) drape's default PC needs rtol {m['rtol']:g}: "
                          f"{m['s_per_step']} s/step against the shortcut's {bl['s_per_step']} s/step: drape is "
                          + (f"{f:.2f}x faster." if f >= 1 else f"{1 / f:.2f}x slower."))
            else:
                md.append(f"No swept rtol of drape's default PC is as inaccurate as the shortcut ({label} error {e:.2e}); the loosest one "
                          f"({rows2[1]['config']}) is more accurate and takes {rows2[1]['s_per_step']} s/step against {bl['s_per_step']}.")
        d = next((r for r in rows2 if r["rtol"] == 1e-4), None)
        if d:
            md.append(f"drape's default (rtol 1e-4) is {float(bl['err_max']) / max(float(d['err_max']), 1e-300):.3g}x more accurate than the "
                      f"shortcut (max error {d['err_max']} against {bl['err_max']}) at {d['s_per_step']} s/step.")
        md += ["", "Flags: a solve stopped by -ksp_max_it (a cap of 5 iterations, 3 steps): "
               + "; ".join(f"{k}: {v}" for k, v in plain_status.items())
               + ". drape stops on a negative KSP reason (KSP_DIVERGED_ITS at the cap) whatever SNES's failure budget; "
               "-ksp_converged_maxits makes reaching max_it KSP_CONVERGED_ITS, so the shortcut needs it.", ""]
    return "\n".join(md) + "\n"


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", default="128,256", help="lattice sides of the preconditioner table")
    p.add_argument("--steps", default="128:40,256:8", help="steps per run as N:steps pairs (others: about 6.5e5 particle-steps)")
    p.add_argument("--acc-size", type=int, default=128, help="lattice side of the shortcut accuracy study")
    p.add_argument("--acc-steps", type=int, default=60, help="steps of the shortcut accuracy study")
    p.add_argument("--rtols", default="1e-2,1e-3,1e-4,1e-5,1e-6", help="rtols of drape's default PC swept against the shortcut")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--parts", default="1,2", help="1 (preconditioners), 2 (shortcut) or 1,2")
    p.add_argument("--out", default=str(ROOT / "out" / "solver_study"))
    p.add_argument("--build", default=os.environ.get("DRAPE_BUILD", "build"))
    p.add_argument("--quick", action="store_true", help="smoke run: 16² and 24², 5 steps, shortcut on 24², 1 repeat (< 30 s)")
    a = p.parse_args()
    if a.quick:
        a.sizes, a.steps, a.acc_size, a.acc_steps, a.repeat = "16,24", "16:5,24:5", 24, 10, 1
    try:
        a.sizes = [int(s) for s in a.sizes.split(",") if s]
        a.steps = {int(k): int(v) for k, v in (kv.split(":") for kv in a.steps.split(",") if kv)}
        a.rtols = [float(t) for t in a.rtols.split(",") if t]
    except ValueError:
        fail(PROG, "--sizes, --steps (N:steps,...) and --rtols must be comma-separated numbers")
    parts = {s.strip() for s in a.parts.split(",") if s.strip()}
    if not parts or parts - {"1", "2"}:
        fail(PROG, f"--parts must be 1, 2 or 1,2, not '{a.parts}'")
    drape = Drape(PROG, a.build)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    print(f"# {PROG} on {machine()}, 1 rank, median of {a.repeat}", flush=True)
    rows1, rows2, plain = [], [], {}
    if "1" in parts:
        print("Part 1: CG preconditioners", flush=True)
        rows1 = part1(drape, a)
        write_csv(out / "pcs.csv", rows1)
        plot(rows1, out / "pcs.png")
    if "2" in parts:
        print("Part 2: the Blender shortcut", flush=True)
        with tempfile.TemporaryDirectory(prefix="ss_") as tmp:
            rows2, plain = part2(drape, a, tmp)
        write_csv(out / "shortcut.csv", rows2)
        write_csv(out / "flags.csv", [{"flags": k, "status": v} for k, v in plain.items()])
    md = report(rows1, rows2, plain, a)
    (out / "solver_study.md").write_text(md)
    print()
    print(md)
    print(f"wrote {out}/solver_study.md and the CSV and PNG files beside it")


if __name__ == "__main__":
    main()
