#!/usr/bin/env python3
"""Benchmark the paper's schemes: particle-steps per second and per CPU second (not a
test), the peers' hanging cloth, and how far the step is from the machine's limits.

For each lattice N x N and each scheme, drape runs the hanging cloth (two pinned
corners) for a fixed number of steps:
  symplectic Euler   -ts_type basicsymplectic at 0.5 x its stability limit (the
                     printed limit is for the unloaded sheet; tension raises
                     Omega as the cloth hangs, and 0.9 x diverges in long runs),
                     drape's model and -cloth_model paper
  explicit Euler     -ts_type euler at 0.9 x its own (damping-set) stability limit
  backward Euler     -ts_type drapebe at 10 x the symplectic limit
The limit is the one drape reports at start-up (one run with -ts_max_steps 0; the
timed explicit runs then skip the estimate, -drape_stability_its 0). The peer row is
the issue's hanging cloth of a peer benchmark (1 m, 64^2, 1333 N/m, 1e-5 N m, 0.1
kg/m^2, symplectic at 1e-4 s), in simulated seconds per CPU second. Each timed run
is repeated; the medians of drape's own report are quoted: particle_steps_per_s
(wall time of the time loop) and particle_steps_per_cpu_s (its CPU time summed over
ranks: per core). The spread between repeats is the noise the test suite allows
between README's table and the generated file. scripts/machine_limits.c measures
the machine's bandwidth and FMA peak (one core); FLOPS and BYTES below turn the
report's element counts into flops and bytes per particle-step.

    python3 scripts/bench_core.py                  # 64,128,256,512, 3 repeats: out/bench_core.{csv,md}
    python3 scripts/bench_core.py --sizes 512 --repeat 5
    python3 scripts/bench_core.py --doc docs/bench_core.md --update-docs   # make bench
    python3 scripts/bench_core.py --update-docs-only   # README/BENCHMARKS from docs/bench_core.md
    python3 scripts/bench_core.py --quick          # smoke run, tiny sizes (in the suite)

--update-docs rewrites, in README.md and BENCHMARKS.md, what lies between
"<!-- bench_core NAME begin -->" and "<!-- bench_core NAME end -->" with block NAME
of the generated file (table, detail, floors, limits).
"""
import argparse
import datetime
import os
import re
import statistics
import subprocess
import sys
from pathlib import Path

import machine_limits
from bench_common import machine, write_csv
from drape_run import ROOT, Drape, fail

PROG = "bench_core"
# (name, label, options, step as a multiple of the limit, which printed limit)
SCHEMES = [("symplectic", "symplectic Euler (0.5 x its limit)", "-ts_type basicsymplectic", 0.5, "symplectic"),
           ("symplectic_paper", "symplectic Euler, `-cloth_model paper`", "-ts_type basicsymplectic -cloth_model paper", 0.5, "symplectic"),
           ("explicit", "explicit Euler (0.9 x its limit)", "-ts_type euler", 0.9, "explicit"),
           ("beuler", "backward Euler (10 x the symplectic limit)", "-ts_type drapebe", 10.0, "symplectic")]
PEER = ("-da_grid_x 64 -da_grid_y 64 -cloth_size 1 -cloth_pin edge_corners -cloth_stretch 1333 -cloth_shear 500 -cloth_bend 1e-5 "
        "-cloth_density 0.1 -cloth_damping 0 -ts_type basicsymplectic -ts_dt 1e-4 -drape_stability_its 0 -ts_max_time 1e9")
PEER_STEPS = 5000  # 0.5 s simulated
# issue 26's floors, particle-steps per CPU second (per core) at 512^2
FLOORS = {"symplectic": 1.2e7, "symplectic_paper": 2e7}
DOCS = {"table": "README.md", "detail": "BENCHMARKS.md", "floors": "BENCHMARKS.md", "limits": "BENCHMARKS.md"}

