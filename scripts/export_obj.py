#!/usr/bin/env python3
"""Export drape frames as Wavefront OBJ meshes (for Blender and other renderers).

    export_obj.py out/sphere.h5 -o objs/             # last frame: objs/cloth_00128.obj
    export_obj.py out/sphere.h5 -o objs/ --frame 0   # objs/cloth_00000.obj
    export_obj.py out/sphere.h5 -o objs/ --all       # every frame: cloth_00000.obj ...

A cloth file holds the particles of the cloth as vertices ("v x y z", in lattice
order j then i, only the active particles of a circle specimen) and two triangles
per lattice cell whose four corners are active ("f a b c", 1-based), counter-
clockwise seen from +z for a horizontal sheet. --normals adds smooth vertex
normals ("vn"), --uv texture coordinates ("vt": u = i/(Mx-1), v = j/(My-1)).
The solid of the scene (/solid_triangles) goes once to solid.obj (shared
vertices merged) and a -solid_floor plane to floor.obj (a square under the
cloth). Bad input gives a one-line error and exit status 2.
"""

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import drape_h5  # noqa: E402


def cloth_mesh(active):
    """Vertex numbering and triangles of the cloth lattice.

    Returns (index [My, Mx] int, -1 for inactive particles; triangles [2 ncells, 3],
    0-based vertex numbers; the two triangles of each active cell are consecutive)."""
    my, mx = active.shape
    index = np.full((my, mx), -1, dtype=np.int64)
    index[active] = np.arange(int(active.sum()))
    cell = active[:-1, :-1] & active[:-1, 1:] & active[1:, 1:] & active[1:, :-1]
    jj, ii = np.nonzero(cell)
    a, b = index[jj, ii], index[jj, ii + 1]
    c, d = index[jj + 1, ii + 1], index[jj + 1, ii]
    tri = np.stack([np.stack([a, b, c], 1), np.stack([a, c, d], 1)], axis=1).reshape(-1, 3)
    return index, tri


def vertex_normals(v, tri):
    """Area-weighted unit normals at the vertices v [n, 3] of triangles tri [m, 3]."""
    fn = np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]])
    n = np.zeros_like(v)
    for k in range(3):
        np.add.at(n, tri[:, k], fn)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.where(length > 0, n / np.where(length > 0, length, 1), [0.0, 0.0, 1.0])


def write_obj(path, v, tri, header=(), normals=None, uv=None, name=None):
    """Write vertices v [n, 3] and 0-based triangles tri [m, 3] to the OBJ file `path`."""
    fmt = "%.9g"
    with open(path, "w") as f:
        for line in header:
            f.write(f"# {line}\n")
        if name:
            f.write(f"o {name}\n")
        np.savetxt(f, v, fmt=f"v {fmt} {fmt} {fmt}")
        if uv is not None:
            np.savetxt(f, uv, fmt=f"vt {fmt} {fmt}")
        if normals is not None:
            np.savetxt(f, normals, fmt=f"vn {fmt} {fmt} {fmt}")
        t = tri + 1
        if normals is not None and uv is not None:
            faces = np.repeat(t, 3, axis=1)
            np.savetxt(f, faces, fmt="f %d/%d/%d %d/%d/%d %d/%d/%d")
        elif normals is not None:
            np.savetxt(f, np.repeat(t, 2, axis=1), fmt="f %d//%d %d//%d %d//%d")
        elif uv is not None:
            np.savetxt(f, np.repeat(t, 2, axis=1), fmt="f %d/%d %d/%d %d/%d")
        else:
            np.savetxt(f, t, fmt="f %d %d %d")


def merge_vertices(tri):
    """Triangle soup [m, 3, 3] -> (vertices [n, 3], triangles [m, 3]) with equal vertices shared."""
    v, inverse = np.unique(tri.reshape(-1, 3), axis=0, return_inverse=True)
    return v, inverse.reshape(-1, 3)


