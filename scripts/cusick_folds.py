#!/usr/bin/env python3
"""The Cusick skirt's folds and drape coefficient frame by frame: when did the fold
count settle? (not a test)

    cusick_folds.py out/cusick.h5               # every frame: t, folds, DC, largest strain
    cusick_folds.py out/cusick.h5 --every 10    # every 10th frame (and the last)
    cusick_folds.py a.h5 b.h5 --label A --label B --plot folds.png   # several runs, and a plot

    import cusick_folds
    cusick_folds.history("out/cusick.h5")       # [(frame, t, folds, DC, strain), ...]

drape reports DC and the folds of its last frame only (src/analysis/cusick.c). Here
the same analysis of any frame, step by step as drape makes it: the lattice cells
whose four corners are active, two triangles each, projected on the horizontal
plane; the pixels of a 1200 x 1200 raster (over a square of 1.2 times the specimen's
diagonal about the pedestal's centre) whose centres lie in one; their area; each of
720 angle bins' largest covered radius; the folds the peaks of that outline (a
moving average over 13 bins) that stand a tenth of the overhang (at least 1.5
spacings) above the valleys on either side; DC = (A - A_disc) / (A_flat - A_disc),
A_flat the first frame's (the flat specimen). The same operations in the same order
in double precision: the last frame's DC and folds are the run's report's (the last
line prints both; tests/test_scripts.py).

The pedestal's centre and radius, the specimen's size and the lattice's spacing come
from the run's own options (-cusick_center, -cusick_pedestal_radius, -cloth_size).
Frames are read one at a time: a 641^2 run's 3 GB file needs one frame's memory
(about 4 s a frame at 641^2 here, 0.1 s at 81^2).
"""

import argparse
import os
import sys

import h5py
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import drape_h5  # noqa: E402

PROG = "cusick_folds"
BINS = 720  # drape's CUSICK_BINS
PIXELS = 1200  # and CUSICK_PIXELS
SMALL = 8  # silhouette(): triangles whose boxes span fewer pixels a side are rasterised together


def triangles(active):
    """The silhouette's triangles, as drape's CusickAnalyse takes them: each lattice
    cell whose four corners are active, corners q = (i, j), (i+1, j), (i+1, j+1), (i, j+1),
    split into (q0, q1, q2) and (q0, q2, q3); [ntri, 3] flat particle numbers j Mx + i."""
    my, mx = active.shape
    cell = active[:-1, :-1] & active[:-1, 1:] & active[1:, 1:] & active[1:, :-1]
    j, i = np.nonzero(cell)
    q = np.stack([j * mx + i, j * mx + i + 1, (j + 1) * mx + i + 1, (j + 1) * mx + i], axis=1)
    return np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])  # (their order: the raster is their union)


