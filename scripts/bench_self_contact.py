#!/usr/bin/env python3
"""Cost of self-contact (-contact_self) on the sphere scene, by lattice size.

Runs runs/sphere.opts (drapebe, h = 2 ms) for --time s of simulated time (the fall,
the landing and the folding) with and without -contact_self on n x n lattices of
the same 1 m cloth, and reports the wall time of each, their ratio, the share of a
run spent in the self-contact filter (the DrapeSelfContact event of -log_view:
gathering the cloth, the broad phase, proximity and collision passes), the filter's
time per step, the broad phase's time per candidate list (DrapeSelfBroad) and how
often the list was rebuilt, for each broad phase of --broad-phase (CGAL's box
intersection, the spatial hash of the primitives, the hash of the lattice's tiles:
the same pairs, so the same collisions). Medians of
--repeat runs, one after the other on an otherwise idle machine.

    .venv/bin/python scripts/bench_self_contact.py --sizes 41,61,81 --repeat 3
    .venv/bin/python scripts/bench_self_contact.py --quick      # smoke run (the test suite's)

With --ranks R1,R2,... it times instead the filter on each number of ranks: the
pile scene (runs/pile.opts) in symplectic Euler (h = 0.1 ms), whose frames are
bitwise the same on any partition, so every rank count does the same work; the
filter's seconds (the slowest rank's), the speed-up over the first rank count, the
largest halo and the pairs gathered across ranks.

    .venv/bin/python scripts/bench_self_contact.py --ranks 1,2 --sizes 61,81 --time 0.3

With --scenes it times instead what self-contact adds to a step on the scenes of
issue 27 (--scene-list: the Cusick drape of denim at 81^2 and 161^2 in backward
Euler over its swing, the sphere drop at 64^2 in backward Euler at 10 ms to 1 s,
the peers' stiff sphere drop at 64^2 in symplectic Euler at 0.1 ms to 0.3 s and to
1 s), in CPU seconds: without it, with it, and with it taking every candidate in
every pass (-contact_self_near_radius 0: no near list), the three runs interleaved
in each repeat; the ratio a run and a step.

    .venv/bin/python scripts/bench_self_contact.py --scenes --repeat 3   # about 30 minutes here
"""
import argparse
import os
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import machine, md_table, median  # noqa: E402
from drape_run import Drape, fail  # noqa: E402

PROG = "bench_self_contact.py"
KINDS = ("cgal", "hash", "tiles")


def event(stdout, name):
    """Calls and seconds of a -log_view event (0, 0 when absent)."""
    m = re.search(rf"^{name}\s+(\d+)\s+\S+\s+(\S+)", stdout, re.M)
    return (int(m.group(1)), float(m.group(2))) if m else (0, 0.0)


def one(drape, n, t, kind):
    """One run without self-contact (kind None) or with the broad phase `kind`: the
    report, the filter's seconds and the broad phase's seconds per call."""
    args = ["-options_file", "runs/sphere.opts", "-da_grid_x", n, "-da_grid_y", n, "-ts_max_time", t,
            "-contact_self", "0" if kind is None else "1", "-log_view"]
    if kind:
        args += ["-contact_self_broad_phase", kind]
    r = drape.run(args)
    if r.returncode:
        fail(PROG, f"the run failed:\n{r.tail()}")
    calls, broad = event(r.stdout, "DrapeSelfBroad")
    return r.report, event(r.stdout, "DrapeSelfContact")[1], broad / max(calls, 1)


def ranks(a, sizes, counts):
    """The --ranks table."""
    rows = []
    for n in sizes:
        base = None
        for r in counts:
            walls, filt, reps = [], [], None
            for _ in range(a.repeat):
                res = Drape(PROG, a.build, r).run(["-options_file", "runs/pile.opts", "-da_grid_x", n, "-da_grid_y", n, "-ts_type", "basicsymplectic",
                                                   "-ts_dt", "1e-4", "-ts_max_time", a.time, "-output_interval", a.time, "-log_view"])
                if res.returncode:
                    fail(PROG, f"the run failed:\n{res.tail()}")
                reps = res.report
                walls.append(reps["wall"])
                filt.append(event(res.stdout, "DrapeSelfContact")[1])
            base = base or median(filt)
            rows.append([f"{n}^2", str(r), f"{median(walls):.2f}", f"{median(filt):.3g}", f"{1e3 * median(filt) / reps['steps']:.3g}",
                         f"{base / median(filt):.2f}", str(reps["self_halo_max"]), str(reps["self_gathered"]), str(reps["self_contact_pairs"])])
    print(f"# {machine()}")
    print(f"# pile scene, symplectic Euler h = 0.1 ms, {a.time:g} s simulated, medians of {a.repeat}")
    print(md_table(["lattice", "ranks", "wall (s)", "filter (s)", "filter ms/step", "filter speed-up", "largest halo",
                    "pairs gathered", "close pairs at the end"], rows))


