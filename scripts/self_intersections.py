#!/usr/bin/env python3
"""Count the self-intersections of drape's cloth, frame by frame (for checking self-contact).

    self_intersections.py out/fold.h5              # every frame: frame, time, count; then the max
    self_intersections.py out/fold.h5 --every 10   # every 10th frame (and the last)

    import self_intersections as si
    si.count("out/fold.h5")                        # [0, 0, 3, ...] piercings per frame
    tris, edges = si.mesh(run.active)
    si.piercings(run.positions[-1].reshape(-1, 3), tris, edges)   # [k, 2] (edge, triangle)

The mesh. Each lattice cell (i, j) whose four corners are active (-cloth_shape) is
two triangles split along the diagonal (i, j)-(i+1, j+1): [(i, j), (i+1, j),
(i+1, j+1)] and [(i, j), (i+1, j+1), (i, j+1)], on the flat particle number j Mx + i
(the index of run.positions[f].reshape(-1, 3)). The edges are those of the
triangles, each once: warp (i, j)-(i+1, j), weft (i, j)-(i, j+1) and the cells'
diagonals; a full Mx x My lattice has (Mx-1) My + Mx (My-1) + (Mx-1)(My-1).

What is counted. A piercing is a pair (edge, triangle) sharing no particle where
the edge's segment crosses the triangle's interior: its ends strictly on either side
of the triangle's plane, the crossing point strictly inside. Where two pieces of
cloth pass through each other, the curve along which they cross runs through one
piercing per edge it cuts, so the count grows with the length of that curve
(in lattice spacings). Touching is not piercing: a crossing at a parameter t along
the edge within 1e-12 of its ends, or with a barycentric coordinate within 1e-12
of the triangle's boundary, is not counted, nor is an edge in the triangle's plane
(cloth folded flat onto itself, layers touching, is 0). A segment can meet a
triangle it shares a particle with only at that particle, so such pairs are never
tested. An intersection curve that passes exactly through a particle or along an
edge is missed there; a real frame is not that exact.

How. A uniform grid (cells about a triangle's size) buckets the bounding boxes of
the triangles and the edges; a pair is tested once, in the grid cell of the low
corner of the intersection of their boxes, and only if the boxes overlap. All of it
is vectorised numpy: a 61 x 61 frame of a drape run takes ~0.03 s, a random crumple
of it (edges stretched 2.5-13x, 2500-23000 piercings) 0.1-0.4 s; 101 x 101 about
2-2.5 times that. Non-finite positions
(a blown-up run) raise ValueError (the CLI: a one-line error, exit status 2).
"""

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import drape_h5  # noqa: E402

EPS = 1e-12  # touching tolerance, relative (edge parameter and barycentric coordinates)


def mesh(active):
    """Triangles and edges of the cloth lattice `active` [My, Mx] (bool).

    Returns (tris [2 ncells, 3], edges [ne, 2]), int64 flat particle numbers j Mx + i;
    the two triangles of a cell are consecutive, cells in lattice order (j, then i);
    each edge is (lower number, higher number), sorted, once."""
    active = np.asarray(active, dtype=bool)
    my, mx = active.shape
    num = np.arange(my * mx, dtype=np.int64).reshape(my, mx)
    cell = active[:-1, :-1] & active[:-1, 1:] & active[1:, :-1] & active[1:, 1:]  # [My-1, Mx-1]
    jj, ii = np.nonzero(cell)
    a, b, c, d = num[jj, ii], num[jj, ii + 1], num[jj + 1, ii + 1], num[jj + 1, ii]
    tris = np.stack([np.stack([a, b, c], 1), np.stack([a, c, d], 1)], axis=1).reshape(-1, 3)
    # a warp edge (i, j)-(i+1, j) bounds the cells (i, j) and (i, j-1); a weft edge
    # (i, j)-(i, j+1) the cells (i, j) and (i-1, j)
    warp = np.zeros((my, mx - 1), dtype=bool) if mx > 1 else np.zeros((my, 0), dtype=bool)
    weft = np.zeros((my - 1, mx), dtype=bool) if my > 1 else np.zeros((0, mx), dtype=bool)
    if cell.size:
        warp[:-1] |= cell
        warp[1:] |= cell
        weft[:, :-1] |= cell
        weft[:, 1:] |= cell
    wj, wi = np.nonzero(warp)
    fj, fi = np.nonzero(weft)
    edges = np.concatenate([np.stack([num[wj, wi], num[wj, wi + 1]], 1),
                            np.stack([num[fj, fi], num[fj + 1, fi]], 1),
                            np.stack([a, c], 1)]).reshape(-1, 2)
    order = np.lexsort((edges[:, 1], edges[:, 0]))
    return tris.reshape(-1, 3), edges[order]


