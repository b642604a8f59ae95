#!/usr/bin/env python3
"""Backward Euler on stiff cloth and with contact: preconditioners, retries, contact cost (not a test).

Part 1, the stiff cloth of a peer benchmark (1 m, 0.1 kg/m^2, -cloth_stretch 1333
-cloth_shear 500 -cloth_bend 1e-5, no damping) in two scenes,

  hang   held at two corners, released flat, for --time s
  drop   dropped from 5 cm onto a sphere of radius 0.25 m (friction 0.3, contact
         thickness 5 mm), for --time s

on N x N lattices (--sizes), -ts_type drapebe -ts_dt 1e-2 with

  bjacobi   -pc_type bjacobi   (block Jacobi, ICC(0) blocks: drape's only default before)
  ml        -pc_type ml        (smoothed aggregation, Trilinos ML)
  gamg      -pc_type gamg -mg_levels_ksp_type richardson -mg_levels_pc_type sor
  default   no -pc_type: drape chooses by (h Omega_max)^2

and symplectic Euler at 0.9 x the limit drape prints. Recorded from drape's report
(-drape_json): whether it completed (else the reason it stopped), simulated s per wall s,
CG iterations and solves per step, steps retried at a smaller step, largest edge
strain.

Part 2, every measured fabric (-cloth_fabric): the sphere scene as shipped
(runs/sphere.opts, 41^2) with drape's default solver at the scene's step and at
1e-2 s, and hanging from two corners (1 m, 32^2 and 64^2) at 1e-2 s.

Part 3, what contact costs: symplectic Euler on the stiff drop (the sphere, a
closed-form distance) against the same run without the sphere, and the cloth of
runs/mesh.opts over its stool (a CGAL AABB tree) against the same cloth without
it: wall time of the same steps.

Part 4, a 2.5 cm x 20 cm strip with -cloth_stretch 1e4 hanging from its short edge,
drapebe at 1e-2 s, with block Jacobi and with the default.

Output in --out (default out/implicit_study): stiff.csv, fabrics.csv, contact.csv,
strip.csv and implicit_study.md (the tables, the machine, the commands).

    python3 scripts/implicit_study.py                       # about 30 minutes on a quiet machine
    python3 scripts/implicit_study.py --quick --out /tmp/is  # smoke run, under a minute
"""
import argparse
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_common import machine, md_table, write_csv  # noqa: E402
from drape_run import Drape, fail  # noqa: E402

PROG = "implicit_study"
STIFF = ["-cloth_size", "1", "-cloth_density", "0.1", "-cloth_stretch", "1333", "-cloth_shear", "500", "-cloth_bend", "1e-5", "-cloth_damping", "0"]
SCENES = {
    "hang": ["-cloth_pin", "edge_corners"],
    "drop": ["-solid_type", "sphere", "-solid_radius", "0.25", "-contact_mode", "friction", "-contact_thickness", "0.005", "-cloth_center", "0,0,0.3"],
}
PCS = [("bjacobi", ["-pc_type", "bjacobi"]), ("ml", ["-pc_type", "ml"]),
       ("gamg", ["-pc_type", "gamg", "-mg_levels_ksp_type", "richardson", "-mg_levels_pc_type", "sor"]), ("default", [])]
MESH = ["-da_grid_x", "41", "-da_grid_y", "41", "-cloth_size", "0.9", "-cloth_center", "0,0,0.15"]
FABRICS = ["denim", "polyester", "royal-target", "gray-interlock", "ivory-rib-knit", "pink-ribbon-brown", "tango-red-jet-set",
           "camel-ponte-roma", "navy-sparkle-sweat", "white-swim-solid"]


def record(r, tend):
    """The numbers of one run: completed?, sim s per wall s, CG its/step, solves/step, retries, strain, PC."""
    st, rep = r.status(), r.report
    row = {"status": st if st != "ok" else "completed"}
    if st == "ok" and rep:
        wall = rep["wall"]
        row.update(sim_per_wall=f"{rep['t'] / wall:.3g}" if wall > 0 else "", cg_per_step=f"{rep['cg_per_step']:.1f}" if rep["cg_per_step"] else "",
                   solves_per_step=f"{rep['solves_per_step']:.2f}", retried=str(rep["steps_retried"]),
                   strain_percent=f"{100 * rep['strain_max']:.3g}", wall=f"{wall:.3g}")
    row["pc"] = rep.get("pc_type", "") if rep else ""
    return row


