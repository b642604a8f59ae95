#!/usr/bin/env python3
"""Virtual KES tests: shear and tensile rigidity of drape's cloth measured as
Kawabata's KES-FB1 measures a fabric's, by displacing a clamp and reading what the
cloth stores.

The specimen (KES: 20 cm along the clamps, 5 cm between them) lies flat, without
gravity, held by two clamps of k pinned lattice columns (or rows) each. drape pins
particles where they are; a clamp is displaced by writing the displaced positions
into the last frame of a zero-step run and restarting from it (-restart): the free
particles start where they were, drape runs backward Euler with damping to rest, and
the energy at rest gives the rigidity:

    tensile (clamps across the pull): e = Delta / W, E = Y e^2 W H / 2,
    shear (the clamp moved along itself): gamma = Delta / W, E = G gamma^2 W H / 2,

with W the distance between the clamps' inner pinned columns (stretch lives on the
edges and shear on the cells between them: the clamp is its inner column, no
half-cell to account for) and H the clamp length. The tensile state is exact in this
model (no Poisson coupling: every row a chain of equal springs), so drape must return
Y to its solver tolerance. In shear, the specimen's free ends (the clamps' ends) carry
no shear stress, so KES's rectangle stores less than G gamma^2 W H / 2: in an end zone
of a few W the shear relaxes through the threads' stretch (the zone grows with
Y / G). The picture-frame test (--frame: all four edges pinned on a rhombus with
unstretched sides, the trellis) has no free edge: its energy is G gamma^2 W H / 2
exactly, reached from the unsheared interior.

Usage:
    python3 scripts/kes.py                      # denim: tensile warp and weft, shear, picture frame
    python3 scripts/kes.py --fabric polyester --gap-cells 10,20 --aspect 4,8
"""
import argparse
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import drape_h5  # noqa: E402
import drape_run  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def drape_path(build=None):
    """The drape executable of `build` (default $DRAPE_BUILD or build/)."""
    return ROOT / (build or os.environ.get("DRAPE_BUILD", "build")) / "drape"


def _run(drape, args, what):
    """The report of a drape run that must succeed."""
    r = drape_run.run(drape, args, timeout=600)
    if r.returncode != 0 or r.report is None:
        raise RuntimeError(f"drape failed on the {what}: {r.tail()}")
    return r.report


