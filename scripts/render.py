#!/usr/bin/env python3
"""Render one frame of a drape HDF5 file as a shaded 3D picture (PNG).

    render.py out/hang.h5                    # last frame -> out/hang.png
    render.py out/hang.h5 --frame 0 -o first.png
    render.py out/cusick.h5 --elev 40 --azim -50

The cloth (only the particles that belong to it: a circle specimen hides the
lattice corners) is drawn as lit facets coloured by height, the solid of the
scene (/solid_triangles) in translucent light grey and the -solid_floor plane as
a light grey square, on equally scaled axes. Bad input (missing or non-drape
file, frame out of range) gives a one-line error and exit status 2.

The drawing is shared with animate.py: `Scene(run)` fixes the axes box,
`Scene.figure()` makes the figure, `Scene.draw(fig, ax, frame)` draws a frame.
"""

import argparse
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import Normalize  # noqa: E402
from matplotlib.ticker import FixedLocator, FuncFormatter, MaxNLocator  # noqa: E402
from mpl_toolkits.mplot3d import proj3d  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import drape_h5  # noqa: E402

MAX_FACETS = 128  # facets per lattice direction (larger lattices are subsampled)
ELEV, AZIM = 25.0, -60.0  # default view (degrees)
CLOTH_CMAP = "viridis"
SOLID_RGB = (0.80, 0.80, 0.82)
SOLID_ALPHA = 0.55
FLOOR_RGB = (0.90, 0.90, 0.90)
SOLID_MARGIN = 0.3  # the solid is drawn within this fraction of the cloth's extent around it
MAX_SOLID_FACETS = 40000  # cap on the subdivided solid (depth sorting needs small facets)


# ---------------------------------------------------------------------------- geometry


def _unit(v):
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)


def view_vectors(elev, azim):
    """Unit vectors from the scene towards the eye and towards the light (upper left of the eye)."""
    e, a = np.radians(elev), np.radians(azim)
    eye = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    right = _unit(np.cross([0.0, 0.0, 1.0], eye)) if abs(eye[2]) < 0.999 else np.array([1.0, 0.0, 0.0])
    up = np.cross(eye, right)
    light = _unit(0.55 * eye + 0.75 * up - 0.35 * right)
    return eye, light


def lattice_normals(p):
    """Smooth normals [My, Mx, 3] of a lattice p [My, Mx, 3] (central differences)."""
    du = np.gradient(p, axis=1)
    dv = np.gradient(p, axis=0)
    return _unit(np.cross(du, dv))


def cloth_facets(p, active, stride=1):
    """Facets of the cloth at positions p [My, Mx, 3], every `stride` particles: a quad
    per cell with four active corners and, along the edge of a circle specimen, a
    triangle per cell with three.

    Returns (quads [n, 4, 3], triangles [m, 3, 3], quad normals [n, 3], triangle
    normals [m, 3]); normals are the mean of the smooth lattice normals at the corners."""
    my, mx = active.shape
    js = np.unique(np.r_[np.arange(0, my, stride), my - 1])
    is_ = np.unique(np.r_[np.arange(0, mx, stride), mx - 1])
    q = p[np.ix_(js, is_)]
    a = active[np.ix_(js, is_)]
    nrm = lattice_normals(q)
    jj, ii = np.meshgrid(np.arange(len(js) - 1), np.arange(len(is_) - 1), indexing="ij")
    corners = [(jj, ii), (jj, ii + 1), (jj + 1, ii + 1), (jj + 1, ii)]  # counter-clockwise
    on = np.stack([a[c] for c in corners], axis=-1)  # [cells..., 4]
    full = on.all(axis=-1)
    quads = np.stack([q[c][full] for c in corners], axis=1)
    qn = sum(nrm[c][full] for c in corners)
    three = on.sum(axis=-1) == 3
    off = np.argmin(on[three], axis=-1)  # the inactive corner
    cs = [(c[0][three], c[1][three]) for c in corners]
    k = np.arange(three.sum())
    pick = [(off + d) % 4 for d in (1, 2, 3)]
    tri = np.stack([np.stack([q[cs[0]], q[cs[1]], q[cs[2]], q[cs[3]]], axis=1)[k, m] for m in pick], axis=1)
    tn = sum(np.stack([nrm[cs[0]], nrm[cs[1]], nrm[cs[2]], nrm[cs[3]]], axis=1)[k, m] for m in pick)
    flat_q = np.cross(quads[:, 2] - quads[:, 0], quads[:, 3] - quads[:, 1])
    flat_t = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    for n, f in ((qn, flat_q), (tn, flat_t)):
        bad = ~np.isfinite(n).all(axis=1) | (np.linalg.norm(n, axis=1) < 1e-9)
        n[bad] = f[bad]
    return quads.reshape(-1, 4, 3), tri.reshape(-1, 3, 3), qn.reshape(-1, 3), tn.reshape(-1, 3)