def _boxes(x, items):
    """Bounding boxes (lo, hi) [m, 3] of the simplices `items` [m, k] of the points x."""
    p = x[items]  # [m, k, 3]
    return p.min(axis=1), p.max(axis=1)


def _cells(c0, c1, dims):
    """Grid cells covered by boxes spanning the cells c0..c1 [m, 3]: (owner [n], cell key
    [n], low [n]: bit d set where the cell is the box's first along axis d)."""
    n = c1 - c0 + 1  # [m, 3] cells per axis
    cnt = n.prod(axis=1)
    owner = np.repeat(np.arange(len(c0), dtype=np.int32), cnt)
    k = np.arange(int(cnt.sum()), dtype=np.int64) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    nn = n[owner]
    dz = k % nn[:, 2]
    k //= nn[:, 2]
    dy = k % nn[:, 1]
    dx = k // nn[:, 1]
    c = c0[owner]
    key = ((c[:, 0] + dx) * dims[1] + c[:, 1] + dy) * dims[2] + c[:, 2] + dz
    low = ((dx == 0) | (dy == 0) << 1 | (dz == 0) << 2).astype(np.int8)
    return owner, key, low


def _grid(tlo, thi, elo, ehi):
    """Origin, cell size and dimensions of the broad phase's grid: cells the size of
    the mean triangle's box, or larger if the boxes would cover too many cells."""
    origin = np.minimum(tlo.min(axis=0), elo.min(axis=0))
    top = np.maximum(thi.max(axis=0), ehi.max(axis=0))
    span = float((top - origin).max())
    h = float((thi - tlo).max(axis=1).mean())
    if not h > 0:
        h = span if span > 0 else 1.0
    budget = 16 * (len(tlo) + len(elo)) + 1000
    while True:
        dims = np.floor((top - origin) / h).astype(np.int64) + 1
        # cells per box, counted in floating point (no overflow), against a budget
        ntc = np.prod(np.floor((thi - origin) / h) - np.floor((tlo - origin) / h) + 1, axis=1).sum()
        nec = np.prod(np.floor((ehi - origin) / h) - np.floor((elo - origin) / h) + 1, axis=1).sum()
        if np.prod(dims.astype(float)) < 2.0**62 and ntc + nec <= budget:
            return origin, h, dims
        h *= 2


def _candidates(x, tris, edges):
    """(edge, triangle) pairs whose bounding boxes overlap, each once, sharing no particle."""
    tlo, thi = _boxes(x, tris)
    elo, ehi = _boxes(x, edges)
    origin, h, dims = _grid(tlo, thi, elo, ehi)
    town, tkey, tlow = _cells(*(np.floor((v - origin) / h).astype(np.int64) for v in (tlo, thi)), dims)
    eown, ekey, elow = _cells(*(np.floor((v - origin) / h).astype(np.int64) for v in (elo, ehi)), dims)
    # A pair of boxes is taken in one of the cells they share: that of the low corner of
    # their intersection, max(lo), the first cell of the edge's box or the triangle's
    # along each axis. The triangles' entries sorted by (low, cell) make 8 groups; an
    # edge entry pairs with the groups that complete its own low bits.
    order = np.lexsort((tkey, tlow))
    town, tkey = town[order], tkey[order]
    bounds = np.searchsorted(tlow[order], np.arange(9))
    es, ts = [], []
    for g in range(8):
        lo, hi = bounds[g], bounds[g + 1]
        sel = np.flatnonzero((elow | g) == 7)
        if hi == lo or len(sel) == 0:
            continue
        keys = tkey[lo:hi]
        first = np.searchsorted(keys, ekey[sel], side="left")
        cnt = np.searchsorted(keys, ekey[sel], side="right") - first
        es.append(eown[np.repeat(sel, cnt)])
        ts.append(town[lo + np.arange(int(cnt.sum())) + np.repeat(first - (np.cumsum(cnt) - cnt), cnt)])
    if not es:
        return np.zeros(0, dtype=np.int32), np.zeros(0, dtype=np.int32)
    e, t = np.concatenate(es), np.concatenate(ts)
    for d in range(3):  # the boxes overlap
        keep = (elo[:, d][e] <= thi[:, d][t]) & (tlo[:, d][t] <= ehi[:, d][e])
        e, t = e[keep], t[keep]
    ev, tv = edges[e], tris[t]
    shared = (ev[:, :1] == tv).any(axis=1) | (ev[:, 1:] == tv).any(axis=1)
    return e[~shared], t[~shared]


