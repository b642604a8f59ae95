#!/usr/bin/env python3
"""Work-precision study: wall time against error for drape's integrators.

Smooth scenes without contact, every scheme swept over step sizes (or, for the
adaptive one, tolerances), each run's positions at fixed times compared with a
reference solution:

  hang    runs/hang.opts (two pinned corners, damping 1/s) on a 16 x 16 lattice
          to T = 0.5 s
  swing   a 1 m sheet released horizontal with its last weft row pinned
          (-cloth_pin edge -cloth_damping 0.1), 16 x 16, to T = 0.5 s
  rest    runs/hang.opts released hanging straight down (-cloth_orientation
          vertical) with -cloth_damping 2 -drape_rest_tol 1e-7, run until
          drape stops it at rest: error of the REST shape only (last frame), for
          symplectic and backward Euler at a few steps

Frames are written every T/4 (-output_interval); every fixed step is T/4 divided
by an integer, so frames land exactly on T/4, T/2, 3T/4, T. The error of a run is
taken over those four frames and all particles, relative to the cloth size
(1 m): err_rms = RMS of |x - x_ref|, err_max = max of |x - x_ref|.

Schemes (the fixed-step ones with -ts_dt on a geometric sweep of
--steps-per-decade sizes per decade, starting from a cap set by the stability
limits drape reports at start-up, read with -ts_max_steps 0):

  explicit Euler     -ts_type euler                        from 0.1 x the symplectic limit
  symplectic Euler   -ts_type basicsymplectic              from 0.9 x the symplectic limit
  backward Euler     -ts_type drapebe -ksp_rtol 1e-10       from 10 x the symplectic limit
  RK2                -ts_type rk -ts_rk_type 2a -ts_adapt_type none   from 0.2 x
  RK4                -ts_type rk -ts_rk_type 4 -ts_adapt_type none    from 1.4 x (2.83/Omega_max)
  RK5DP adaptive     -ts_type rk -ts_rk_type 5dp -ts_adapt_type basic -ts_rtol R -ts_atol R,
                     R swept instead of the step; it does not land on the frame
                     times, so it is run once to each of them (-ts_max_time k T/4);
                     the run to T gives the steps and wall time

Explicit Euler's printed limit (c/Omega_max^2, a few 1e-7 s) is pessimistic for
these scenes (the stiffest modes are hardly excited), so its sweep starts well
above it: a run that drape stops with its divergence message (non-zero exit) is
recorded with status 'diverged', as is any scheme's. A run that would need more
than --max-steps steps is not made (status 'skipped').

Reference: RK4 at dt_ref (1/8 of RK4's smallest swept step) and at dt_ref/2; their
difference is recorded (rows with scheme 'reference RK4', status 'ref_check') and
the script stops with an error unless it is at least --ref-margin (10) times
below the smallest error it reports. For 'rest' the references are RK4 runs to
rest at -drape_rest_tol 1e-12 (steps 0.5 and 0.25 x the symplectic limit).

Wall time is drape's own, the "wall" of its report (the time loop only, as in
its "Summary:" line). Runs are made one at a time (--jobs 1) so they do not
compete for cores.

Output in --out (default out/work_precision):
  work_precision.csv    scene, scheme, dt, tol, steps, wall_s, err_rms, err_max, status
  wp_<scene>.png        err_max against wall time, log-log, one line per scheme
  fastest.md            per scene, the fastest run reaching err_max <= 1e-2, 1e-3, 1e-4

Reproduce (about 3-4 minutes on 2 cores):

    .venv/bin/python scripts/work_precision.py
    .venv/bin/python scripts/work_precision.py --quick --out /tmp/wp   # 8 x 8, T = 0.1 s, < 30 s
    .venv/bin/python scripts/work_precision.py --np 2                  # mpiexec -np 2
"""
import argparse
import csv
import itertools
import math
import os
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

import drape_h5
import drape_run
from drape_run import ROOT, fail

PROG = "work_precision"
TARGETS = (1e-2, 1e-3, 1e-4)
CLOTH_SIZE = 1.0  # m, every scene here: errors are relative to it
FIELDS = ["scene", "scheme", "dt", "tol", "steps", "wall_s", "err_rms", "err_max", "status"]

