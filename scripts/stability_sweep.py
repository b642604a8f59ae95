#!/usr/bin/env python3
"""Stability stress test of drape's explicit schemes (issue "stability stress test").

For symplectic Euler (-ts_type basicsymplectic) and explicit Euler (-ts_type euler)
the largest stable step is found by bisection on -ts_dt, across four sweeps
(stretch stiffness, areal density, damping, lattice size), and compared with the
limit drape prints at start-up and with the linear theory

    symplectic Euler:  h <= (sqrt(c^2 + 4 Omega^2) - c) / Omega^2
    explicit Euler:    h <= c / Omega^2        (underdamped; unstable for c = 0)

where Omega = Omega_max is the value drape prints (power iterations at t = 0).

Stability criterion of one run: the hanging cloth (-cloth_pin edge_corners, lattice
12 x 12 unless swept, gravity (0,0,-1) m/s^2) is run for a FIXED NUMBER OF STEPS
(400 for symplectic Euler, 20000 for explicit Euler; --quick: 400 and 2000) with no
time cap; it is stable when drape exits 0. A non-zero exit must be drape's
divergence message (one stderr line starting "drape: error: The run diverged at
step"); anything else is counted as an unexpected failure. Every run writes its first
and last frames to HDF5; a run that exits 0 with a non-finite position is a "silent
NaN" (must be 0).

Why a fixed step count, and the "finite-N" column: near the limit an unstable mode
grows by the spectral radius rho(h) of the one-step map per step, and drape only
stops once the energy has grown far beyond the initial energy scale. A run of N steps
therefore looks stable until N * 2 ln rho(h) ~ K (K ~ 25, i.e. an energy growth of
e^25). For symplectic Euler rho grows quickly past the limit, so 400 steps resolve
it to a few percent. For explicit Euler rho^2 = 1 - hc + h^2 Omega^2 is barely above
1 just past c/Omega^2 when c << Omega, so any finite run overestimates the limit;
the column `finite_n_model` is the h where N * 2 ln rho(h) = K for the single mode
Omega, which is what a finite run can measure. Explicit Euler therefore uses a soft,
heavy, strongly damped base fabric (stretch 10 N/m, shear 0.6 N/m, 0.5 kg/m^2,
c = 10 1/s), where c/Omega is ~0.1 and the bias is ~10-20 %.

Backward Euler part: stiff light fabric (stretch 1e4 N/m, 0.05 kg/m^2), gravity
9.81 m/s^2 so the cloth swings, steps 0.01..0.1 s to t = 2 s with -snes_type ksponly
(drape's default, linearised) and newtonls (full backward Euler). Reported: whether
the run completes, the position difference ksponly vs newtonls at the last common
frame, and the numerical damping: kinetic energy at t = 0.5 s and 1 s relative to a
small-step symplectic Euler reference (h = half its limit).

Outputs in --out (default out/stability): sweep_<name>.csv and .png per sweep,
backward_euler.csv/.png, summary.md, summary.json.

Usage: scripts/stability_sweep.py [--out DIR] [--quick] [--np K] [--jobs J]
"""
import argparse
import concurrent.futures as cf
import csv
import json
import math
import os
import shutil
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

import drape_h5
from drape_run import Drape

PROG = "stability_sweep"
K_GROWTH = 25.0  # ln of the energy growth drape needs to call a run diverged (model)

SYM, EXP = "symplectic", "explicit"
TS_TYPE = {SYM: ["-ts_type", "basicsymplectic"], EXP: ["-ts_type", "euler"]}

# Base fabrics (drape's defaults for symplectic Euler; soft/heavy/damped for explicit)
BASE = {
    SYM: dict(stretch=500.0, shear=30.0, density=0.15, damping=0.2, lattice=12),
    EXP: dict(stretch=10.0, shear=0.6, density=0.5, damping=10.0, lattice=12),
}
GRAVITY = "0,0,-1"

SWEEPS_FULL = {
    "stretch": [10.0, 100.0, 1000.0, 10000.0],
    "density": [0.05, 0.1, 0.2, 0.5],
    "damping": [0.0, 0.5, 2.0, 10.0],
    "lattice": [8, 12, 16, 24],
}
SWEEPS_QUICK = {
    "stretch": [100.0, 10000.0],
    "density": [0.05, 0.5],
    "damping": [2.0, 10.0],
    "lattice": [8, 16],
}
UNITS = {"stretch": "N/m", "density": "kg/m^2", "damping": "1/s", "lattice": "particles per side"}
# expected log-log slope of the limit against the parameter for a stiffness-dominated Omega
SLOPE = {"stretch": -0.5, "density": 0.5, "lattice": -1.0}