# Work of one explicit step with drape's default force loop, the lattice kernel
# (-cloth_force_kernel lattice, src/cloth/lattice.c), counted in its kernels
# (src/cloth/kernels.h; update these with them). Flops: +, -, x, /, sqrt one each (an
# FMA two), min/max, selects and negations none:
#   stretch edge   (gradient 15, sums into two particles 6)                      21
#   shear cell     (12 edge differences, 8 dot products 40, 4 corners of 46 with
#                   KernelAsin's 30, w0..w3 12, the gradient 87, sums 12)         347
#   bending triple (coefficients 34, gradient 30, sums 9)                        73
#   particle       acceleration f/m + g - c v (12) and the updates of x and v (12)  24
# Bytes that cross the memory bus per particle-step at the least (the kernel streams
# the caller's arrays once; its rows of positions and forces stay in the cache): one
# class byte per element kind and slot (7 kinds in drape's model, 5 in the paper's)
# and the particle arrays: symplectic Euler, kick and drift fused into the sweep, reads
# and writes x and v and reads mass and pin flag (108 B); explicit Euler's sweep reads
# x, v, mass and pin flag and writes the acceleration (84), the right-hand side gets v
# (48) and TS's U += h G reads U and G and writes U (144): 276 B. Backward Euler: per
# CG iteration the SBAIJ matrix twice (product and ICC(0) solves: 7 blocks of 9
# doubles and an index a row) and 10 vectors, once more to assemble it; flops
# 4 x 13 blocks x 9 + 30 per iteration (the element Hessians are not counted: a
# lower bound).
FLOPS = {"stretch_edges": 21, "shear_cells": 347, "bending_triples": 73, "particle": 24}
BYTES_PARTICLE = {"symplectic": 108, "symplectic_paper": 108, "explicit": 276}
KINDS = {"drape": 7, "paper": 5}
SBAIJ_ROW_BYTES = 7 * (72 + 4)


def work(scheme, report, cg_per_step):
    """(bytes, flops) per particle-step of a run, from its report's element counts."""
    n = report["particles"]
    if scheme == "beuler":
        its = max(cg_per_step, 0)
        return (2 * its + 1) * SBAIJ_ROW_BYTES + 10 * 24 * its, its * (4 * 13 * 9 + 30)
    b = BYTES_PARTICLE[scheme] + KINDS.get(report.get("model"), 7)
    f = FLOPS["particle"] + sum(FLOPS[k] * report.get(k, 0) for k in ("stretch_edges", "shear_cells", "bending_triples")) / n
    return b, f


def git_commit():
    """The commit measured: HEAD's short hash, '+' if src/, include/ or the Makefile differ from it."""
    try:
        head = subprocess.run(["git", "rev-parse", "--short=10", "HEAD"], cwd=ROOT, capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "-uno", "--", "src", "include", "Makefile"], cwd=ROOT, capture_output=True, text=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("+" if dirty else "")


def g3(x):
    """3 significant digits as README writes them: 1.34e7, 0.173, 2.5e-5; '' for NaN."""
    if x != x:
        return ""
    return re.sub(r"e([-+])0*(\d)", lambda m: "e" + ("-" if m.group(1) == "-" else "") + m.group(2), f"{x:.3g}")


def spread(xs):
    return (max(xs) - min(xs)) / statistics.median(xs) if len(xs) > 1 else 0.0


def timed(drape, args, repeat):
    """Repeat a run; (reports, status)."""
    reports = []
    for _ in range(repeat):
        res = drape.run(args)
        if res.returncode or res.report is None:
            return reports, res.status()
        reports.append(res.report)
    return reports, "ok"


def block(name, text):
    return f"<!-- bench_core {name} begin -->\n{text.strip()}\n<!-- bench_core {name} end -->"


def blocks_of(text):
    """{name: content} of the bench_core blocks in a document."""
    return {m.group(1): m.group(2).strip() for m in re.finditer(r"<!-- bench_core (\w+) begin -->\n(.*?)\n?<!-- bench_core \1 end -->", text, re.S)}


def update_docs(generated, root=ROOT):
    """Rewrite the blocks of README.md and BENCHMARKS.md under root from the generated markdown."""
    blocks = blocks_of(generated)
    for doc in sorted(set(DOCS.values())):
        path = Path(root) / doc
        text = path.read_text()
        for name, target in DOCS.items():
            if target != doc:
                continue
            if name not in blocks:
                fail(PROG, f"the generated file has no block '{name}'")
            pattern = re.compile(rf"<!-- bench_core {name} begin -->\n.*?<!-- bench_core {name} end -->", re.S)
            if not pattern.search(text):
                fail(PROG, f"{path} has no '<!-- bench_core {name} begin -->' ... '<!-- bench_core {name} end -->' markers")
            text = pattern.sub(lambda _: block(name, blocks[name]), text)
        path.write_text(text)
        print(f"updated {path}")


