#!/usr/bin/env python3
"""Virtual cantilever test (Peirce; ASTM D1388, FAST): a drape strip clamped at one end
rests bent by its own weight; its tip is compared with the heavy elastica
(scripts/elastica.py) at the same free length.

The strip. A lattice strip cut along the warp (0 deg: long along i), the weft
(90 deg: long along j) or the bias (45 deg: a rotated rectangle, -cloth_shape polygon,
on a square lattice) of width --width, with n free lattice rows beyond k pinned ones
(-cloth_pin list). Its free length L is chosen so that lambda = w L^3 / B (w = rho g,
B the rigidity of the thread along the strip) is --lam: the deflection is neither
tiny nor past vertical (lambda = 8 puts the chord at 41.5 deg, ASTM's angle).

The discrete clamp. drape bends a thread through the angle at each particle between
its two neighbouring segments: the tangent of a segment sits at its midpoint and a
particle's turning angle is the curvature times a spacing h. Pinning rows 0..k-1
fixes the tangent of the last pinned segment, (k-2, k-1), horizontal: the clamp is
the midpoint of that segment, s_c = (k - 3/2) h from row 0, and not the last pinned
particle. The last row carries half a cell (drape halves the masses and
rigidities of boundary rows), so the strip ends at its last particle, and the free
length is L = (n + 1/2) h. At 45 deg the rows are the lattice's diagonals, h = d/sqrt(2)
for a lattice spacing d, and the same holds thread by thread: every thread's last
pinned particle lies on the same diagonal.

Four pinned rows, not two. A clamp must hold the tangent of every line of triples,
and drape's model has two more families than the threads: the diagonal triples
(i-1,j-1),(i,j),(i+1,j+1) and (i-1,j+1),(i,j),(i+1,j-1). Along a 0 or 90 deg strip
a diagonal advances one row per step, like a thread; along a 45 deg strip it
advances two, so with two pinned rows each diagonal line along the strip has one
pinned particle: it is hinged, not clamped, and the diagonals' part of Bb (6 d/4,
45 % of denim's) carries no moment at the clamp. Such a strip bent at 0.70 Bb at 20
rows and crept towards Bb as the clamp's share of the strip shrank (0.81, 0.87,
0.91 at 40, 80, 160 rows); with four pinned rows it bends at 0.94-0.96 Bb from 20
to 80 rows. Four rows change nothing at 0 and 90 deg.

What is compared. The tip (the mean of the last row's particles) below the clamp
(drop) and beyond it along the strip (reach), against the elastica's at lambda; and
the rigidity the strip shows, B_eff / B = lambda / lambda_eff with lambda_eff the
elastica's lambda for the measured drop (the weight per unit length and the free
length being the strip's own). At 45 deg a real fabric is about as stiff as along
the threads (ARCSim's bias-angle bending data); the paper's model has no twist
rigidity, so a bias strip bends by twisting its threads (at most (Bw + Bf)/4), while
drape's model gives it Bb through its diagonal triples.

Usage:
    python3 scripts/cantilever.py                         # 0, 90, 45 deg at n = 10, 20
    python3 scripts/cantilever.py --angles 0 --rows 10,20,40 --fabric polyester
"""
import argparse
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import drape_h5  # noqa: E402
import drape_run  # noqa: E402
import elastica  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
G = 9.81


def drape_path(build=None):
    """The drape executable of `build` (default $DRAPE_BUILD or build/)."""
    return ROOT / (build or os.environ.get("DRAPE_BUILD", "build")) / "drape"


def material(drape, fabric_args):
    """density, bend_warp, bend_weft, bend_bias of a material (a zero-step run's report)."""
    r = drape_run.run(drape, [*fabric_args, "-da_grid_x", "3", "-da_grid_y", "3", "-ts_max_steps", "0"], timeout=60)
    if r.returncode != 0 or r.report is None:
        raise RuntimeError(f"drape refused the material {' '.join(fabric_args)}: {r.tail()}")
    j = r.report
    return j["density"], j["bend_warp"], j["bend_weft"], j["bend_bias"]