class Stats:
    """Counts over every drape run of the script (thread safe)."""

    def __init__(self):
        self.lock = threading.Lock()
        self.runs = 0
        self.ok = 0
        self.diverged_caught = 0
        self.solver_errors = 0  # backward Euler: clean one-line drape errors (SNES/KSP failures)
        self.silent_nan = 0
        self.nan_runs = []
        self.unexpected = []  # (command, exit code, stderr)
        self.log = []  # every run except clean backward-Euler solver errors

    def add(self, res):
        with self.lock:
            self.runs += 1
            self.log.append(dict(status=res["status"], rc=res["rc"], nonfinite=int(res["nonfinite"]),
                                 stderr=(res["stderr"].strip().splitlines() or [""])[0][:200],
                                 args=" ".join(res["args"])))
            if res["status"] == "ok":
                self.ok += 1
                if res["nonfinite"]:
                    self.silent_nan += 1
                    self.nan_runs.append(res["cmd"])
            elif res["status"] == "diverged":
                self.diverged_caught += 1
            else:
                self.unexpected.append((res["cmd"], res["rc"], res["stderr"].strip()))


STATS = Stats()
DRAPE = None  # the Drape of main(): the executable, the ranks per run
TMP = None


def material_args(p):
    m = int(p["lattice"])
    return ["-da_grid_x", str(m), "-da_grid_y", str(m), "-cloth_pin", "edge_corners",
            "-cloth_stretch", repr(float(p["stretch"])), "-cloth_shear", repr(float(p["shear"])),
            "-cloth_density", repr(float(p["density"])), "-cloth_damping", repr(float(p["damping"]))]


def run_drape(args, expect=None, keep_h5=False, timeout=900):
    """Run drape; classify the outcome. With expect="diverged-or-ok" (default) any
    non-zero exit other than drape's divergence message is 'failed'; expect="solve"
    also accepts drape's other one-line errors as 'failed' (recorded, not a bug)."""
    fd, h5 = tempfile.mkstemp(suffix=".h5", dir=TMP)
    os.close(fd)
    os.unlink(h5)
    args = list(args) + ["-output_file", h5]
    r = DRAPE.run(args, timeout=timeout)
    res = dict(cmd=r.cmd, args=args, rc=r.returncode, stdout=r.stdout, stderr=r.stderr, report=r.report,
               nonfinite=False, div_step=r.diverged_at(), h5=h5 if keep_h5 else None)
    if r.returncode == 0:
        res["status"] = "ok"
        try:
            res["nonfinite"] = not np.all(np.isfinite(drape_h5.load(h5).positions))
        except (OSError, ValueError) as e:  # no readable output from a successful run is a bug too
            res["status"] = "failed"
            res["stderr"] += f"\n[stability_sweep] unreadable output: {e}"
    elif res["div_step"] is not None:
        res["status"] = "diverged"
    else:
        res["status"] = "failed"
    if expect == "solve" and res["status"] == "failed" and r.error():
        res["status"] = "error"  # a clean drape error (e.g. SNES not converged): reported, not a bug
        res["message"] = r.error()
    if res["status"] == "error":
        with STATS.lock:
            STATS.runs += 1
            STATS.solver_errors += 1
    else:
        STATS.add(res)
    if not keep_h5 and os.path.exists(h5):
        os.unlink(h5)
    return res


def read_limits(p):
    """Omega_max and the symplectic and explicit Euler limits drape reports for a fabric
    (-ts_max_steps 0); the explicit one is 0 when it is unstable at every step."""
    res = run_drape(material_args(p) + ["-gravity", GRAVITY, "-ts_max_steps", "0"])
    if res["status"] != "ok":
        raise RuntimeError(f"drape failed reading the limits: {res['stderr']}")
    rep = res["report"]
    return rep["omega_max"], rep["symplectic_limit"], rep["euler_limit"]


def theory(scheme, omega, c):
    if scheme == SYM:
        return (math.sqrt(c * c + 4 * omega * omega) - c) / omega ** 2
    return c / omega ** 2 if c < 2 * omega else 2.0 / (c / 2 + math.sqrt(c * c / 4 - omega * omega))