RK = ["-ts_type", "rk", "-ts_adapt_type", "none", "-ts_rk_type"]
# name, options, order, first step as a multiple of the symplectic limit, decades swept
FIXED = [
    ("explicit Euler", ["-ts_type", "euler"], 1, 0.1, 2.0),
    ("symplectic Euler", ["-ts_type", "basicsymplectic"], 1, 0.9, 2.0),
    ("backward Euler", ["-ts_type", "drapebe", "-ksp_rtol", "1e-10"], 1, 10.0, 2.0),
    ("RK2", RK + ["2a"], 2, 0.2, 2.0),
    ("RK4", RK + ["4"], 4, 1.4, 1.0),
]
ADAPTIVE = ("RK5DP adaptive", ["-ts_type", "rk", "-ts_rk_type", "5dp", "-ts_adapt_type", "basic"])
REF = ("reference RK4", RK + ["4"])
FIRST_ORDER = [name for name, _, order, _, _ in FIXED if order == 1]
SCHEMES = [name for name, *_ in FIXED] + [ADAPTIVE[0]]


class StudyError(Exception):
    pass


class Drape(drape_run.Drape):
    """drape_run.Drape whose runs write their frames to numbered files in a temporary directory."""

    def __init__(self, build, np_, tmpdir):
        super().__init__(PROG, build, np_)
        self.tmp, self.count = Path(tmpdir), itertools.count(1)

    def run_frames(self, args):
        """Run drape writing its frames; returns (Result, HDF5 path)."""
        h5 = self.tmp / f"run{next(self.count)}.h5"
        return self.run(args + ["-output_file", h5], timeout=None), h5


def summary(r):
    """(steps, simulated time, wall s of the time loop) of a completed run."""
    if r.report is None:
        raise StudyError(f"no report (-drape_json) in the output of\n{r.tail()}")
    return r.summary()[:3]


def frames(h5, times, tol):
    """Positions [len(times), My, Mx, 3] at the given times (each must be a frame)."""
    run = drape_h5.load(h5)
    ks = [run.frame_at(t, tol) for t in times]
    for t, k in zip(times, ks):
        if k is None:
            raise StudyError(f"{h5}: no frame at t = {t:g} s (frames at {np.array2string(run.time, precision=6)})")
    return run.positions[ks]


def errors(x, ref):
    d = np.linalg.norm(x - ref, axis=-1) / CLOTH_SIZE
    return float(np.sqrt(np.mean(d**2))), float(np.max(d))


def sweep(first, decades, spd, interval):
    """Geometric steps from `first` down `decades` decades, each interval/integer."""
    out = []
    for k in range(int(round(decades * spd)) + 1):
        n = max(1, math.ceil(interval / (first * 10 ** (-k / spd)) - 1e-9))
        dt = interval / n
        if not out or dt < out[-1] * (1 - 1e-9):
            out.append(dt)
    return out


def row(scene, scheme, dt=None, tol=None, steps=None, wall=None, err=None, status="ok"):
    return {"scene": scene, "scheme": scheme, "dt": "" if dt is None else f"{dt:.6e}", "tol": "" if tol is None else f"{tol:.1e}",
            "steps": "" if steps is None else steps, "wall_s": "" if wall is None else f"{wall:.3f}",
            "err_rms": "" if err is None else f"{err[0]:.4e}", "err_max": "" if err is None else f"{err[1]:.4e}", "status": status}


def show(r):
    p = f"dt={r['dt']}" if r["dt"] else f"tol={r['tol']}"
    e = f"err_rms={r['err_rms']} err_max={r['err_max']}" if r["err_max"] else ""
    print(f"  {r['scene']:6s} {r['scheme']:17s} {p:16s} steps={str(r['steps']):>7s} wall={r['wall_s'] or '-':>7s}s {e} [{r['status']}]", flush=True)


def check_reference(scene, refrow, rows, margin):
    ok = [float(r["err_max"]) for r in rows if r["scene"] == scene and r["status"] == "ok" and r["err_max"]]
    diff = float(refrow["err_max"])
    print(f"  {scene}: references dt_ref={refrow['dt']} and dt_ref/2 differ by {diff:.3e} (max), "
          f"smallest reported error {min(ok) if ok else float('nan'):.3e}", flush=True)
    if ok and not diff * margin <= min(ok):
        raise StudyError(f"scene {scene}: the reference is not accurate enough: its two runs (dt_ref = {refrow['dt']} s and half) "
                         f"differ by {diff:.3e}, not {margin:g} times below the smallest error reported ({min(ok):.3e}); "
                         f"lower the reference step or drop the finest sweep sizes")