def silhouette(xy, tri, centre, extent, npixels=PIXELS, bins=BINS):
    """drape's SilhouetteCover and SilhouetteMeasure: the pixels (npixels^2 over the
    square of half-width extent about centre) whose centres lie in a projected
    triangle, the same tests in the same order; their area and each angle bin's
    largest covered radius."""
    px = 2 * extent / npixels
    x0, y0 = centre[0] - extent, centre[1] - extent
    p = xy[tri]  # [ntri, 3, 2]
    det = (p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) - (p[:, 2, 0] - p[:, 0, 0]) * (p[:, 1, 1] - p[:, 0, 1])
    p = p[det != 0]
    det = det[det != 0]
    lo, hi = p.min(axis=1), p.max(axis=1)
    i0 = np.maximum(0, np.floor((lo[:, 0] - x0) / px).astype(np.int64))
    i1 = np.minimum(npixels - 1, np.floor((hi[:, 0] - x0) / px).astype(np.int64))
    j0 = np.maximum(0, np.floor((lo[:, 1] - y0) / px).astype(np.int64))
    j1 = np.minimum(npixels - 1, np.floor((hi[:, 1] - y0) / px).astype(np.int64))
    cover = np.zeros(npixels * npixels, dtype=bool)

    def mark(k, i, j):  # the pixels (i, j) of triangles k whose centres lie in them
        qx, qy = x0 + (i + 0.5) * px, y0 + (j + 0.5) * px
        a = p[k]
        l1 = ((a[:, 1, 0] - qx) * (a[:, 2, 1] - qy) - (a[:, 2, 0] - qx) * (a[:, 1, 1] - qy)) / det[k]
        l2 = ((a[:, 2, 0] - qx) * (a[:, 0, 1] - qy) - (a[:, 0, 0] - qx) * (a[:, 2, 1] - qy)) / det[k]
        inside = (l1 >= 0) & (l2 >= 0) & (l1 + l2 <= 1)
        cover[j[inside] * npixels + i[inside]] = True

    # triangles within SMALL x SMALL pixels: all at once, pixel by pixel of their boxes;
    # a larger one (a coarse lattice's, a torn frame's) alone, its box at once
    small = (i1 - i0 < SMALL) & (j1 - j0 < SMALL)
    ks = np.flatnonzero(small)
    for dj in range(int((j1[ks] - j0[ks]).max(initial=-1)) + 1):
        for di in range(int((i1[ks] - i0[ks]).max(initial=-1)) + 1):
            k = ks[(j0[ks] + dj <= j1[ks]) & (i0[ks] + di <= i1[ks])]
            mark(k, i0[k] + di, j0[k] + dj)
    for t in np.flatnonzero(~small):
        j, i = np.mgrid[j0[t] : j1[t] + 1, i0[t] : i1[t] + 1]
        mark(np.full(i.size, t), i.ravel(), j.ravel())
    j, i = np.divmod(np.flatnonzero(cover), npixels)
    qx, qy = x0 + (i + 0.5) * px - centre[0], y0 + (j + 0.5) * px - centre[1]
    r = np.sqrt(qx * qx + qy * qy)
    b = np.minimum(bins - 1, ((np.arctan2(qy, qx) + np.pi) / (2 * np.pi) * bins).astype(np.int64))
    radius = np.zeros(bins)
    np.maximum.at(radius, b, r)
    return len(i) * px * px, radius