def spectral_radius(scheme, h, omega, c):
    w2 = omega * omega
    if scheme == SYM:  # v1 = (1-hc) v - h w2 x ; x1 = x + h v1
        a = np.array([[1 - h * h * w2, h * (1 - h * c)], [-h * w2, 1 - h * c]])
    else:  # x1 = x + h v ; v1 = v - h (w2 x + c v)
        a = np.array([[1.0, h], [-h * w2, 1 - h * c]])
    return max(abs(np.linalg.eigvals(a)))


def finite_n_model(scheme, omega, c, nsteps, k=K_GROWTH):
    """Step at which N * 2 ln rho(h) = k for the single mode omega (what N steps can detect)."""
    g = lambda h: nsteps * 2 * math.log(spectral_radius(scheme, h, omega, c)) - k
    lo = max(theory(scheme, omega, c), 1e-12 / omega)
    hi = lo * 2 + 1.0 / omega
    while g(hi) < 0:
        hi *= 2
    if g(lo) > 0:
        return lo
    for _ in range(100):
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if g(mid) < 0 else (lo, mid)
        if hi / lo - 1 < 1e-6:
            break
    return math.sqrt(lo * hi)


def bisect_limit(scheme, p, guess, nsteps, tol):
    """Largest stable step: bracket around `guess`, then geometric bisection to tol."""
    args = material_args(p) + ["-gravity", GRAVITY, "-ts_max_steps", str(nsteps),
                               "-ts_max_time", "1e30", "-output_steps", str(nsteps)] + TS_TYPE[scheme]
    runs = []

    def stable(h):
        r = run_drape(args + ["-ts_dt", repr(h)])
        runs.append((h, r["status"], r["div_step"]))
        if r["status"] == "failed":
            return None
        return r["status"] == "ok"

    lo, hi = guess * 0.8, guess * 1.25
    s = stable(lo)
    while s is False and lo > guess * 1e-4:
        hi, lo = lo, lo / 2
        s = stable(lo)
    if s is None:
        return None, None, runs
    if hi == guess * 1.25:
        s = stable(hi)
        while s is True and hi < guess * 1e4:
            lo, hi = hi, hi * 2
            s = stable(hi)
        if s is None:
            return None, None, runs
    while hi / lo - 1 > tol:
        mid = math.sqrt(lo * hi)
        s = stable(mid)
        if s is None:
            return None, None, runs
        lo, hi = (mid, hi) if s else (lo, mid)
    return lo, hi, runs


def sweep_point(scheme, name, value, nsteps, tol):
    p = dict(BASE[scheme])
    p[name] = value
    omega, psym, pexp = read_limits(p)
    printed = psym if scheme == SYM else pexp
    c = p["damping"]
    th = theory(scheme, omega, c) if (scheme == SYM or c > 0) else 0.0
    fin = finite_n_model(scheme, omega, c, nsteps)
    lo, hi, runs = bisect_limit(scheme, p, fin, nsteps, tol)
    meas = math.sqrt(lo * hi) if lo else float("nan")
    div_hi = [d for h, st, d in runs if h == hi]
    return dict(sweep=name, value=value, scheme=scheme, nsteps=nsteps, omega_max=omega,
                printed=printed, theory=th, finite_n_model=fin, stable_lo=lo or float("nan"),
                unstable_hi=hi or float("nan"), measured=meas,
                ratio_printed=meas / printed if printed > 0 else float("nan"),
                ratio_theory=meas / th if th > 0 else float("nan"),
                ratio_finite_n=meas / fin, runs=len(runs),
                diverged=sum(1 for r in runs if r[1] == "diverged"),
                failed=sum(1 for r in runs if r[1] == "failed"),
                div_step_at_hi=div_hi[0] if div_hi else "",
                **{f"base_{k}": v for k, v in p.items()})


FIELDS = ["sweep", "value", "scheme", "nsteps", "omega_max", "printed", "theory", "finite_n_model",
          "stable_lo", "unstable_hi", "measured", "ratio_printed", "ratio_theory", "ratio_finite_n",
          "runs", "diverged", "failed", "div_step_at_hi",
          "base_stretch", "base_shear", "base_density", "base_damping", "base_lattice"]


def write_csv(path, rows, fields):
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})