def piercings(x, tris, edges):
    """Pairs (edge, triangle) where an edge pierces a triangle sharing no particle with it.

    x [N, 3] positions, tris [nt, 3] and edges [ne, 2] particle numbers (as from mesh()).
    Returns int64 [k, 2]: (row of edges, row of tris), sorted. A crossing within EPS
    (relative) of an end of the edge or of the triangle's boundary, or an edge lying in
    the triangle's plane, is touching and not counted. Raises ValueError if a position
    of the mesh is not finite."""
    x = np.asarray(x, dtype=float)
    tris = np.asarray(tris, dtype=np.int64).reshape(-1, 3)
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    if len(tris) == 0 or len(edges) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    used = np.unique(np.concatenate([tris.ravel(), edges.ravel()]))
    if not np.isfinite(x[used]).all():
        raise ValueError("non-finite particle positions")
    e, t = _candidates(x, tris, edges)
    # narrow phase, relative to the triangle's first corner A
    a = x[tris[t, 0]]
    b = x[tris[t, 1]] - a
    c = x[tris[t, 2]] - a
    p = x[edges[e, 0]] - a
    q = x[edges[e, 1]] - a
    n = np.cross(b, c)
    sp = np.einsum("ij,ij->i", n, p)
    sq = np.einsum("ij,ij->i", n, q)
    keep = np.sign(sp) * np.sign(sq) < 0  # ends strictly on either side (in the plane: both 0)
    e, t, b, c, n, p, q, sp, sq = e[keep], t[keep], b[keep], c[keep], n[keep], p[keep], q[keep], sp[keep], sq[keep]
    s = sp / (sp - sq)  # where the segment meets the plane, 0 < s < 1
    y = p + s[:, None] * (q - p)
    nn = np.einsum("ij,ij->i", n, n)
    lb = np.einsum("ij,ij->i", n, np.cross(y, c)) / nn  # y = lb b + lc c
    lc = np.einsum("ij,ij->i", n, np.cross(b, y)) / nn
    keep = (s > EPS) & (s < 1 - EPS) & (lb > EPS) & (lc > EPS) & (1 - lb - lc > EPS)
    out = np.stack([e[keep], t[keep]], axis=1).astype(np.int64)
    return out[np.lexsort((out[:, 1], out[:, 0]))]


def count(path, frames=None):
    """Number of piercings in each frame of the drape HDF5 file `path` (all frames by
    default, else the frame indices `frames`, negative from the end): a list of int."""
    run = drape_h5.load(path)
    tris, edges = mesh(run.active)
    frames = range(run.nframes) if frames is None else frames
    return [len(piercings(run.positions[f].reshape(-1, 3), tris, edges)) for f in frames]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("file", help="drape HDF5 output (-output_file)")
    ap.add_argument("--every", type=int, default=1, help="every K-th frame (and the last); default every frame")
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
    frames = list(range(0, n, args.every))
    if frames[-1] != n - 1:
        frames.append(n - 1)
    tris, edges = mesh(run.active)
    my, mx = run.shape
    print(f"# {args.file}: {mx} x {my} lattice, {len(tris)} triangles, {len(edges)} edges, {len(frames)} of {n} frames")
    print("# frame  time (s)  piercings")
    counts = []
    for f in frames:
        try:
            k = len(piercings(run.positions[f].reshape(-1, 3), tris, edges))
        except ValueError as e:
            ap.error(f"{args.file}: frame {f}: {e}")
        counts.append(k)
        print(f"{f:7d} {run.time[f]:9.6g} {k:10d}")
    worst = int(np.argmax(counts))
    print(f"max {counts[worst]} piercings at frame {frames[worst]} (t = {run.time[frames[worst]]:.6g} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