def count_folds(radius, prominence):
    """drape's CusickCountFolds: a circular moving average over 2 w + 1 bins (w =
    bins / 120), then from the lowest bin around, a fold at each peak that rises
    `prominence` above the last valley and falls as much after it."""
    n = len(radius)
    w = max(1, n // 120)
    r = sum(np.roll(radius, k) for k in range(-w, w + 1)) / (2 * w + 1)
    start = int(np.argmin(r))
    valley = peak = r[start]
    rising, folds = True, 0
    for k in range(1, n + 1):
        v = r[(start + k) % n]
        if rising:
            if v > peak:
                peak = v
            elif peak - v >= prominence and peak - valley >= prominence:
                folds += 1
                rising, valley = False, v
        else:
            if v < valley:
                valley = v
            elif v - valley >= prominence:
                rising, peak = True, v
    return folds


class Error(Exception):
    """A file or run this analysis cannot take (one sentence)."""


def history(path, every=1):
    """[(frame, t, folds, DC, largest strain or None)] of every `every`-th frame of the
    run in path, and its last; raises Error."""
    if every < 1:
        raise Error(f"--every {every}: give 1 or more")
    try:
        run = drape_h5.load(path, frames=False)
    except ValueError as e:
        raise Error(str(e)) from None
    pedestal = number_option(run, "cusick_pedestal_radius", [0.0])[0]
    if not pedestal > 0:
        raise Error(f"{path}: the run has no Cusick pedestal (-cusick_pedestal_radius)")
    centre = np.array((number_option(run, "cusick_center", [0.0, 0.0]) * 2)[:2], dtype=float)
    size = (number_option(run, "cloth_size", [1.0]) * 2)[:2]
    my, mx = run.active.shape
    spacing = max(size[0] / max(1, mx - 1), size[1] / max(1, my - 1))
    prominence = max(0.1 * (0.5 * min(size) - pedestal), 1.5 * spacing)
    extent = 0.6 * np.hypot(size[0], size[1])
    disc = np.pi * pedestal**2
    tri = triangles(run.active)
    rows = []
    with h5py.File(path, "r", locking=False) as f:
        pos = f["position"]
        n = run.nframes
        flat, _ = silhouette(pos[0].reshape(-1, 3)[:, :2], tri, centre, extent)
        for k in sorted(set(range(0, n, every)) | {n - 1}):
            x = pos[k].reshape(-1, 3)
            if not np.isfinite(x[run.active.reshape(-1)]).all():
                raise Error(f"{path}: frame {k} has positions that are not finite")
            covered, radius = silhouette(x[:, :2], tri, centre, extent)
            strain = float(run.strain_max[k]) if run.strain_max is not None else None
            rows.append((k, float(run.time[k]), count_folds(radius, prominence), (covered - disc) / (flat - disc), strain))
    return rows


def number_option(run, name, default):
    """The numbers of an option of the run (comma-separated), or default."""
    value = run.option(name)
    if value is None:
        return default
    try:
        return [float(v) for v in str(value).split(",")]
    except ValueError:
        raise Error(f"{run.path}: option -{name} is not a number: {value!r}") from None


def plot(histories, path, t_max=None):
    """Folds, DC and the largest edge strain against t, a line per run."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(3, 1, figsize=(7, 7.5), sharex=True)
    for label, rows in histories:
        t = [r[1] for r in rows]
        axes[0].step(t, [r[2] for r in rows], where="post", label=label)
        axes[1].plot(t, [r[3] for r in rows], label=label)
        if all(r[4] is not None for r in rows):
            axes[2].plot(t, [100 * r[4] for r in rows], label=label)
    axes[0].set_ylabel("folds")
    axes[1].set_ylabel("drape coefficient")
    axes[2].set_ylabel("largest edge strain (%)")
    axes[2].set_xlabel("t (s)")
    if t_max:
        axes[2].set_xlim(0, t_max)
    for ax in axes:
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("h5", nargs="+", help="the runs' frames (-output_file), one or more")
    ap.add_argument("--every", type=int, default=1, help="every this many frames (and the last)")
    ap.add_argument("--label", action="append", help="a run's name in the plot, once per file in order (default: the files')")
    ap.add_argument("--plot", help="also draw folds, DC and the largest strain against t into this PNG")
    ap.add_argument("--t-max", type=float, help="the plot up to this time (s)")
    a = ap.parse_args(argv)
    labels = a.label or [os.path.basename(h) for h in a.h5]
    if len(labels) != len(a.h5):
        print(f"{PROG}: error: --label given {len(labels)} times for {len(a.h5)} files", file=sys.stderr)
        return 2
    histories = []
    for h5, label in zip(a.h5, labels):
        try:
            rows = history(h5, a.every)
            run = drape_h5.load(h5, frames=False)
        except Error as e:
            print(f"{PROG}: error: {e}", file=sys.stderr)
            return 2
        histories.append((label, rows))
        print(f"# {h5}: {run.active.shape[1]} x {run.active.shape[0]} particles")
        print(f"# {'frame':>5s} {'t (s)':>8s} {'folds':>5s} {'DC':>7s} {'strain %':>8s}")
        for k, t, folds, dc, strain in rows:
            print(f"  {k:5d} {t:8.3f} {folds:5d} {dc:7.4f} {'-' if strain is None else f'{100 * strain:.2f}':>8s}")
        rep_dc, rep_folds = run.attrs.get("drape_coefficient"), run.attrs.get("drape_folds")
        if rep_dc is not None:
            print(f"# the run's report (its last frame): DC {float(rep_dc):.4f}, {int(float(rep_folds))} folds")
    if a.plot:
        plot(histories, a.plot, a.t_max)
        print(f"wrote {a.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