def timed_scene(drape, scene, base, T, spd, a, pool):
    """hang / swing: every scheme against an RK4 reference at 4 frames."""
    interval = T / 4
    base = base + ["-ts_max_time", repr(T), "-output_interval", repr(interval)]
    times = [interval * k for k in range(1, 5)]
    lim = drape.limits(base)
    print(f"{scene}: symplectic limit {lim['symplectic']:.4e} s, explicit Euler limit {lim['explicit']:.4e} s", flush=True)
    ftol = 1e-6 * interval

    # reference: RK4 at dt_ref and dt_ref/2
    rk4 = next(f for f in FIXED if f[0] == "RK4")
    rk4_min = sweep(rk4[3] * lim["symplectic"], 1.0 if a.quick else rk4[4], spd, interval)[-1]
    dt_ref = interval / math.ceil(interval / (rk4_min / 8) - 1e-9)
    refs = []
    for dt in (dt_ref, dt_ref / 2):
        r, h5 = drape.run_frames(base + REF[1] + ["-ts_dt", repr(dt)])
        if r.returncode:
            fail(PROG, f"the reference run failed:\n{r.tail()}")
        refs.append((summary(r), frames(h5, times, ftol)))
        h5.unlink()
    xref = refs[1][1]
    refrow = row(scene, REF[0], dt=dt_ref, steps=refs[0][0][0], wall=refs[0][0][2], err=errors(refs[0][1], xref), status="ref_check")

    def fixed(job):
        name, opts, dt = job
        steps = round(T / dt)
        if steps > a.max_steps:
            return row(scene, name, dt=dt, steps=steps, status="skipped")
        r, h5 = drape.run_frames(base + opts + ["-ts_dt", repr(dt)])
        st = r.status()
        if st != "ok":
            if st == "failed":
                print(f"warning: a run failed:\n{r.tail(2000)}", file=sys.stderr)
            h5.unlink(missing_ok=True)
            return row(scene, name, dt=dt, status=st)
        n, _, wall = summary(r)
        err = errors(frames(h5, times, ftol), xref)
        h5.unlink()
        return row(scene, name, dt=dt, steps=n, wall=wall, err=err)

    def adaptive(tol):
        xs, n, wall = [], None, None
        for k, t in enumerate(times):
            opts = base + ADAPTIVE[1] + ["-ts_rtol", repr(tol), "-ts_atol", repr(tol), "-ts_max_time", repr(t),
                                         "-output_interval", repr(10 * T), "-ts_dt", repr(lim["symplectic"] / 10)]
            r, h5 = drape.run_frames(opts)
            st = r.status()
            if st != "ok":
                h5.unlink(missing_ok=True)
                return row(scene, ADAPTIVE[0], tol=tol, status=st)
            xs.append(frames(h5, [t], ftol)[0])
            h5.unlink()
            if k == len(times) - 1:
                n, _, wall = summary(r)
        return row(scene, ADAPTIVE[0], tol=tol, steps=n, wall=wall, err=errors(np.array(xs), xref))

    jobs = [(name, opts, dt) for name, opts, _, first, dec in FIXED
            for dt in sweep(first * lim["symplectic"], 1.0 if a.quick else dec, spd, interval)]
    rows = list(pool.map(fixed, jobs))
    tols = [10 ** (-a.tol_range[0] - k / spd) for k in range(int(round((a.tol_range[1] - a.tol_range[0]) * spd)) + 1)]
    rows += list(pool.map(adaptive, tols))
    for r in rows:
        show(r)
    show(refrow)
    return rows, refrow