def loglog_slope(rows):
    x = np.array([r["value"] for r in rows], float)
    y = np.array([r["measured"] for r in rows], float)
    ok = (x > 0) & np.isfinite(y) & (y > 0)
    if ok.sum() < 2:
        return float("nan")
    return float(np.polyfit(np.log(x[ok]), np.log(y[ok]), 1)[0])


def plot_sweep(path, name, rows_by_scheme):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    schemes = [s for s in (SYM, EXP) if rows_by_scheme.get(s)]
    fig, axes = plt.subplots(1, len(schemes), figsize=(5.5 * len(schemes), 4.2), squeeze=False)
    for ax, s in zip(axes[0], schemes):
        rows = rows_by_scheme[s]
        x = np.array([r["value"] for r in rows], float)
        xp = np.where(x > 0, x, np.nan) if name != "damping" else x
        for key, style, label in (("theory", "k-", "theory (drape's Omega_max)"),
                                  ("finite_n_model", "C2--", f"finite-N model (K={K_GROWTH:g})"),
                                  ("printed", "C1x", "printed by drape")):
            y = np.array([r[key] for r in rows], float)
            y = np.where(y > 0, y, np.nan)
            ax.plot(xp, y, style, label=label, ms=9)
        y = np.array([r["measured"] for r in rows], float)
        lo = np.array([r["stable_lo"] for r in rows], float)
        hi = np.array([r["unstable_hi"] for r in rows], float)
        ax.errorbar(xp, y, yerr=[y - lo, hi - y], fmt="C0o", label="measured (bisection)", capsize=3)
        if name != "damping":
            ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(f"{name} ({UNITS[name]})")
        ax.set_ylabel("largest stable h (s)")
        b = BASE[s]
        ax.set_title(f"{s} Euler, {rows[0]['nsteps']} steps\nbase Y={b['stretch']:g} G={b['shear']:g} "
                     f"rho={b['density']:g} c={b['damping']:g} M={b['lattice']}", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------- backward Euler
BE_FABRIC = dict(stretch=1e4, shear=30.0, density=0.05, damping=0.2, lattice=12)
BE_GRAVITY = "0,0,-9.81"


def be_run(extra, t_end, interval, max_steps=None):
    args = material_args(BE_FABRIC) + ["-gravity", BE_GRAVITY, "-ts_max_time", repr(t_end),
                                       "-output_interval", repr(interval)] + extra
    if max_steps:  # (--quick: a run whose failed solves keep its step small stops there; t_reached says where)
        args += ["-ts_max_steps", str(max_steps)]
    res = run_drape(args, expect="solve", keep_h5=True)
    data = None  # the frames (drape_h5.DrapeRun), if any were written
    if os.path.exists(res["h5"]):
        try:
            data = drape_h5.load(res["h5"])
        except (OSError, ValueError):
            pass
        os.unlink(res["h5"])
    return res, data


def at_time(data, t, tol):
    return None if data is None else data.frame_at(t, tol)


def backward_euler(steps, t_end, interval, max_steps=None):
    omega, psym, _ = read_limits(BE_FABRIC)
    href = 0.5 * psym
    ref_res, ref = be_run(["-ts_type", "basicsymplectic", "-ts_dt", repr(href)], t_end, interval)
    rows = []
    for h in steps:
        out = {}
        for snes in ("ksponly", "newtonls"):
            res, data = be_run(["-ts_type", "drapebe", "-snes_type", snes, "-ts_dt", repr(h)], t_end, interval, max_steps)
            out[snes] = (res, data)
        row = dict(h=h, h_over_sym_limit=h / psym)
        for snes, (res, data) in out.items():
            msg = res.get("message") or (res["stderr"].strip().splitlines() or [""])[0]
            row[f"{snes}_status"] = res["status"]
            row[f"{snes}_t_reached"] = float(data.time[-1]) if data is not None else float("nan")
            row[f"{snes}_message"] = msg[:160]
            row[f"{snes}_nonfinite"] = bool(data is not None and not np.all(np.isfinite(data.positions)))
            for t in (0.5, 1.0):
                i, j = at_time(data, t, h / 4), at_time(ref, t, href)
                row[f"{snes}_ke_ratio_{t:g}s"] = (float(data.energies["kinetic"][i] / ref.energies["kinetic"][j])
                                                 if i is not None and j is not None and ref.energies["kinetic"][j] > 0
                                                 else float("nan"))
            i, j = (len(data.time) - 1 if data is not None else None), None
            if i is not None:
                j = at_time(ref, data.time[i], href)
            row[f"{snes}_dx_ref_rms"] = (float(np.sqrt(np.mean(np.sum((data.positions[i] - ref.positions[j]) ** 2, -1))))
                                         if i is not None and j is not None else float("nan"))
        a, b = out["ksponly"][1], out["newtonls"][1]
        n = min(len(a.time), len(b.time)) - 1 if a is not None and b is not None else 0
        if n > 0:
            d = np.linalg.norm(a.positions[n] - b.positions[n], axis=-1)
            row.update(cmp_time=float(a.time[n]), dx_ksp_newton_rms=float(np.sqrt(np.mean(d ** 2))),
                       dx_ksp_newton_max=float(d.max()))
        else:
            row.update(cmp_time=float("nan"), dx_ksp_newton_rms=float("nan"), dx_ksp_newton_max=float("nan"))
        rows.append(row)
    info = dict(omega=omega, sym_limit=psym, h_ref=href, ref_status=ref_res["status"],
                ref_ke_0_5=float(ref.energies["kinetic"][at_time(ref, 0.5, href)]) if ref is not None else float("nan"))
    return rows, info


BE_FIELDS = ["h", "h_over_sym_limit"] + [f"{s}_{k}" for s in ("ksponly", "newtonls") for k in (
    "status", "t_reached", "ke_ratio_0.5s", "ke_ratio_1s", "dx_ref_rms", "nonfinite", "message")] + [
    "cmp_time", "dx_ksp_newton_rms", "dx_ksp_newton_max"]


def plot_be(path, rows):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    h = np.array([r["h"] for r in rows])
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.2))
    for s, m in (("ksponly", "o-"), ("newtonls", "s--")):
        for t in ("0.5", "1"):
            a1.plot(h, [r[f"{s}_ke_ratio_{t}s"] for r in rows], m, label=f"{s}, t = {t} s")
        a2.plot(h, [r[f"{s}_dx_ref_rms"] for r in rows], m, label=f"{s} vs small-step reference")
    a2.plot(h, [r["dx_ksp_newton_rms"] for r in rows], "k^:", label="ksponly vs newtonls")
    a1.set_xscale("log"); a1.set_yscale("log"); a1.set_xlabel("h (s)")
    a1.set_ylabel("KE / KE(reference)"); a1.set_title("numerical damping of backward Euler")
    a2.set_xscale("log"); a2.set_yscale("log"); a2.set_xlabel("h (s)")
    a2.set_ylabel("RMS position difference at last common frame (m)")
    a2.set_title(f"Y={BE_FABRIC['stretch']:g} N/m, rho={BE_FABRIC['density']:g} kg/m^2, g=9.81")
    for a in (a1, a2):
        a.grid(True, which="both", alpha=0.3); a.legend(fontsize=8)
    fig.tight_layout(); fig.savefig(path, dpi=110); plt.close(fig)