def clip_box(tri, lo, hi):
    """The parts of triangles tri [n, 3, 3] inside the box [lo, hi] (cut exactly)."""
    for axis in range(3):
        for value, sign in ((lo[axis], 1.0), (hi[axis], -1.0)):
            tri = _clip_plane(tri, axis, value, sign)
    return tri


def _clip_plane(tri, axis, value, sign):
    """Keep the part of each triangle where sign * (x[axis] - value) >= 0."""
    d = sign * (tri[:, :, axis] - value)
    inside = d >= 0
    n_in = inside.sum(axis=1)
    keep = [tri[n_in == 3]]
    for count in (1, 2):
        sel = n_in == count
        if not sel.any():
            continue
        t, dd, ins = tri[sel], d[sel], inside[sel]
        # rotate each triangle so that its odd vertex (the one inside, or the one outside) comes first
        odd = np.argmax(ins if count == 1 else ~ins, axis=1)
        r = np.arange(len(t))[:, None]
        order = (odd[:, None] + np.arange(3)) % 3
        t, dd = t[r, order], dd[r, order]
        A, B, C = t[:, 0], t[:, 1], t[:, 2]
        dA, dB, dC = dd[:, 0:1], dd[:, 1:2], dd[:, 2:3]
        AB = A + (B - A) * (dA / (dA - dB))
        AC = A + (C - A) * (dA / (dA - dC))
        if count == 1:  # A inside
            keep.append(np.stack([A, AB, AC], axis=1))
        else:  # A outside: quad AB, B, C, AC
            keep.append(np.stack([AB, B, C], axis=1))
            keep.append(np.stack([AB, C, AC], axis=1))
    return np.concatenate(keep) if keep else tri[:0]


def view_frame(elev, azim):
    """Orthonormal (right, up, eye) of the view: screen axes and the direction to the eye."""
    eye, _ = view_vectors(elev, azim)
    right = _unit(np.cross([0.0, 0.0, 1.0], eye)) if abs(eye[2]) < 0.999 else np.array([1.0, 0.0, 0.0])
    return right, np.cross(eye, right), eye


def occluded(points, tris, frame, eps):
    """[len(points)] bool: is each point hidden from the eye (orthographic view along
    frame[2]) by one of the triangles `tris` [n, 3, 3]: is a triangle in front of it by
    more than `eps` in depth (a negative eps also counts triangles just behind it)?"""
    right, up, eye = frame
    basis = np.stack([right, up, eye], axis=1)
    q = points @ basis  # (u, v, depth towards the eye)
    t = tris @ basis  # [n, 3, 3]
    a, b, c = t[:, 0, :2], t[:, 1, :2], t[:, 2, :2]
    det = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    ok = np.abs(det) > 1e-300
    a, b, c, t, det = a[ok], b[ok], c[ok], t[ok], det[ok]
    out = np.zeros(len(points), bool)
    if not len(t) or not len(q):
        return out
    # bin the triangles on a uniform screen grid of cells as large as the largest triangle
    tlo, thi = t[:, :, :2].min(axis=1), t[:, :, :2].max(axis=1)
    g = max(float((thi - tlo).max()), 1e-12)
    origin = tlo.min(axis=0)
    c0 = np.floor((tlo - origin) / g).astype(np.int64)
    c1 = np.floor((thi - origin) / g).astype(np.int64)  # c1 - c0 <= 1
    ncol = int(c1[:, 0].max()) + 2
    tri_ids, cell_ids = [], []
    for dx in (0, 1):
        for dy in (0, 1):
            m = (c0[:, 0] + dx <= c1[:, 0]) & (c0[:, 1] + dy <= c1[:, 1])
            tri_ids.append(np.nonzero(m)[0])
            cell_ids.append((c0[m, 1] + dy) * ncol + c0[m, 0] + dx)
    tri_ids, cell_ids = np.concatenate(tri_ids), np.concatenate(cell_ids)
    order = np.argsort(cell_ids, kind="stable")
    tri_ids, cell_ids = tri_ids[order], cell_ids[order]
    pc = np.floor((q[:, :2] - origin) / g).astype(np.int64)
    inside_grid = (pc >= 0).all(axis=1) & (pc[:, 0] < ncol)
    pcell = pc[:, 1] * ncol + pc[:, 0]
    start = np.searchsorted(cell_ids, pcell, side="left")
    stop = np.searchsorted(cell_ids, pcell, side="right")
    count = np.where(inside_grid, stop - start, 0)
    rows = np.repeat(np.arange(len(q)), count)
    offs = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    cols = tri_ids[np.repeat(start, count) + offs]
    du, dv = q[rows, 0] - a[cols, 0], q[rows, 1] - a[cols, 1]
    l1 = (du * (c[cols, 1] - a[cols, 1]) - dv * (c[cols, 0] - a[cols, 0])) / det[cols]
    l2 = ((b[cols, 0] - a[cols, 0]) * dv - (b[cols, 1] - a[cols, 1]) * du) / det[cols]
    inside = (l1 >= 0) & (l2 >= 0) & (l1 + l2 <= 1)
    depth = (1 - l1 - l2) * t[cols, 0, 2] + l1 * t[cols, 1, 2] + l2 * t[cols, 2, 2]
    out[rows[inside & (depth > q[rows, 2] + eps)]] = True
    return out