class Strip:
    """Lattice, pins and outline of a strip at `angle` (0, 90 or 45 deg) with n free rows of
    spacing h beyond k pinned ones, `width` wide: which particles are in it, and each
    one's row (0 at the first pinned row) and offset across."""

    def __init__(self, angle, n, k, h, width):
        self.angle, self.n, self.k, self.h = angle, n, k, h
        self.L = (n + 0.5) * h
        self.clamp = (k - 1.5) * h  # along the strip from row 0
        rows = k + n
        if angle in (0, 90):
            across = max(3, int(round(width / h)) + 1)
            self.width = (across - 1) * h
            self.d = h
            mx, my = (rows, across) if angle == 0 else (across, rows)
            self.shape = (my, mx)
            jj, ii = np.mgrid[0:my, 0:mx]
            self.row = ii if angle == 0 else jj
            self.off = (jj if angle == 0 else ii) * h - 0.5 * self.width
            self.active = np.ones(self.shape, dtype=bool)
            self.size = ((mx - 1) * h, (my - 1) * h)
            self.outline = None
        elif angle == 45:
            d = h * math.sqrt(2)  # a thread step moves one diagonal row along the strip
            q = max(1, int(round(width / (2 * h) - 0.5)))
            self.width = (2 * q + 1) * h
            self.d = d
            a = -(rows - 1) // 2  # diagonal index of row 0 (the strip centred on the sheet)
            smax = max(abs(a), abs(a + rows - 1))
            c = (smax + q) // 2 + 1
            m = 2 * c + 1
            self.shape = (m, m)
            jj, ii = np.mgrid[0:m, 0:m]
            sidx, vidx = (ii - c) + (jj - c), (jj - c) - (ii - c)
            self.row = sidx - a
            self.off = vidx * h
            self.active = (self.row >= 0) & (self.row < rows) & (np.abs(vidx) <= q)
            self.size = ((m - 1) * d, (m - 1) * d)
            s0, s1, v = (a - 0.5) * h, (a + rows - 0.5) * h, (q + 0.5) * h  # the cuts fall between particles
            self.outline = [((s - t) / math.sqrt(2), (s + t) / math.sqrt(2)) for s, t in ((s0, -v), (s1, -v), (s1, v), (s0, v))]
        else:
            raise ValueError(f"angle {angle}: the strip is cut at 0, 90 or 45 deg")
        # drape's cloth is the lattice cells inside the outline: a particle that is a
        # corner of no such cell (a spike of the 45 degree cut) is not cloth
        a = self.active
        cell = a[:-1, :-1] & a[1:, :-1] & a[:-1, 1:] & a[1:, 1:]
        corner = np.zeros_like(a)
        for dj in (0, 1):
            for di in (0, 1):
                corner[dj:dj + cell.shape[0], di:di + cell.shape[1]] |= cell
        self.active = corner
        self.pinned = self.active & (self.row < k)
        self.tip = self.active & (self.row == rows - 1)

    def options(self, tmp):
        """drape options for this strip's lattice, shape and pins (writes the outline into tmp)."""
        my, mx = self.shape
        pins = ",".join(f"{i},{j}" for j, i in zip(*np.nonzero(self.pinned)))
        opts = ["-da_grid_x", str(mx), "-da_grid_y", str(my), "-cloth_size", f"{self.size[0]!r},{self.size[1]!r}", "-cloth_center", "0,0,0",
                "-cloth_pin", "list", "-cloth_pin_list", pins]
        if self.outline:
            path = Path(tmp) / "strip45.txt"
            path.write_text("".join(f"{x!r} {y!r}\n" for x, y in self.outline))
            opts += ["-cloth_shape", "polygon", "-cloth_outline", str(path)]
        return opts