def rest_scene(drape, base, a, pool):
    """Error of the rest shape (last frame) for symplectic and backward Euler."""
    base = base + ["-output_interval", "1e6"]  # first and last frames only
    lim = drape.limits(base)
    tmax = float(base[base.index("-ts_max_time") + 1])
    print(f"rest: symplectic limit {lim['symplectic']:.4e} s", flush=True)

    def last(h5):
        run = drape_h5.load(h5)
        return run.positions[-1], run.time[-1]

    refs = []
    for dt in (0.5 * lim["symplectic"], 0.25 * lim["symplectic"]):
        r, h5 = drape.run_frames(base + REF[1] + ["-ts_dt", repr(dt), "-drape_rest_tol", "1e-12"])
        if r.returncode:
            fail(PROG, f"the rest reference run failed:\n{r.tail()}")
        x, t = last(h5)
        h5.unlink()
        if t >= tmax * (1 - 1e-9):
            fail(PROG, f"the rest reference did not come to rest by t = {tmax:g} s:\n  {r.cmd}")
        refs.append((summary(r), x, dt))
    xref = refs[1][1]
    refrow = row("rest", REF[0], dt=refs[0][2], steps=refs[0][0][0], wall=refs[0][0][2], err=errors(refs[0][1], xref), status="ref_check")

    def one(job):
        name, opts, dt = job
        r, h5 = drape.run_frames(base + opts + ["-ts_dt", repr(dt)])
        st = r.status()
        if st != "ok":
            h5.unlink(missing_ok=True)
            return row("rest", name, dt=dt, status=st)
        n, t, wall = summary(r)
        x, _ = last(h5)
        h5.unlink()
        if t >= tmax * (1 - 1e-9):
            return row("rest", name, dt=dt, steps=n, wall=wall, status="not at rest")
        return row("rest", name, dt=dt, steps=n, wall=wall, err=errors(x, xref))

    symp = next(f for f in FIXED if f[0] == "symplectic Euler")
    beul = next(f for f in FIXED if f[0] == "backward Euler")
    jobs = [(symp[0], symp[1], f * lim["symplectic"]) for f in a.rest_symplectic]
    jobs += [(beul[0], beul[1], f * lim["symplectic"]) for f in a.rest_beuler]
    rows = list(pool.map(one, jobs))
    for r in rows:
        show(r)
    show(refrow)
    return rows, refrow