def markdown(rows, peer, limits, meta):
    """The generated file: its header and the four blocks."""
    sizes = sorted({r["N"] for r in rows})
    cell = {(r["scheme"], r["N"]): r for r in rows}
    head = (f"Measured by `make bench` on {meta['date']} at commit {meta['commit']} ({meta['machine']}); "
            f"{'one rank' if meta['np'] == 1 else str(meta['np']) + ' ranks'}, medians of {meta['repeat']} runs; repeat spread up to {100 * meta['noise']:.1f} %.")
    lim = (f"Machine limits, one core (`scripts/machine_limits.c`, {limits['compiler']}): memory bandwidth "
           f"{limits['triad_gb_per_s']:.1f} GB/s (STREAM triad, {limits['triad_array_mb']:.0f} MB arrays), peak "
           f"{limits['peak_gflop_per_s']:.1f} GFLOP/s ({limits['fma_lanes']}-wide FMA), scalar {limits['scalar_gflop_per_s']:.1f} GFLOP/s.")

    # README: particle-steps per CPU second (per core), wall in parentheses where they differ by > 5 %
    t = [head, "", "| scheme | " + " | ".join(f"{n}²" for n in sizes) + " |", "|---|" + "---|" * len(sizes)]
    for name, label, *_ in SCHEMES:
        cells = []
        for n in sizes:
            r = cell.get((name, n))
            if r is None or r["status"] != "ok":
                cells.append(r["status"] if r else "")
                continue
            c = g3(r["cpu_rate"])
            if name == "beuler":
                c += f" ({r['cg_its_per_step']} CG its)"
            cells.append(c)
        t.append(f"| {label} | " + " | ".join(cells) + " |")
    t += ["", "Particle-steps per CPU second of the time loop, per core (drape's `particle_steps_per_cpu_s`; "
          "wall-time figures in BENCHMARKS.md)."]
    if peer:
        t += ["", f"The peers' hanging cloth (1 m, 64², 1333 N/m, 1e-5 N m, 0.1 kg/m², symplectic Euler at 1e-4 s, "
                  f"{peer['steps']} steps): {g3(peer['sim_per_cpu'])} simulated s per CPU second "
                  f"({g3(peer['cpu_rate'])} particle-steps per CPU second)."]
    t += ["", lim]

    d = [head, "", "| scheme | lattice | dt (s) | steps | particle-steps/s (wall) | per CPU s | spread | CG its/step | status |",
         "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        d.append(f"| {r['scheme']} | {r['N']}² | {r['dt']} | {r['steps']} | {g3(r['wall_rate'])} | {g3(r['cpu_rate'])} | "
                 f"{100 * r['spread']:.1f} % | {r['cg_its_per_step']} | {r['status']} |")
    if peer:
        d.append(f"| peer | 64² | 1e-4 | {peer['steps']} | {g3(peer['wall_rate'])} | {g3(peer['cpu_rate'])} | "
                 f"{100 * peer['spread']:.1f} % | | {peer['status']} |")

    f = [head, "", "| floor (issue 26), 512², per core | measured (particle-steps per CPU s) | met? |", "|---|---|---|"]
    for name, floor in FLOORS.items():
        r = cell.get((name, 512))
        label = next(lab for n_, lab, *_ in SCHEMES if n_ == name)
        if r is None or r["status"] != "ok":
            f.append(f"| {label}: {g3(floor)} | {r['status'] if r else 'not run at 512²'} | |")
        else:
            f.append(f"| {label}: {g3(floor)} | {g3(r['cpu_rate'])} | {'yes' if r['cpu_rate'] >= floor else 'no'} |")
    if peer:
        f.append(f"| the peers' hanging cloth: at least the peer's simulated s per CPU s | {g3(peer['sim_per_cpu'])} | compare by hand |")

    big = max(sizes)
    lm = [head, "", lim, "",
          f"At {big}², from each scheme's report (element counts) and the work per element of `FLOPS`, `BYTES_PARTICLE` and `KINDS` in `scripts/bench_core.py`:", "",
          "| scheme | B / particle-step | flop / particle-step | particle-steps per CPU s | GB/s (of the triad's) | GFLOP/s (of peak; of scalar) | at the nearer limit | "
          "distance |", "|---|---|---|---|---|---|---|---|"]
    for name, label, *_ in SCHEMES:
        r = cell.get((name, big))
        if r is None or r["status"] != "ok":
            continue
        bw, peak, scal = limits["triad_gb_per_s"] * 1e9, limits["peak_gflop_per_s"] * 1e9, limits["scalar_gflop_per_s"] * 1e9
        gbs, gfs = r["bytes"] * r["cpu_rate"], r["flops"] * r["cpu_rate"]
        bound = min(bw / r["bytes"], peak / r["flops"])
        which = "memory" if bw / r["bytes"] <= peak / r["flops"] else "flops"
        lm.append(f"| {label} | {r['bytes']:.0f} | {r['flops']:.0f} | {g3(r['cpu_rate'])} | {gbs / 1e9:.2f} ({100 * gbs / bw:.0f} %) | "
                  f"{gfs / 1e9:.2f} ({100 * gfs / peak:.0f} %; {100 * gfs / scal:.0f} %) | {g3(bound)} ({which}) | {bound / r['cpu_rate']:.1f} x |")
    lm += ["", "\"At the nearer limit\": the particle-steps per second the step would reach if it were bound only by the "
           "nearer of memory bandwidth (bytes / triad) and the vector FMA peak (flops / peak); \"distance\": that over the measured rate."]
    out = ["# drape core benchmark (generated by `scripts/bench_core.py`; do not edit)", "",
           "`make bench` rewrites this file and the blocks of README.md and BENCHMARKS.md between the "
           "`<!-- bench_core NAME begin/end -->` markers; tests/test_benchmarks.py checks that they agree.", ""]
    for name, text in (("table", "\n".join(t)), ("detail", "\n".join(d)), ("floors", "\n".join(f)), ("limits", "\n".join(lm))):
        out += [f"## {name}", "", block(name, text), ""]
    return "\n".join(out)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", default="64,128,256,512")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--np", type=int, default=1)
    p.add_argument("--steps", type=int, default=0, help="steps per run (0: about 2e7 particle-steps explicit, 1/20 of that implicit)")
    p.add_argument("--out", default=str(ROOT / "out" / "bench_core.csv"), help="CSV file, or a directory for bench_core.csv")
    p.add_argument("--doc", default="", help="generated markdown (default: bench_core.md beside the CSV; make bench: docs/bench_core.md)")
    p.add_argument("--update-docs", action="store_true", help="then rewrite README.md's and BENCHMARKS.md's bench_core blocks from --doc")
    p.add_argument("--update-docs-only", action="store_true", help="measure nothing: rewrite the blocks from --doc (default docs/bench_core.md)")
    p.add_argument("--build", default=os.environ.get("DRAPE_BUILD", "build"))
    p.add_argument("--quick", action="store_true", help="smoke run: sizes 16,24, 20 steps, 1 repeat, small machine-limit loops")
    a = p.parse_args()
    if a.update_docs_only:
        doc = Path(a.doc or ROOT / "docs" / "bench_core.md")
        if not doc.is_file():
            fail(PROG, f"{doc} does not exist: run 'make bench' first")
        update_docs(doc.read_text())
        return
    if a.quick:
        a.sizes, a.repeat, a.steps = "16,24", 1, 20
    out = Path(a.out)
    if out.is_dir() or not out.suffix:
        out = out / "bench_core.csv"
    doc = Path(a.doc) if a.doc else out.with_suffix(".md")
    drape = Drape(PROG, a.build, a.np)
    sizes = [int(s) for s in a.sizes.split(",")]
    meta = {"date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"), "commit": git_commit(),
            "machine": machine(), "np": a.np, "repeat": a.repeat}
    print(f"# drape core benchmark on {meta['machine']}, commit {meta['commit']}, {a.np} rank(s), median of {a.repeat}", flush=True)
    limits = machine_limits.measure(a.build, a.quick, PROG)
    print(f"  machine: triad {limits['triad_gb_per_s']:.1f} GB/s, peak {limits['peak_gflop_per_s']:.1f} GFLOP/s, "
          f"scalar {limits['scalar_gflop_per_s']:.1f} GFLOP/s (one core)", flush=True)
    rows, limit_of = [], {}
    for n in sizes:
        base = ["-da_grid_x", str(n), "-da_grid_y", str(n), "-cloth_pin", "edge_corners", "-ts_max_time", "1e9"]
        for name, _, args, factor, which in SCHEMES:
            opts = base + args.split()
            model = "-cloth_model" in args  # the schemes of one model share a start-up estimate
            if (n, model) not in limit_of:
                limit_of[n, model] = drape.limits(opts)
            limit = limit_of[n, model][which]
            dt = factor * limit
            steps = a.steps or max(20, int(2e7 // (n * n)) // (20 if name == "beuler" else 1))
            # the explicit runs skip the start-up estimate; backward Euler's solver choice depends on it
            extra = [] if name == "beuler" else ["-drape_stability_its", "0"]
            reports, status = timed(drape, opts + extra + ["-ts_dt", f"{dt:.6e}", "-ts_max_steps", str(steps)], a.repeat)
            wall = [r["particle_steps_per_s"] / a.np for r in reports]
            cpu = [r["particle_steps_per_cpu_s"] for r in reports]
            its = statistics.median([r["cg_per_step"] for r in reports]) if reports and name == "beuler" else None
            row = {"scheme": name, "N": n, "particles": n * n, "dt": f"{dt:.3e}", "steps": steps, "runs": len(reports), "status": status,
                   "wall_rate": statistics.median(wall) if wall else float("nan"), "cpu_rate": statistics.median(cpu) if cpu else float("nan"),
                   "spread": spread(cpu) if cpu else 0.0, "cg_its_per_step": f"{its:.2f}" if its is not None else ""}
            row["bytes"], row["flops"] = work(name, reports[0], its) if reports else (float("nan"), float("nan"))
            rows.append(row)
            print(f"  {name:16s} N={n:4d} dt={row['dt']} steps={steps:6d} {g3(row['wall_rate']) or status:>9s} particle-steps/s per core (wall), "
                  f"{g3(row['cpu_rate']) or status:>9s} per CPU s, spread {100 * row['spread']:.1f} %"
                  + (f", {row['cg_its_per_step']} CG its/step" if row["cg_its_per_step"] else ""), flush=True)
    peer_steps = a.steps or PEER_STEPS
    reports, status = timed(drape, PEER.split() + ["-ts_max_steps", str(peer_steps)], a.repeat)
    peer = None
    if reports:
        cpu = [r["particle_steps_per_cpu_s"] for r in reports]
        peer = {"steps": peer_steps, "status": status, "cpu_rate": statistics.median(cpu), "spread": spread(cpu),
                "wall_rate": statistics.median([r["particle_steps_per_s"] / a.np for r in reports]),
                "sim_per_cpu": statistics.median([r["t"] / r["cpu"] for r in reports if r["cpu"] > 0] or [float("nan")])}
        print(f"  peer hanging cloth 64^2: {g3(peer['sim_per_cpu'])} simulated s per CPU s ({g3(peer['cpu_rate'])} particle-steps per CPU s)")
    else:
        print(f"  peer hanging cloth 64^2: {status}")
    meta["noise"] = max([r["spread"] for r in rows] + ([peer["spread"]] if peer else []))

    out.parent.mkdir(parents=True, exist_ok=True)
    fields = ["scheme", "N", "particles", "dt", "steps", "median_particle_steps_per_s", "median_particle_steps_per_cpu_s", "spread",
              "cg_its_per_step", "bytes_per_particle_step", "flops_per_particle_step", "runs", "status"]
    csv_rows = [{"scheme": r["scheme"], "N": r["N"], "particles": r["particles"], "dt": r["dt"], "steps": r["steps"],
                 "median_particle_steps_per_s": f"{r['wall_rate']:.4g}", "median_particle_steps_per_cpu_s": f"{r['cpu_rate']:.4g}",
                 "spread": f"{r['spread']:.4f}", "cg_its_per_step": r["cg_its_per_step"], "bytes_per_particle_step": f"{r['bytes']:.0f}",
                 "flops_per_particle_step": f"{r['flops']:.0f}", "runs": r["runs"], "status": r["status"]} for r in rows]
    if peer:
        csv_rows.append({"scheme": "peer", "N": 64, "particles": 4096, "dt": "1.000e-04", "steps": peer_steps,
                         "median_particle_steps_per_s": f"{peer['wall_rate']:.4g}", "median_particle_steps_per_cpu_s": f"{peer['cpu_rate']:.4g}",
                         "spread": f"{peer['spread']:.4f}", "cg_its_per_step": "", "bytes_per_particle_step": "", "flops_per_particle_step": "",
                         "runs": a.repeat, "status": peer["status"]})
    write_csv(out, csv_rows, fields)
    text = markdown(rows, peer, limits, meta)
    doc.parent.mkdir(parents=True, exist_ok=True)
    doc.write_text(text)
    print(f"\n{blocks_of(text)['table']}\n\nwrote {out} and {doc}")
    if a.update_docs:
        update_docs(text)


if __name__ == "__main__":
    sys.exit(main())