def export(run, outdir, frames, normals=False, uv=False, log=print):
    """Write cloth_NNNNN.obj for each frame of `frames`, solid.obj and floor.obj; return the paths."""
    os.makedirs(outdir, exist_ok=True)
    index, tri = cloth_mesh(run.active)
    my, mx = run.shape
    texture = None
    if uv:
        jj, ii = np.nonzero(run.active)
        texture = np.c_[ii / max(mx - 1, 1), jj / max(my - 1, 1)]
    width = max(5, len(str(run.nframes - 1)))
    written = []
    for k in frames:
        v = run.positions[k][run.active]
        path = os.path.join(outdir, f"cloth_{k:0{width}d}.obj")
        write_obj(path, v, tri, name="cloth", normals=vertex_normals(v, tri) if normals else None, uv=texture,
                  header=[f"drape cloth: {os.path.basename(run.path)}, frame {k}, t = {run.time[k]:.9g} s, "
                          f"step {run.step[k]}", f"{len(v)} vertices (of a {mx} x {my} lattice), "
                          f"{len(tri)} triangles (2 per lattice cell)"])
        written.append(path)
    if run.solid_triangles is not None:
        v, t = merge_vertices(run.solid_triangles)
        path = os.path.join(outdir, "solid.obj")
        write_obj(path, v, t, name="solid", normals=vertex_normals(v, t) if normals else None,
                  header=[f"drape solid: {os.path.basename(run.path)} /solid_triangles", f"{len(v)} vertices, {len(t)} triangles"])
        written.append(path)
    if run.floor is not None:
        pts = run.positions[list(frames)][:, run.active].reshape(-1, 3)
        if run.solid_triangles is not None:
            pts = np.concatenate([pts, run.solid_triangles.reshape(-1, 3)])
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        pad = 0.5 * max(hi[:2] - lo[:2])
        z = run.floor
        v = np.array([[lo[0] - pad, lo[1] - pad, z], [hi[0] + pad, lo[1] - pad, z],
                      [hi[0] + pad, hi[1] + pad, z], [lo[0] - pad, hi[1] + pad, z]])
        path = os.path.join(outdir, "floor.obj")
        write_obj(path, v, np.array([[0, 1, 2], [0, 2, 3]]), name="floor",
                  header=[f"drape floor: -solid_floor {z:g} of {os.path.basename(run.path)} (a square under the scene)"])
        written.append(path)
    return written


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("file", help="drape HDF5 output (-output_file)")
    ap.add_argument("-o", "--outdir", required=True, help="directory for the OBJ files (created if missing)")
    which = ap.add_mutually_exclusive_group()
    which.add_argument("--frame", type=int, help="frame index, negative counts from the end (default: the last)")
    which.add_argument("--all", action="store_true", help="every frame")
    ap.add_argument("--every", type=int, default=1, help="with --all: every N-th frame (and the last)")
    ap.add_argument("--normals", action="store_true", help="write vertex normals (vn)")
    ap.add_argument("--uv", action="store_true", help="write texture coordinates (vt) from the lattice indices")
    args = ap.parse_args(argv)
    if args.every < 1:
        ap.error(f"--every must be at least 1; got {args.every}")

    try:
        run = drape_h5.load(args.file)
    except ValueError as e:
        ap.error(str(e))
    except OSError as e:
        ap.error(f"{args.file}: cannot read ({e})")
    n = run.nframes
    if n == 0:
        ap.error(f"{args.file}: no complete frame")
    if args.all:
        frames = list(range(0, n, args.every))
        if frames[-1] != n - 1:
            frames.append(n - 1)
    else:
        frame = -1 if args.frame is None else args.frame
        if not -n <= frame < n:
            ap.error(f"--frame {frame} out of range: {args.file} has {n} frame(s) (valid {-n}..{n - 1})")
        frames = [frame % n]
    if os.path.exists(args.outdir) and not os.path.isdir(args.outdir):
        ap.error(f"{args.outdir}: exists and is not a directory")
    try:
        written = export(run, args.outdir, frames, normals=args.normals, uv=args.uv)
    except OSError as e:
        ap.error(f"cannot write to {args.outdir}: {e.strerror or e}")
    extra = [os.path.basename(p) for p in written[len(frames):]]
    print(f"export_obj: wrote {len(frames)} cloth file(s) to {args.outdir} "
          f"({os.path.basename(written[0])}{' .. ' + os.path.basename(written[len(frames) - 1]) if len(frames) > 1 else ''})"
          + (f" and {', '.join(extra)}" if extra else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