STIFF = ["-cloth_size", "1", "-cloth_stretch", "1333", "-cloth_shear", "500", "-cloth_bend", "1e-5", "-cloth_density", "0.1", "-cloth_damping", "0",
         "-solid_type", "sphere", "-solid_radius", "0.25", "-contact_mode", "friction", "-contact_thickness", "0.005", "-cloth_center", "0,0,0.3",
         "-ts_type", "basicsymplectic", "-ts_dt", "1e-4"]
CUSICK = ["-options_file", "runs/cusick.opts", "-cloth_fabric", "denim", "-drape_rest_tol", "0"]
# key: (label, options, lattice, simulated s); the scenes: the Cusick drape at 81^2
# and 161^2 (its swing), the sphere drop of its floor (drapebe, 10 ms, to 1 s), and the
# peers' stiff drop in symplectic Euler over its fall and landing (0.3 s) and its folding
# on the sphere (to 1 s)
SCENES = {
    "cusick81": ("Cusick denim, drapebe 1 ms", CUSICK, 81, 1.5),
    "cusick161": ("Cusick denim, drapebe 1 ms", CUSICK, 161, 1.5),
    "sphere": ("sphere drop, drapebe 10 ms", ["-options_file", "runs/sphere.opts", "-ts_dt", "1e-2"], 64, 1.0),
    "stiff": ("stiff sphere drop, symplectic 0.1 ms", STIFF, 64, 0.3),
    "stiff1": ("stiff sphere drop, symplectic 0.1 ms", STIFF, 64, 1.0),
}
QUICK_SCENES = {"cusick81": 0.05, "sphere": 0.3, "stiff": 0.05}  # --quick: one of each at 21^2, simulated s
VARIANTS = (("without", ["-contact_self", "0"]), ("with", ["-contact_self"]), ("every candidate", ["-contact_self", "-contact_self_near_radius", "0"]))