def cell_size(p, active):
    """Mean length of the lattice edges between active particles of positions p."""
    d = [np.linalg.norm(np.diff(p, axis=0), axis=2)[active[1:] & active[:-1]],
         np.linalg.norm(np.diff(p, axis=1), axis=2)[active[:, 1:] & active[:, :-1]]]
    d = np.concatenate(d)
    return float(d.mean()) if d.size else 0.0


def closed_and_oriented(tri):
    """(closed, sign): is the triangle soup a closed surface, and the sign that makes
    its normals point outwards (signed volume)."""
    flat = tri.reshape(-1, 3)
    _, ids = np.unique(flat, axis=0, return_inverse=True)
    ids = ids.reshape(-1, 3)
    edges = np.sort(np.concatenate([ids[:, [0, 1]], ids[:, [1, 2]], ids[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    closed = bool(np.all(counts == 2))
    vol = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum()
    return closed, (1.0 if vol >= 0 else -1.0)


def subdivide(tri, hmax, cap=MAX_SOLID_FACETS):
    """Split triangles along their longest edge until every edge is <= hmax (or the
    count would pass `cap`), so that mplot3d's per-facet depth sort mixes them well
    with the cloth's facets."""
    tri = np.asarray(tri, float)
    while len(tri):
        e = np.stack([np.linalg.norm(tri[:, (k + 1) % 3] - tri[:, k], axis=1) for k in range(3)], axis=1)
        k = e.argmax(axis=1)
        big = e[np.arange(len(tri)), k] > hmax
        if not big.any() or len(tri) + big.sum() > cap:
            break
        t = tri[big]
        k = k[big]
        r = np.arange(len(t))
        a, b, c = t[r, k], t[r, (k + 1) % 3], t[r, (k + 2) % 3]  # longest edge a-b
        m = 0.5 * (a + b)
        tri = np.concatenate([tri[~big], np.stack([a, m, c], 1), np.stack([m, b, c], 1)])
    return tri


def axis_ticks(lo, hi, rel):
    """Tick locator for an axis from lo to hi whose length is `rel` times the longest:
    about one tick per quarter of the longest axis, a single one on a short axis."""
    if rel >= 0.3:
        return MaxNLocator(nbins=max(2, int(round(4 * rel))), steps=[1, 2, 2.5, 5, 10])
    values = [v for v in MaxNLocator(nbins=2, steps=[1, 2, 2.5, 5, 10]).tick_values(lo, hi) if lo <= v <= hi]
    if not values:
        return FixedLocator([])
    return FixedLocator([min(values, key=lambda v: abs(v - 0.5 * (lo + hi)))])


def trim(path, margin=12):
    """Crop the white border of a raster picture (PNG, JPEG) in place."""
    if os.path.splitext(path)[1].lower() not in (".png", ".jpg", ".jpeg"):
        return
    from PIL import Image, ImageChops

    with Image.open(path) as im:
        im.load()
    rgb = im.convert("RGB")
    box = ImageChops.difference(rgb, Image.new("RGB", rgb.size, (255, 255, 255))).getbbox()
    if box:
        box = (max(box[0] - margin, 0), max(box[1] - margin, 0),
               min(box[2] + margin, im.width), min(box[3] + margin, im.height))
        im.crop(box).save(path)


# ---------------------------------------------------------------------------- the scene


class Scene:
    """How a run is drawn: fixed bounds (so that an animation does not jump) and view."""

    def __init__(self, run, frames=None, elev=ELEV, azim=AZIM):
        self.run = run
        self.elev, self.azim = elev, azim
        frames = list(range(run.nframes) if frames is None else frames)
        pts = run.positions[frames][:, run.active].reshape(-1, 3)
        self.zrange = (pts[:, 2].min(), pts[:, 2].max())  # colour scale of the cloth
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        floor = run.floor
        my, mx = run.shape
        self.stride = max(1, -(-(max(mx, my) - 1) // MAX_FACETS))

        # the solid is shown near the cloth only (down to the floor): a tall pedestal
        # would leave the specimen small
        self.solid = None
        tri = run.solid_triangles
        if tri is not None:
            margin = SOLID_MARGIN * max(hi - lo) + 1e-9
            clo, chi = lo - margin, hi + margin
            if floor is not None:
                clo[2] = min(clo[2], floor)
            eye, _ = view_vectors(elev, azim)
            closed, sign = closed_and_oriented(tri)
            if closed:  # the back faces of a closed solid are hidden: leave them out
                n = sign * np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
                tri = tri[n @ eye > 0]
            if floor is not None:  # and so is what lies under the floor
                tri = tri[tri[:, :, 2].max(axis=1) > floor + 1e-9]
            tri = clip_box(tri, clo, chi)
            if len(tri):
                lo = np.minimum(lo, tri.reshape(-1, 3).min(axis=0))
                hi = np.maximum(hi, tri.reshape(-1, 3).max(axis=0))
            self.solid = subdivide(tri, max(hi - lo) / 40.0 + 1e-12)
        if floor is not None:
            lo[2], hi[2] = min(lo[2], floor), max(hi[2], floor)
        self.lo, self.hi = lo, hi
        self.floor_rect = None
        if floor is not None:
            pad = 0.08 * max(hi - lo)
            self.floor_rect = np.array([[lo[0] - pad, lo[1] - pad], [hi[0] + pad, lo[1] - pad],
                                        [hi[0] + pad, hi[1] + pad], [lo[0] - pad, hi[1] + pad]])

    # -- figure and axes

    def figure(self, width=6.5, margins=(0.45, 0.6, 0.5, 0.55)):
        """A figure `width` inches wide that fits the axes box of this scene, with
        margins (left, right, bottom, top; inches) for the tick labels and the title."""
        fig = plt.figure(figsize=(6.0, 6.0))
        ax = fig.add_subplot(projection="3d", computed_zorder=False)
        ax.set_position([0, 0, 1, 1])  # the 3D box is drawn in a square: here, the whole figure
        self._setup_axes(ax)
        x0, x1, y0, y1 = self._box_on_figure(ax)
        ml, mr, mb, mt = margins
        side = (width - ml - mr) / max(x1 - x0, 1e-6)  # inches of the square
        height = side * (y1 - y0) + mb + mt
        fig.set_size_inches(width, height)
        ax.set_position([(ml - side * x0) / width, (mb - side * y0) / height, side / width, side / height])
        return fig, ax

    def _setup_axes(self, ax):
        lo, hi = self.lo, self.hi
        pad = 0.03 * max(hi - lo) + 1e-9
        if self.floor_rect is not None:
            lo = np.r_[self.floor_rect.min(axis=0), lo[2]]
            hi = np.r_[self.floor_rect.max(axis=0), hi[2]]
        span = np.maximum(hi - lo, 0.08 * max(hi - lo)) + 2 * pad  # a flat sheet keeps some depth
        mid = 0.5 * (lo + hi)
        ax.set_xlim(mid[0] - span[0] / 2, mid[0] + span[0] / 2)
        ax.set_ylim(mid[1] - span[1] / 2, mid[1] + span[1] / 2)
        ax.set_zlim(mid[2] - span[2] / 2, mid[2] + span[2] / 2)
        ax.set_box_aspect(span)
        ax.view_init(elev=self.elev, azim=self.azim)
        ax.set_proj_type("ortho")  # parallel projection: what occluded() assumes
        # ticks: about one per 0.25 of the largest extent on each axis, never crowded;
        # a short axis gets a single tick that names it ("z = 0 m") instead of a label
        ax.tick_params(labelsize=7, pad=0)
        for name, axis, s, m in zip("xyz", (ax.xaxis, ax.yaxis, ax.zaxis), span, mid):
            rel = s / span.max()
            axis.set_major_locator(axis_ticks(m - s / 2, m + s / 2, rel))
            if rel < 0.3:
                axis.set_major_formatter(FuncFormatter(lambda v, _, name=name: f"{name} = {v + 0.0:.3g} m"))
            else:
                axis.set_label_text(f"{name} (m)", fontsize=8)
                axis.labelpad = 1
            axis.set_pane_color((0.97, 0.97, 0.97, 1.0))
            axis._axinfo["grid"].update(color=(0.85, 0.85, 0.85, 1.0), linewidth=0.5)

    def _box_on_figure(self, ax):
        """Left, right, bottom and top of the projected axes box, in figure coordinates."""
        lims = np.array([ax.get_xlim(), ax.get_ylim(), ax.get_zlim()])
        corners = np.array([[lims[0, i], lims[1, j], lims[2, k]] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
        xs, ys, _ = proj3d.proj_transform(corners[:, 0], corners[:, 1], corners[:, 2], ax.get_proj())
        ax.apply_aspect()
        pts = ax.figure.transFigure.inverted().transform(ax.transData.transform(np.c_[xs, ys]))
        return pts[:, 0].min(), pts[:, 0].max(), pts[:, 1].min(), pts[:, 1].max()

    # -- drawing

    def _shade(self, normals, rgb, eye, light, ambient=0.38):
        """Two-sided Lambert shading: facets are lit on the side that faces the eye."""
        n = _unit(normals)
        n = n * np.where(n @ eye < 0, -1.0, 1.0)[:, None]
        lam = np.clip(n @ light, 0, 1)
        return np.clip(rgb * (ambient + (1 - ambient) * lam)[:, None], 0, 1)

    def _visible_solid(self, t, p, tris, refine=2):
        """The facets t of the solid that the cloth (triangles tris, particles p) does not hide.

        A facet of the solid and a facet of the cloth lying on it have about the same
        depth, and mplot3d's facet sort would often draw the solid on top: so the
        facets behind the cloth (centre and corners) are left out, and those partly
        behind it are split and tested again, `refine` times. Where the cloth wraps an
        edge of the solid its flat facets cut the corner: so "behind" allows the solid
        up to half a cell in front of the cloth."""
        view = view_frame(self.elev, self.azim)
        tol = -0.5 * self.stride * cell_size(p, self.run.active)
        hmax = max(self.hi - self.lo) / 40.0
        keep = []
        for level in range(refine + 1):
            hid = occluded(np.concatenate([t.mean(axis=1), t.reshape(-1, 3)]), tris, view, tol)
            centre, corners = hid[: len(t)], hid[len(t):].reshape(-1, 3).sum(axis=1)
            hidden = centre & (corners == 3)
            if level == refine:
                keep.append(t[~hidden])
                break
            partly = ~hidden & (centre | (corners > 0))
            keep.append(t[~hidden & ~partly])
            t = subdivide(t[partly], hmax / 2 ** (level + 1))
        return np.concatenate(keep)

    def draw(self, fig, ax, frame, title=True):
        """Draw frame `frame` (a valid non-negative index) on `ax` (cleared first)."""
        run = self.run
        ax.cla()
        for t in list(fig.texts):
            t.remove()
        self._setup_axes(ax)
        eye, light = view_vectors(self.elev, self.azim)

        polys, colours, cloth = [], [], []
        p = run.positions[frame]
        quads, ctri, qn, tn = cloth_facets(p, run.active, self.stride)
        facets = list(quads) + list(ctri)
        if facets:
            normals = np.concatenate([qn, tn])
            zc = np.concatenate([quads[:, :, 2].mean(axis=1), ctri[:, :, 2].mean(axis=1)])
            lo, hi = self.zrange
            base = plt.get_cmap(CLOTH_CMAP)(Normalize(lo, hi + 1e-12 if hi > lo else lo + 1)(zc) * 0.85 + 0.1)[:, :3]
            rgb = self._shade(normals, base, eye, light)
            polys += facets
            colours.append(np.c_[rgb, np.ones(len(rgb))])
            cloth += [True] * len(facets)
        if self.solid is not None and len(self.solid):
            t = self.solid
            if facets:
                t = self._visible_solid(t, p, np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]], ctri]))
            normals = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
            rgb = self._shade(normals, np.tile(SOLID_RGB, (len(t), 1)), eye, light, ambient=0.55)
            polys += list(t)
            colours.append(np.c_[rgb, np.full(len(rgb), SOLID_ALPHA)])
            cloth += [False] * len(t)
        if self.floor_rect is not None:
            z = run.floor
            f = np.c_[self.floor_rect, np.full(4, z)]
            floor = Poly3DCollection([f], facecolors=[(*FLOOR_RGB, 1.0)], edgecolors=[(0.7, 0.7, 0.7, 1.0)],
                                     linewidths=0.6, zorder=1)
            ax.add_collection3d(floor)
        if polys:
            rgba = np.concatenate(colours)
            edges = rgba.copy()
            edges[~np.asarray(cloth), 3] = 0  # no outline on the (translucent) solid: it would darken the seams
            # (one line width for all: mplot3d reorders the colours, not the widths)
            # cloth and solid in one collection: mplot3d sorts its facets by depth together
            coll = Poly3DCollection(polys, facecolors=rgba, edgecolors=edges, linewidths=0.5,
                                    antialiaseds=True, zorder=2)
            ax.add_collection3d(coll)

        if title:
            my, mx = run.shape
            nact = int(run.active.sum())
            line2 = [f"{mx} x {my} particles" if nact == mx * my else f"{nact} particles ({mx} x {my} lattice)"]
            if "kinetic" in run.energies:
                line2.append(f"kinetic energy {run.energies['kinetic'][frame]:.3g} J")
            if "drape_coefficient" in run.attrs and frame == run.nframes - 1:
                line2.append(f"drape coefficient {run.attrs['drape_coefficient']:.3f}, "
                             f"{int(run.attrs.get('drape_folds', 0))} folds")
            text = (f"{os.path.basename(run.path)}: t = {run.time[frame]:.3f} s "
                    f"(frame {frame} of 0..{run.nframes - 1}, step {run.step[frame]})\n" + ", ".join(line2))
            # just above the drawing (the 3D box leaves a wide margin inside the axes)
            x0, x1, _, top = self._box_on_figure(ax)
            top += 0.1 / fig.get_figheight()
            fig.text(0.5 * (x0 + x1), min(top, 0.99), text, ha="center", va="bottom", fontsize=9)


def render(run, frame, out, dpi=150, elev=ELEV, azim=AZIM):
    """Draw frame `frame` (a valid non-negative index) of `run` to the file `out`."""
    scene = Scene(run, [frame], elev=elev, azim=azim)
    fig, ax = scene.figure()
    scene.draw(fig, ax, frame)
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    fig.savefig(out, dpi=dpi)
    plt.close(fig)
    trim(out)


def load_or_exit(ap, path):
    """drape_h5.load, or argparse's one-line error (exit status 2)."""
    try:
        run = drape_h5.load(path)
    except ValueError as e:
        ap.error(str(e))
    except OSError as e:  # e.g. a truncated file h5py opens but cannot read
        ap.error(f"{path}: cannot read ({e})")
    if run.nframes == 0:
        ap.error(f"{path}: no complete frame")
    return run


def check_frame(ap, run, frame, path):
    n = run.nframes
    if not -n <= frame < n:
        ap.error(f"--frame {frame} out of range: {path} has {n} frame(s) (valid {-n}..{n - 1})")
    return frame % n


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("file", help="drape HDF5 output (-output_file)")
    ap.add_argument("-o", "--output", help="PNG to write (default: FILE with .png)")
    ap.add_argument("--frame", type=int, default=-1, help="frame index, negative counts from the end (default -1: last)")
    ap.add_argument("--dpi", type=int, default=150, help="resolution of the PNG (default 150)")
    ap.add_argument("--elev", type=float, default=ELEV, help=f"view elevation, degrees (default {ELEV:g})")
    ap.add_argument("--azim", type=float, default=AZIM, help=f"view azimuth, degrees (default {AZIM:g})")
    args = ap.parse_args(argv)
    if args.dpi <= 0:
        ap.error(f"--dpi must be positive; got {args.dpi}")

    run = load_or_exit(ap, args.file)
    frame = check_frame(ap, run, args.frame, args.file)
    out = args.output or os.path.splitext(args.file)[0] + ".png"
    try:
        render(run, frame, out, dpi=args.dpi, elev=args.elev, azim=args.azim)
    except OSError as e:
        ap.error(f"cannot write {out}: {e.strerror or e}")
    print(f"render: wrote {out} (frame {frame}, t = {run.time[frame]:.4g} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