# ---------------------------------------------------------------- summary
def fmt(v, spec=".3g"):
    if isinstance(v, float):
        return "-" if math.isnan(v) else format(v, spec)
    return str(v)


def summary_md(path, args, sweeps, be_rows, be_info, elapsed, nsteps):
    L = [f"# Stability stress test ({'quick' if args.quick else 'full'})", "",
         f"Command: `{' '.join(['scripts/stability_sweep.py'] + sys.argv[1:])}`, {elapsed:.0f} s wall, "
         f"{DRAPE.np} rank(s) per run.", "",
         f"Criterion: hanging cloth (`-cloth_pin edge_corners`, gravity {GRAVITY} m/s^2), stable when drape "
         f"exits 0 after a fixed number of steps: symplectic Euler {nsteps[SYM]}, explicit Euler {nsteps[EXP]}. "
         f"Bisection on h to {args.tol:.0%} relative width; `measured` is the geometric mean of the bracket.", "",
         "Theory uses drape's printed Omega_max: symplectic `(sqrt(c^2+4 Omega^2)-c)/Omega^2`, explicit "
         "`c/Omega^2` (0 = unstable). `finite-N` is the step at which N steps give an energy growth e^"
         f"{K_GROWTH:g} in the top mode: what a run of finite length can detect.", "",
         "Base fabrics: " + "; ".join(f"{s} Euler: stretch {b['stretch']:g} N/m, shear {b['shear']:g}, "
                                      f"density {b['density']:g} kg/m^2, damping {b['damping']:g} 1/s, "
                                      f"lattice {b['lattice']}" for s, b in BASE.items()), "",
         "## Run counts", "",
         f"- drape runs: {STATS.runs}, exit 0: {STATS.ok}",
         f"- divergences caught with drape's message: {STATS.diverged_caught}",
         f"- backward-Euler solves that failed with a one-line drape error (reported below): "
         f"{STATS.solver_errors}",
         f"- silent NaN (exit 0 but non-finite positions in the HDF5): **{STATS.silent_nan}**",
         f"- unexpected failures (non-zero exit without drape's divergence message, stability runs): "
         f"**{len(STATS.unexpected)}**", ""]
    for cmd, rc, err in STATS.unexpected[:10]:
        L += [f"  - exit {rc}: `{cmd}`: {err[:300]}"]
    for name, by in sweeps.items():
        L += ["", f"## Sweep: {name} ({UNITS[name]})", "", f"![{name}](sweep_{name}.png)", ""]
        L += ["| scheme | value | Omega_max (rad/s) | printed (s) | theory (s) | finite-N (s) | measured (s) "
              "| measured/printed | measured/finite-N | runs |", "|---|---|---|---|---|---|---|---|---|---|"]
        for s, rows in by.items():
            for r in rows:
                L.append(f"| {s} | {r['value']:g} | {r['omega_max']:.4g} | {fmt(r['printed'], '.4g')} | "
                         f"{fmt(r['theory'], '.4g')} | {r['finite_n_model']:.4g} | {fmt(r['measured'], '.4g')} | "
                         f"{fmt(r['ratio_printed'])} | {fmt(r['ratio_finite_n'])} | {r['runs']} |")
        if name in SLOPE:
            L += ["", "Log-log slope of the measured limit: " + ", ".join(
                f"{s} {loglog_slope(rows):.3f}" for s, rows in by.items()) +
                f" (stiffness-dominated expectation {SLOPE[name]:g})."]
    if be_rows is not None:
        L += ["", "## Backward Euler on stiff light fabric", "",
              f"Stretch {BE_FABRIC['stretch']:g} N/m, density {BE_FABRIC['density']:g} kg/m^2, damping "
              f"{BE_FABRIC['damping']:g} 1/s, lattice {BE_FABRIC['lattice']}, gravity {BE_GRAVITY}, to t = "
              f"{args.be_time:g} s. Omega_max {be_info['omega']:.4g} rad/s, symplectic limit "
              f"{be_info['sym_limit']:.3g} s; reference: symplectic Euler h = {be_info['h_ref']:.3g} s "
              f"({be_info['ref_status']}), KE(0.5 s) = {be_info['ref_ke_0_5']:.4g} J.", "",
              "![backward Euler](backward_euler.png)", "",
              "| h (s) | h / sym. limit | ksponly | KE/KE_ref 0.5 s | KE/KE_ref 1 s | newtonls | KE/KE_ref 0.5 s "
              "| KE/KE_ref 1 s | ksponly-newtonls RMS / max (m) at t |", "|---|---|---|---|---|---|---|---|---|"]
        for r in be_rows:
            st = lambda s: r[f"{s}_status"] + ("" if r[f"{s}_status"] == "ok" else f" (t={r[f'{s}_t_reached']:g})")
            L.append(f"| {r['h']:g} | {r['h_over_sym_limit']:.0f} | {st('ksponly')} | {fmt(r['ksponly_ke_ratio_0.5s'])} | "
                     f"{fmt(r['ksponly_ke_ratio_1s'])} | {st('newtonls')} | {fmt(r['newtonls_ke_ratio_0.5s'])} | "
                     f"{fmt(r['newtonls_ke_ratio_1s'])} | {fmt(r['dx_ksp_newton_rms'])} / "
                     f"{fmt(r['dx_ksp_newton_max'])} at {fmt(r['cmp_time'])} |")
        msgs = sorted({r[f"{s}_message"] for r in be_rows for s in ("ksponly", "newtonls")
                       if r[f"{s}_status"] != "ok"})
        if msgs:
            L += ["", "Messages of the backward-Euler runs that stopped:", ""] + [f"- `{m}`" for m in msgs]
    Path(path).write_text("\n".join(L) + "\n")