def run_case(angle, n, lam=8.0, fabric=("-cloth_fabric", "denim"), k=4, width=0.025, drape=None, keep=None, eta=0.0, stick=None, damping=1.0):
    """Clamp a strip at `angle` with n free rows, lambda = w L^3 / B, run it to rest, compare
    its tip with the elastica's. Returns a dict of the numbers (lengths in m).

    eta > 0: with bending friction (-cloth_bend_hysteresis, 0 or 90 deg), HB = eta B / L
    in the strip's direction and the stick stiffness `stick` x B (drape's default if
    None); the reference is then the strip's first loading under that law
    (elastica.solve_law with elastica.grosberg_law), which a strip released from flat
    follows only if it does not swing back: give damping (times the first mode's
    frequency) well above 2, an overdamped fall."""
    drape = drape or drape_path()
    rho, bw, bf, bb = material(drape, list(fabric))
    B = {0: bw, 90: bf, 45: bb}[angle]  # at 45 deg: the bias rigidity
    w = rho * G
    L = (lam * B / w) ** (1 / 3)
    strip = Strip(angle, n, k, L / (n + 0.5), width)
    omega = 3.516 * math.sqrt(B / (rho * L ** 4))  # first bending mode of the clamped strip
    friction = []
    if eta > 0:
        if angle not in (0, 90):
            raise ValueError("bending friction acts along the threads: a strip at 0 or 90 degrees")
        hb = [0.0, 0.0]
        hb[0 if angle == 0 else 1] = eta * B / L
        friction = ["-cloth_bend_hysteresis", f"{2 * hb[0]:.9g},{2 * hb[1]:.9g}"]
        if stick is not None:
            friction += ["-cloth_bend_hysteresis_stiffness", f"{stick:g}"]
    with tempfile.TemporaryDirectory(prefix="cantilever_") as tmp:
        out = Path(keep) if keep else Path(tmp) / "strip.h5"
        opts = [*fabric, *friction, *strip.options(tmp), "-cloth_damping", f"{damping * omega:.6g}", "-ts_type", "drapebe", "-ts_dt", f"{0.1 / omega:.6g}",
                "-ts_max_time", f"{400 * max(1.0, damping) / omega:.6g}", "-drape_rest_tol", "1e-10", "-output_interval", f"{400 * max(1.0, damping) / omega:.6g}",
                "-output_file", str(out)]
        t0 = time.perf_counter()
        r = drape_run.run(drape, opts, timeout=600)
        wall = time.perf_counter() - t0
        if r.returncode != 0 or r.report is None:
            raise RuntimeError(f"drape failed on the {angle} deg strip: {r.tail()}")
        summary = r.report
        fr = drape_h5.load(out)
        x, x0 = fr.positions[-1], fr.positions[0]  # [My][Mx][3]
    # the strip's axis in the plane, from its initial positions
    axis = {0: np.array([1.0, 0.0]), 90: np.array([0.0, 1.0]), 45: np.array([1.0, 1.0]) / math.sqrt(2)}[angle]
    s0 = x0[..., :2] @ axis
    row0 = s0[strip.pinned & (strip.row == 0)].mean()
    clamp_s = row0 + strip.clamp
    z0 = x0[strip.pinned, 2].mean()
    drop = float(z0 - x[strip.tip, 2].mean())
    reach = float((x[strip.tip, :2] @ axis).mean() - clamp_s)
    if eta > 0:
        if stick is None:  # drape's default, from its report
            stick = summary["hysteresis_stiffness"]
        e = elastica.solve_law(lam, elastica.grosberg_law(eta, stick))
    else:
        e = elastica.solve(lam)
    lam_eff = elastica.lam_for(drop / L, "drop")
    return {"angle": angle, "rows": n, "h": strip.h, "lattice": f"{strip.shape[1]}x{strip.shape[0]}", "particles": int(strip.active.sum()),
            "width": strip.width, "L": L, "lam": lam, "B": B, "drop": drop, "reach": reach, "drop_elastica": e.drop * L, "reach_elastica": e.reach * L,
            "drop_err": drop / (e.drop * L) - 1, "reach_err": reach / (e.reach * L) - 1, "B_eff_ratio": lam / lam_eff,
            "at_rest": summary.get("at_rest"), "t": summary["t"], "strain_max": summary["strain_max"], "wall": wall}


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--angles", default="0,90,45", help="strip angles to the warp: 0, 90, 45 (deg)")
    p.add_argument("--rows", default="10,20", help="free lattice rows n (resolution)")
    p.add_argument("--lam", type=float, default=8.0, help="w L^3 / B (8: chord at 41.5 deg)")
    p.add_argument("--width", type=float, default=0.025, help="strip width (m; ASTM D1388: 25 mm)")
    p.add_argument("--pinned", type=int, default=4, help="pinned rows k (>= 2; 4 clamp every diagonal of a 45 degree strip)")
    p.add_argument("--fabric", default="denim", help="-cloth_fabric NAME (density and B)")
    p.add_argument("--build", default=None, help="build directory (default $DRAPE_BUILD or build)")
    a = p.parse_args()
    if a.pinned < 2:
        p.error("--pinned must be at least 2: the clamp is the tangent of the last pinned segment")
    print(f"cantilever: {a.fabric}, lambda = w L^3 / B = {a.lam:g}, width {1e3 * a.width:g} mm, {a.pinned} pinned rows")
    print("| angle | rows n | lattice | L (mm) | drop drape / elastica (mm) | error | reach drape / elastica (mm) | error | B_eff / B | at rest (t s) | wall s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for angle in (int(v) for v in a.angles.split(",")):
        for n in (int(v) for v in a.rows.split(",")):
            r = run_case(angle, n, a.lam, ("-cloth_fabric", a.fabric), a.pinned, a.width, drape_path(a.build))
            print(f"| {angle} | {n} | {r['lattice']} | {1e3 * r['L']:.2f} | {1e3 * r['drop']:.3f} / {1e3 * r['drop_elastica']:.3f} | {100 * r['drop_err']:+.2f} % "
                  f"| {1e3 * r['reach']:.3f} / {1e3 * r['reach_elastica']:.3f} | {100 * r['reach_err']:+.2f} % | {r['B_eff_ratio']:.3f} "
                  f"| {r['at_rest']} ({r['t']:.2f}) | {r['wall']:.1f} |", flush=True)


if __name__ == "__main__":
    main()