def plot(rows, scene, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 5))
    markers = "os^vD*P"
    for i, name in enumerate(SCHEMES):
        mine = sorted((r for r in rows if r["scene"] == scene and r["scheme"] == name and r["status"] == "ok"),
                      key=lambda r: -float(r["dt"] or r["tol"]))  # joined in sweep order: coarse to fine
        pts = [(max(float(r["wall_s"]), 1e-3), float(r["err_max"])) for r in mine]
        if pts:
            ax.loglog(*zip(*pts), marker=markers[i % len(markers)], label=name)
    for t in TARGETS:
        ax.axhline(t, color="0.8", lw=0.8, zorder=0)
    ax.set_xlabel("wall time of the time loop (s; drape's Summary, floor 1 ms)")
    ax.set_ylabel("max error / cloth size over the frames")
    ax.set_title(f"drape work-precision: {scene}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def fastest(rows, scenes, refrows):
    lines = ["| scene | target err_max | fastest scheme | dt (s) / tol | steps | wall (s) | err_max |", "|---|---|---|---|---|---|---|"]
    for scene in scenes:
        ok = [r for r in rows if r["scene"] == scene and r["status"] == "ok" and r["err_max"]]
        for t in TARGETS:
            hit = [r for r in ok if float(r["err_max"]) <= t]
            if hit:
                b = min(hit, key=lambda r: (float(r["wall_s"]), float(r["err_max"])))
                lines.append(f"| {scene} | {t:.0e} | {b['scheme']} | {b['dt'] or 'tol ' + b['tol']} | {b['steps']} | {b['wall_s']} | {b['err_max']} |")
            else:
                lines.append(f"| {scene} | {t:.0e} | none reached | | | | |")
    lines.append("")
    lines.append("Reference check (RK4 at dt_ref against dt_ref/2, max over frames and particles):")
    lines.append("")
    for r in refrows:
        lines.append(f"- {r['scene']}: dt_ref = {r['dt']} s, difference {r['err_max']} (RMS {r['err_rms']})")
    return "\n".join(lines) + "\n"


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", default=str(ROOT / "out" / "work_precision"), help="output directory")
    p.add_argument("--quick", action="store_true", help="8 x 8 lattice, T = 0.1 s, 2 sizes per scheme (one decade apart), 2 runs at once: for the tests, < 30 s")
    p.add_argument("--np", type=int, default=1, help="MPI ranks per drape run (mpiexec --oversubscribe -np K)")
    p.add_argument("--steps-per-decade", type=int, default=None, help="sizes per decade of the step sweep (default 2; quick 1)")
    p.add_argument("--grid", type=int, default=None, help="lattice N x N (default 16; quick 8)")
    p.add_argument("--time", type=float, default=None, help="end time T of hang and swing, s (default 0.5; quick 0.1)")
    p.add_argument("--max-steps", type=int, default=300000, help="runs needing more steps are skipped (default 300000)")
    p.add_argument("--jobs", type=int, default=None, help="drape runs at once (default 1: wall times undisturbed; quick 2)")
    p.add_argument("--scenes", default="hang,swing,rest", help="comma-separated subset of hang,swing,rest")
    p.add_argument("--ref-margin", type=float, default=10.0, help="reference difference must be this many times below the smallest error")
    p.add_argument("--build", default=os.environ.get("DRAPE_BUILD", "build"))
    a = p.parse_args()
    spd = a.steps_per_decade or (1 if a.quick else 2)
    N = a.grid or (8 if a.quick else 16)
    T = a.time or (0.1 if a.quick else 0.5)
    a.tol_range = (3, 4) if a.quick else (2, 8)  # adaptive tolerances 10^-3..10^-4 / 10^-2..10^-8
    if a.jobs is None:
        a.jobs = 2 if a.quick else 1
    a.rest_symplectic = [0.5, 0.25] if a.quick else [0.9, 0.5, 0.25]
    a.rest_beuler = [10.0, 2.5] if a.quick else [20.0, 10.0, 5.0, 2.0]
    if spd < 1:
        fail(PROG, "--steps-per-decade must be at least 1")
    scenes = [s for s in a.scenes.split(",") if s]
    for s in scenes:
        if s not in ("hang", "swing", "rest"):
            fail(PROG, f"unknown scene '{s}' (choose from hang, swing, rest)")
    if not (ROOT / "runs" / "hang.opts").exists():
        fail(PROG, f"{ROOT / 'runs' / 'hang.opts'} is missing")

    grid = ["-da_grid_x", str(N), "-da_grid_y", str(N)]
    hang = ["-options_file", "runs/hang.opts"] + grid
    swing = grid + ["-cloth_size", "1", "-cloth_orientation", "horizontal", "-cloth_center", "0,0,1", "-cloth_pin", "edge",
                    "-cloth_damping", "0.1"]
    # released hanging straight down from its two top corners: one equilibrium (a
    # sheet dropped from horizontal can settle into different fold states)
    rest = hang + ["-cloth_orientation", "vertical", "-cloth_damping", "2", "-drape_rest_tol", "1e-7", "-ts_max_time", "60"]

    rows, refrows = [], []
    with tempfile.TemporaryDirectory(prefix="wp_") as tmp, ThreadPoolExecutor(max(1, a.jobs)) as pool:
        drape = Drape(a.build, a.np, tmp)
        out = Path(a.out)
        out.mkdir(parents=True, exist_ok=True)
        print(f"work_precision: {N} x {N} lattice, T = {T:g} s, {spd} step(s) per decade, {a.np} rank(s), {drape.exe}", flush=True)
        try:
            for s in scenes:
                r, ref = rest_scene(drape, rest, a, pool) if s == "rest" else timed_scene(drape, s, hang if s == "hang" else swing, T, spd, a, pool)
                rows += r
                refrows.append(ref)
        except StudyError as e:
            fail(PROG, str(e))

    csv_path = out / "work_precision.csv"
    with open(csv_path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS)
        w.writeheader()
        w.writerows(rows + refrows)
    for s in scenes:
        plot(rows, s, out / f"wp_{s}.png")
    table = fastest(rows, scenes, refrows)
    head = (f"Fastest scheme per target error (err_max relative to the 1 m cloth; {N} x {N} lattice, T = {T:g} s, "
            f"{a.np} rank(s); command: scripts/work_precision.py{' --quick' if a.quick else ''})\n\n")
    (out / "fastest.md").write_text(head + table)
    print()
    print(head + table)
    # the reference must be far more accurate than anything it judges (checked after writing, so the CSV shows why)
    try:
        for ref in refrows:
            check_reference(ref["scene"], ref, rows, a.ref_margin)
    except StudyError as e:
        fail(PROG, str(e))
    print(f"wrote {csv_path}, {', '.join(str(out / f'wp_{s}.png') for s in scenes)}, {out / 'fastest.md'}")


if __name__ == "__main__":
    main()