def scenes(a):
    """The --scenes table: CPU seconds without self-contact, with it, and with it on every
    candidate; the ratio a run and a step (a run without self-contact may take other
    steps: the drapebe drop's folds pass through each other, and steps that added
    energy are cut)."""
    drape = Drape(PROG, a.build)
    keys = [k for k in a.scene_list.split(",") if k]
    if not keys or any(k not in SCENES for k in keys):
        fail(PROG, f"--scene-list takes {', '.join(SCENES)}, comma-separated; got {a.scene_list!r}")
    if a.quick:
        keys = [k for k in keys if k in QUICK_SCENES]
    rows = []
    for key in keys:
        name, args, n, t = SCENES[key]
        n, t = (21, QUICK_SCENES[key]) if a.quick else (n, t)
        lattice = ["-da_grid_x", str(n), "-da_grid_y", str(n)]
        cpu, reps = {v: [] for v, _ in VARIANTS}, {}
        for _ in range(a.repeat):
            for v, extra in VARIANTS:
                r = drape.run(args + lattice + extra + ["-ts_max_time", str(t), "-output_interval", str(t)])
                if r.returncode:
                    fail(PROG, f"the run failed:\n{r.tail()}")
                cpu[v].append(r.report["cpu"])
                reps[v] = r.report
        off = median(cpu["without"])
        rep = reps["with"]
        per_step = (median(cpu["with"]) / rep["steps"]) / (off / reps["without"]["steps"])
        rows.append([name, f"{n}^2", f"{t:g}", str(rep["steps"]), f"{off:.2f}", f"{median(cpu['with']):.2f}", f"{median(cpu['with']) / off:.2f}",
                     f"{median(cpu['every candidate']):.2f}", f"{median(cpu['every candidate']) / off:.2f}",
                     f"{rep['self_broad_phases']}", f"{rep['self_near_lists']}", f"{rep['self_live_lists']}", str(reps["without"]["steps"]), f"{per_step:.2f}"])
    print(f"# {machine()}")
    print(f"# CPU seconds (all ranks), one rank, medians of {a.repeat} interleaved repeats")
    print(md_table(["scene", "lattice", "simulated s", "steps", "without", "with", "ratio", "every candidate", "ratio",
                    "candidate lists", "near lists", "passes on the live list", "steps without", "ratio a step"], rows))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="41,61,81", help="lattice sizes n (n x n), comma-separated")
    ap.add_argument("--time", type=float, default=1.0, help="simulated time of each run (s)")
    ap.add_argument("--repeat", type=int, default=3, help="runs per case (medians)")
    ap.add_argument("--broad-phase", default="cgal,hash,tiles", help="broad phases to time, comma-separated (cgal, hash, tiles)")
    ap.add_argument("--build", default=os.environ.get("DRAPE_BUILD", "build"), help="drape's build directory (default $DRAPE_BUILD or build)")
    ap.add_argument("--ranks", help="time the filter on these numbers of ranks instead (comma-separated; the pile scene)")
    ap.add_argument("--scenes", action="store_true", help="time self-contact's share of a step on the scenes of issue 27 instead")
    ap.add_argument("--scene-list", default=",".join(SCENES), help="with --scenes: which, comma-separated (" + ", ".join(SCENES) + ")")
    ap.add_argument("--quick", action="store_true", help="one 21^2 run of 0.4 s each way (with --scenes: one scene of each kind, QUICK_SCENES; a smoke test)")
    a = ap.parse_args()
    if a.quick:
        a.sizes, a.time, a.repeat = "21", 0.4, 1
    try:
        sizes = [int(s) for s in a.sizes.split(",")]
    except ValueError:
        fail(PROG, f"--sizes takes integers separated by commas; got {a.sizes!r}")
    if any(n < 3 or n > 1025 for n in sizes) or a.repeat < 1 or not 0 < a.time <= 100:
        fail(PROG, "--sizes must lie in 3..1025, --repeat be at least 1 and --time in (0, 100] s")
    if a.scenes:
        scenes(a)
        return
    if a.ranks:
        try:
            counts = [int(r) for r in a.ranks.split(",")]
        except ValueError:
            fail(PROG, f"--ranks takes integers separated by commas; got {a.ranks!r}")
        if any(r < 1 or r > 1024 for r in counts):
            fail(PROG, "--ranks must lie in 1..1024")
        ranks(a, sizes, counts)
        return
    kinds = a.broad_phase.split(",")
    if not kinds or any(k not in KINDS for k in kinds):
        fail(PROG, f"--broad-phase takes {' and '.join(KINDS)}, comma-separated; got {a.broad_phase!r}")
    drape = Drape(PROG, a.build)
    rows = []
    for n in sizes:
        off, on, share, broad = [], {k: [] for k in kinds}, {k: [] for k in kinds}, {k: [] for k in kinds}
        reps = {}
        for _ in range(a.repeat):
            off.append(one(drape, n, a.time, None)[0]["wall"])
            for k in kinds:
                rep, ev, bp = one(drape, n, a.time, k)
                on[k].append(rep["wall"])
                share[k].append(ev / rep["wall"])
                broad[k].append(bp)
                reps[k] = rep
        for k in kinds:
            rep, steps = reps[k], reps[k]["steps"]
            rows.append([f"{n}^2", k, f"{median(off):.2f}", f"{median(on[k]):.2f}", f"{median(on[k]) / median(off):.2f}",
                         f"{100 * median(share[k]):.0f} %", f"{1e3 * median(share[k]) * median(on[k]) / steps:.2f}",
                         f"{1e3 * median(broad[k]):.2f}", f"{rep['self_broad_phases']} / {steps}", str(rep["self_collisions"]),
                         str(rep["self_failsafe"])])
    print(f"# {machine()}")
    print(f"# sphere scene, {a.time:g} s simulated, medians of {a.repeat}")
    print(md_table(["lattice", "broad phase", "wall without (s)", "with (s)", "ratio", "filter share", "filter ms/step",
                    "broad phase ms/list", "candidate lists / steps", "collisions", "fail-safe"], rows))


if __name__ == "__main__":
    main()