def part_stiff(drape, a):
    rows = []
    for scene, extra in SCENES.items():
        if scene not in a.scenes:
            continue
        for n in a.sizes:
            base = STIFF + extra + ["-da_grid_x", str(n), "-da_grid_y", str(n), "-ts_max_time", str(a.time)]
            lim = drape.limits(base)["symplectic"]
            for name, pc in PCS:
                r = drape.run(base + ["-ts_type", "drapebe", "-ts_dt", "1e-2"] + pc, timeout=a.timeout)
                row = {"scene": scene, "n": n, "scheme": "drapebe 1e-2", "solver": name, **record(r, a.time)}
                rows.append(row)
                print(f"  {scene} {n}^2 {name}: {row}", flush=True)
            r = drape.run(base + ["-ts_type", "basicsymplectic", "-ts_dt", f"{0.9 * lim:.6e}"], timeout=a.timeout)
            row = {"scene": scene, "n": n, "scheme": f"symplectic {0.9 * lim:.3g}", "solver": "", **record(r, a.time)}
            rows.append(row)
            print(f"  {scene} {n}^2 symplectic: {row}", flush=True)
    return rows


def part_fabrics(drape, a):
    rows = []
    for fab in a.fabrics:
        for name, args in (("sphere, scene step", ["-options_file", "runs/sphere.opts", "-ts_max_time", str(a.time)]),
                           ("sphere, 1e-2", ["-options_file", "runs/sphere.opts", "-ts_dt", "1e-2", "-ts_max_time", str(a.time)])):
            r = drape.run(args + ["-cloth_fabric", fab], timeout=a.timeout)
            rows.append({"fabric": fab, "case": name, **record(r, a.time)})
            print(f"  {fab} {name}: {rows[-1]}", flush=True)
        for n in a.fabric_sizes:
            args = ["-cloth_fabric", fab, "-cloth_pin", "edge_corners", "-da_grid_x", str(n), "-da_grid_y", str(n), "-ts_type", "drapebe",
                    "-ts_dt", "1e-2", "-ts_max_time", str(a.time)]
            r = drape.run(args, timeout=a.timeout)
            rows.append({"fabric": fab, "case": f"hang {n}^2, 1e-2", **record(r, a.time)})
            print(f"  {fab} hang {n}: {rows[-1]}", flush=True)
    return rows


def part_contact(drape, a):
    rows = []
    n = a.contact_size
    lattice = ["-da_grid_x", str(n), "-da_grid_y", str(n), "-ts_max_time", str(a.time)]
    base = STIFF + SCENES["drop"] + lattice
    cases = [("stiff drop, sphere (closed form)", base, STIFF + ["-cloth_center", "0,0,0.3"] + lattice),
             ("stool mesh of runs/mesh.opts (AABB tree)", MESH + ["-solid_file", "runs/meshes/stool.off", "-contact_mode", "friction"] + lattice[4:],
              MESH + lattice[4:])]
    for name, with_solid, without in cases:
        walls, dt = {}, 0.9 * drape.limits(with_solid)["symplectic"]
        for label, args in (("with", with_solid), ("without", without)):
            r = drape.must(args + ["-ts_type", "basicsymplectic", "-ts_dt", f"{dt:.6e}", "-ts_max_steps", str(a.contact_steps), "-drape_rest_tol", "0"],
                           f"{name} {label} the solid")
            walls[label] = r.summary()[2]
        rows.append({"case": name, "steps": a.contact_steps, "wall_with_s": f"{walls['with']:.3g}", "wall_without_s": f"{walls['without']:.3g}",
                     "ratio": f"{walls['with'] / walls['without']:.2f}"})
        print(f"  {rows[-1]}", flush=True)
    return rows