def main(argv=None):
    global DRAPE, TMP
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="out/stability")
    ap.add_argument("--quick", action="store_true", help="2 points per sweep, coarse bisection (test suite)")
    ap.add_argument("--np", type=int, default=1, help="MPI ranks per drape run")
    ap.add_argument("--jobs", type=int, default=2, help="drape runs at once (sweep points in parallel)")
    ap.add_argument("--tol", type=float, default=None, help="relative bracket width (default 0.02, quick 0.1)")
    ap.add_argument("--no-beuler", action="store_true", help="skip the backward-Euler part")
    args = ap.parse_args(argv)
    DRAPE = Drape(PROG, os.environ.get("DRAPE_BUILD", "build"), args.np)
    if args.tol is None:
        args.tol = 0.1 if args.quick else 0.02
    nsteps = {SYM: 400, EXP: 2000 if args.quick else 20000}
    sweeps_def = SWEEPS_QUICK if args.quick else SWEEPS_FULL
    # quick: explicit Euler only on the damping sweep (it is slow and duration-limited elsewhere)
    plan = [(s, name, v) for name, vals in sweeps_def.items() for s in (SYM, EXP) for v in vals
            if not (args.quick and s == EXP and name != "damping")]
    be_steps = [0.05] if args.quick else [0.01, 0.02, 0.05, 0.1]
    args.be_time = 1.0 if args.quick else 2.0
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    TMP = tempfile.mkdtemp(prefix="stability_sweep_")
    t0 = time.time()
    try:
        with cf.ThreadPoolExecutor(max_workers=max(1, args.jobs)) as ex:
            futs = {(s, n, v): ex.submit(sweep_point, s, n, v, nsteps[s], args.tol) for s, n, v in plan}
            # quick: at most 2000 steps a backward-Euler run (t = 1 s takes 20 at 0.05 s): a
            # solver whose failures keep cutting its step stops there, t_reached saying where
            # (Newton with backtracking on |R|, before cp: 38005 steps and 134 s to t = 1 s)
            be_fut = None if args.no_beuler else ex.submit(backward_euler, be_steps, args.be_time, 0.1, 2000 if args.quick else None)
            results = {k: f.result() for k, f in futs.items()}
            be_rows, be_info = be_fut.result() if be_fut else (None, None)
    finally:
        shutil.rmtree(TMP, ignore_errors=True)
    sweeps = {}
    for name in sweeps_def:
        by = {s: [results[(s, name, v)] for v in sweeps_def[name] if (s, name, v) in results] for s in (SYM, EXP)}
        by = {s: r for s, r in by.items() if r}
        sweeps[name] = by
        write_csv(out / f"sweep_{name}.csv", [r for rows in by.values() for r in rows], FIELDS)
        plot_sweep(out / f"sweep_{name}.png", name, by)
    if be_rows is not None:
        write_csv(out / "backward_euler.csv", be_rows, BE_FIELDS)
        plot_be(out / "backward_euler.png", be_rows)
    elapsed = time.time() - t0
    summary_md(out / "summary.md", args, sweeps, be_rows, be_info, elapsed, nsteps)
    counts = dict(runs=STATS.runs, ok=STATS.ok, diverged_caught=STATS.diverged_caught,
                  silent_nan=STATS.silent_nan, solver_errors=STATS.solver_errors, silent_nan_runs=STATS.nan_runs,
                  unexpected_failures=[dict(cmd=c, rc=r, stderr=e) for c, r, e in STATS.unexpected],
                  be_nonfinite=sum(int(r[f"{s}_nonfinite"]) for r in (be_rows or [])
                                   for s in ("ksponly", "newtonls")),
                  elapsed_s=elapsed, quick=args.quick, nsteps=nsteps, tol=args.tol)
    write_csv(out / "runs.csv", STATS.log, ["status", "rc", "nonfinite", "stderr", "args"])
    (out / "summary.json").write_text(json.dumps(counts, indent=1))
    print(f"{STATS.runs} drape runs in {elapsed:.1f} s: {STATS.diverged_caught} divergences caught, "
          f"{STATS.silent_nan} silent NaN, {len(STATS.unexpected)} unexpected failures; see {out / 'summary.md'}")
    return 0 if STATS.silent_nan == 0 and not STATS.unexpected else 1


if __name__ == "__main__":
    sys.exit(main())