def clamp_test(mode, fabric=("-cloth_fabric", "denim"), gap=10, aspect=4.0, k=2, strain=0.01, h=0.005, drape=None):
    """One virtual KES test. mode: "tensile-warp", "tensile-weft", "shear" (clamps along the
    weft, one moved along it) or "frame" (picture frame). gap: lattice cells between the
    clamps (W = gap h); aspect: H / W; strain: e or gamma. Returns a dict (SI units)."""
    drape = drape or drape_path()
    n_along = max(2, int(round(aspect * gap)))  # cells along the clamps
    W, H = gap * h, n_along * h
    across = gap + 2 * k - 1  # particles between the clamps' outer columns
    along = n_along + 1
    # the pull, or the clamps, along the warp (i) unless tensile-weft
    if mode == "tensile-weft":
        mx, my = along, across
    else:
        mx, my = across, along
    jj, ii = np.mgrid[0:my, 0:mx]
    if mode == "frame":
        mx = my = gap + 1
        W = H = gap * h
        jj, ii = np.mgrid[0:my, 0:mx]
        pinned = (ii == 0) | (ii == mx - 1) | (jj == 0) | (jj == my - 1)
    else:
        c = jj if mode == "tensile-weft" else ii  # coordinate across the clamps
        pinned = (c < k) | (c > c.max() - k)
    pins = ",".join(f"{i},{j}" for j, i in zip(*np.nonzero(pinned)))
    size = ((mx - 1) * h, (my - 1) * h)
    base_opts = [*fabric, "-da_grid_x", str(mx), "-da_grid_y", str(my), "-cloth_size", f"{size[0]!r},{size[1]!r}", "-cloth_center", "0,0,0",
                 "-gravity", "0,0,0", "-cloth_pin", "list", "-cloth_pin_list", pins]
    with tempfile.TemporaryDirectory(prefix="kes_") as tmp:
        base, out = Path(tmp) / "base.h5", Path(tmp) / "rest.h5"
        j = _run(drape, [*base_opts, "-ts_max_steps", "0", "-output_file", str(base)], f"{mode} set-up")
        rho, G, (Yw, Yf) = j["density"], j["shear"], (j["stretch_warp"], j["stretch_weft"])
        with h5py.File(base, "r+") as f:
            x = f["position"][-1]
            if mode == "frame":  # trellis: the warp and the weft turned by gamma/2 towards each other, lengths kept
                a = strain / 2
                u, v = ii * h, jj * h
                trellis = np.stack([u * math.cos(a) + v * math.sin(a), u * math.sin(a) + v * math.cos(a)], -1)
                trellis -= trellis.mean((0, 1)) - x[..., :2].mean((0, 1))
                x[pinned, :2] = trellis[pinned]
            else:
                c = jj if mode == "tensile-weft" else ii
                moved = pinned & (c > c.max() - k)
                Delta = strain * W
                axis = {"tensile-warp": 0, "tensile-weft": 1, "shear": 1}[mode]
                x[moved, axis] += Delta
            f["position"][-1] = x
            f["velocity"][-1] = 0.0
        # the slowest in-plane mode sets the damping and the time to rest
        stiff = {"tensile-warp": Yw, "tensile-weft": Yf, "shear": G, "frame": G}[mode]
        omega = math.pi / (2 * W) * math.sqrt(stiff / rho)
        opts = ["-restart", str(base), "-output_file", str(out), "-ts_max_steps", "100000000", "-ts_type", "drapebe", "-ts_dt", f"{0.2 / omega:.6g}", "-cloth_damping", f"{omega:.6g}",
                "-ts_max_time", f"{2000 / omega:.6g}", "-drape_rest_tol", "1e-14", "-output_interval", f"{2000 / omega:.6g}", "-ksp_rtol", "1e-10",
                "-pc_type", "bjacobi"]
        t0 = time.perf_counter()
        summary = _run(drape, opts, mode)
        wall = time.perf_counter() - t0
        fr = drape_h5.load(out)
        energy = {k: float(fr.energies[k][-1]) for k in ("stretch", "shear", "bend", "kinetic")}
        xr = fr.positions[-1]
    total = energy["stretch"] + energy["shear"] + energy["bend"]
    measured = 2 * total / (strain ** 2 * W * H)
    return {"mode": mode, "gap": gap, "aspect": H / W, "lattice": f"{mx}x{my}", "W": W, "H": H, "strain": strain, "energy": energy,
            "measured": measured, "expected": stiff, "error": measured / stiff - 1, "out_of_plane": float(np.abs(xr[..., 2]).max()),
            "at_rest": summary.get("at_rest"), "t": summary["t"], "wall": wall}


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--modes", default="tensile-warp,tensile-weft,shear,frame")
    p.add_argument("--fabric", default="denim", help="-cloth_fabric NAME")
    p.add_argument("--gap-cells", default="10", help="lattice cells between the clamps")
    p.add_argument("--aspect", default="4", help="clamp length / distance between the clamps (KES: 4)")
    p.add_argument("--strain", type=float, default=0.01, help="tensile strain e or shear angle gamma (rad)")
    p.add_argument("--build", default=None)
    a = p.parse_args()
    print(f"kes: {a.fabric}, strain {a.strain:g}")
    print("| test | gap cells | H/W | lattice | rigidity drape (N/m) | model (N/m) | error | shear, stretch energy (J) | at rest (t s) | wall s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for mode in a.modes.split(","):
        for gap in (int(v) for v in a.gap_cells.split(",")):
            for aspect in ((1.0,) if mode == "frame" else (float(v) for v in a.aspect.split(","))):
                r = clamp_test(mode, ("-cloth_fabric", a.fabric), gap, aspect, strain=a.strain, drape=drape_path(a.build))
                print(f"| {mode} | {gap} | {r['aspect']:g} | {r['lattice']} | {r['measured']:.4g} | {r['expected']:.4g} | {100 * r['error']:+.3f} % "
                      f"| {r['energy']['shear']:.3e}, {r['energy']['stretch']:.3e} | {r['at_rest']} ({r['t']:.3g}) | {r['wall']:.1f} |", flush=True)


if __name__ == "__main__":
    main()
