#!/usr/bin/env python3
"""Write the small closed triangle meshes shipped in runs/meshes/ (made by drape).

    python3 scripts/make_meshes.py [outdir]

torus.obj  a torus (R = 0.25 m, r = 0.08 m), OBJ
cone.stl   a cone (base radius 0.2 m, height 0.4 m), ASCII STL
stool.off  a stool: a round seat on three legs (three closed parts), OFF
"""
import math
import sys
from pathlib import Path


def torus(R=0.25, r=0.08, n=48, m=16):
    v = [((R + r * math.cos(b)) * math.cos(a), (R + r * math.cos(b)) * math.sin(a), r * math.sin(b))
         for a in (2 * math.pi * i / n for i in range(n)) for b in (2 * math.pi * j / m for j in range(m))]
    f = []
    for i in range(n):
        for j in range(m):
            a, b = i * m + j, ((i + 1) % n) * m + j
            c, d = ((i + 1) % n) * m + (j + 1) % m, i * m + (j + 1) % m
            f += [(a, b, c), (a, c, d)]
    return v, f


def cylinder(radius, z0, z1, n, cx=0.0, cy=0.0):
    v = [(cx, cy, z0), (cx, cy, z1)]
    v += [(cx + radius * math.cos(2 * math.pi * k / n), cy + radius * math.sin(2 * math.pi * k / n), z) for z in (z0, z1) for k in range(n)]
    f = []
    for k in range(n):
        b0, b1, t0, t1 = 2 + k, 2 + (k + 1) % n, 2 + n + k, 2 + n + (k + 1) % n
        f += [(0, b1, b0), (1, t0, t1), (b0, b1, t1), (b0, t1, t0)]
    return v, f


def cone(radius=0.2, height=0.4, n=48):
    v = [(0.0, 0.0, 0.0), (0.0, 0.0, height)] + [(radius * math.cos(2 * math.pi * k / n), radius * math.sin(2 * math.pi * k / n), 0.0) for k in range(n)]
    f = []
    for k in range(n):
        a, b = 2 + k, 2 + (k + 1) % n
        f += [(0, b, a), (1, a, b)]
    return v, f


def merge(*parts):
    v, f = [], []
    for pv, pf in parts:
        f += [tuple(i + len(v) for i in t) for t in pf]
        v += pv
    return v, f


def write_off(path, v, f):
    with open(path, "w") as out:
        out.write(f"OFF\n{len(v)} {len(f)} 0\n")
        out.writelines(f"{x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in v)
        out.writelines(f"3 {a} {b} {c}\n" for a, b, c in f)


def write_obj(path, v, f):
    with open(path, "w") as out:
        out.write("# drape test mesh\n")
        out.writelines(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in v)
        out.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in f)


def write_stl(path, v, f, name="cone"):
    with open(path, "w") as out:
        out.write(f"solid {name}\n")
        for t in f:
            p = [v[i] for i in t]
            u = [p[1][k] - p[0][k] for k in range(3)]
            w = [p[2][k] - p[0][k] for k in range(3)]
            nrm = (u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0])
            s = math.sqrt(sum(c * c for c in nrm)) or 1.0
            out.write(f"  facet normal {nrm[0] / s:.6g} {nrm[1] / s:.6g} {nrm[2] / s:.6g}\n    outer loop\n")
            out.writelines(f"      vertex {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in p)
            out.write("    endloop\n  endfacet\n")
        out.write(f"endsolid {name}\n")


def main():
    out = Path(sys.argv[1] if len(sys.argv) > 1 else Path(__file__).resolve().parent.parent / "runs" / "meshes")
    out.mkdir(parents=True, exist_ok=True)
    write_obj(out / "torus.obj", *torus())
    write_stl(out / "cone.stl", *cone())
    legs = [cylinder(0.025, -0.45, -0.02, 16, 0.15 * math.cos(a), 0.15 * math.sin(a)) for a in (0.5, 0.5 + 2.094, 0.5 + 4.189)]
    write_off(out / "stool.off", *merge(cylinder(0.22, 0.0, 0.04, 48), *legs))


if __name__ == "__main__":
    main()