def part_strip(drape, a):
    rows = []
    base = ["-cloth_size", "0.025,0.2", "-da_grid_x", "6", "-da_grid_y", "41", "-cloth_stretch", "1e4", "-cloth_pin", "edge",
            "-ts_type", "drapebe", "-ts_dt", "1e-2", "-ts_max_time", str(a.time)]
    for name, pc in (("bjacobi", ["-pc_type", "bjacobi"]), ("default", [])):
        r = drape.run(base + pc, timeout=a.timeout)
        rows.append({"solver": name, **record(r, a.time)})
        print(f"  strip {name}: {rows[-1]}", flush=True)
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="out/implicit_study")
    ap.add_argument("--build", default=os.environ.get("DRAPE_BUILD", "build"), help="drape's build directory (default $DRAPE_BUILD or build)")
    ap.add_argument("--sizes", default="32,64,128", help="lattices of part 1")
    ap.add_argument("--time", type=float, default=2.0, help="simulated time of every run, s")
    ap.add_argument("--fabric-sizes", default="32,64")
    ap.add_argument("--contact-size", type=int, default=64)
    ap.add_argument("--contact-steps", type=int, default=3000)
    ap.add_argument("--timeout", type=float, default=3600)
    ap.add_argument("--scenes", default="hang,drop", help="scenes of part 1")
    ap.add_argument("--parts", default="stiff,fabrics,contact,strip", help="parts to run (the tables of the others are empty)")
    ap.add_argument("--quick", action="store_true", help="smoke run: small lattices, short times, two fabrics")
    a = ap.parse_args()
    if a.quick:
        a.sizes, a.time, a.fabric_sizes, a.contact_size, a.contact_steps = "16", 0.1, "16", 16, 200
        a.fabrics = FABRICS[:2]
    else:
        a.fabrics = FABRICS
    a.scenes, a.parts = a.scenes.split(","), a.parts.split(",")
    if not set(a.scenes) <= set(SCENES) or not set(a.parts) <= {"stiff", "fabrics", "contact", "strip"}:
        fail(PROG, "--scenes takes hang and/or drop, --parts any of stiff, fabrics, contact, strip (comma-separated)")
    try:
        a.sizes = [int(s) for s in a.sizes.split(",")]
        a.fabric_sizes = [int(s) for s in a.fabric_sizes.split(",")]
    except ValueError:
        fail(PROG, "--sizes and --fabric-sizes take comma-separated lattice sizes, e.g. 32,64")
    if a.time <= 0 or min(a.sizes + a.fabric_sizes) < 4:
        fail(PROG, "--time must be positive and lattices at least 4 x 4")
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    drape = Drape(PROG, a.build)
    print(f"{PROG}: {machine()}", flush=True)
    stiff = part_stiff(drape, a) if "stiff" in a.parts else []
    write_csv(out / "stiff.csv", stiff, ["scene", "n", "scheme", "solver", "status", "pc", "sim_per_wall", "cg_per_step", "solves_per_step", "retried",
                                         "strain_percent", "wall"])
    fabrics = part_fabrics(drape, a) if "fabrics" in a.parts else []
    write_csv(out / "fabrics.csv", fabrics, ["fabric", "case", "status", "pc", "sim_per_wall", "cg_per_step", "solves_per_step", "retried", "strain_percent", "wall"])
    contact = part_contact(drape, a) if "contact" in a.parts else []
    write_csv(out / "contact.csv", contact, ["case", "steps", "wall_with_s", "wall_without_s", "ratio"])
    strip = part_strip(drape, a) if "strip" in a.parts else []
    write_csv(out / "strip.csv", strip, ["solver", "status", "pc", "sim_per_wall", "cg_per_step", "solves_per_step", "retried", "strain_percent", "wall"])

    def g(r, k):
        return r.get(k, "")

    md = [f"# {PROG}", "", f"Machine: {machine()}", "", f"Command: `python3 scripts/{PROG}.py {' '.join(sys.argv[1:])}`", "",
          "## Stiff cloth, drapebe at 1e-2 s", "",
          md_table(["scene", "N", "scheme", "solver", "outcome", "PC", "sim s / wall s", "CG its/step", "solves/step", "retried", "strain %"],
                   [[r["scene"], r["n"], r["scheme"], r["solver"], r["status"], g(r, "pc"), g(r, "sim_per_wall"), g(r, "cg_per_step"),
                     g(r, "solves_per_step"), g(r, "retried"), g(r, "strain_percent")] for r in stiff]), "",
          "## Measured fabrics, drape's default solver", "",
          md_table(["fabric", "case", "outcome", "PC", "sim s / wall s", "CG its/step", "solves/step", "retried", "strain %"],
                   [[r["fabric"], r["case"], r["status"], g(r, "pc"), g(r, "sim_per_wall"), g(r, "cg_per_step"), g(r, "solves_per_step"),
                     g(r, "retried"), g(r, "strain_percent")] for r in fabrics]), "",
          "## What contact costs (symplectic Euler, the same steps with and without the solid)", "",
          md_table(["case", "steps", "wall with (s)", "wall without (s)", "ratio"],
                   [[r["case"], r["steps"], r["wall_with_s"], r["wall_without_s"], r["ratio"]] for r in contact]), "",
          "## 2.5 cm strip, stretch 1e4 N/m, drapebe at 1e-2 s", "",
          md_table(["solver", "outcome", "PC", "sim s / wall s", "CG its/step", "retried"],
                   [[r["solver"], r["status"], g(r, "pc"), g(r, "sim_per_wall"), g(r, "cg_per_step"), g(r, "retried")] for r in strip]), ""]
    (out / f"{PROG}.md").write_text("\n".join(md))
    print(f"{PROG}: wrote {out}/{{stiff,fabrics,contact,strip}}.csv and {PROG}.md", flush=True)


if __name__ == "__main__":
    main()
