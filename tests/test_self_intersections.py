"""scripts/self_intersections.py: the cloth mesh of a lattice (full and circle masks),
piercings against hand counts and a brute-force reference on crumpled sheets,
touching and shared particles not counted, count() and the command line on small
HDF5 files written here (no drape run)."""
import subprocess
import sys

import h5py
import numpy as np
import pytest

from conftest import ROOT
import drape_h5
import self_intersections as si


def lattice(mx, my):
    """Flat sheet, spacing 1: [My, Mx, 3] positions (i, j, 0)."""
    j, i = np.mgrid[0:my, 0:mx].astype(float)
    return np.stack([i, j, np.zeros_like(i)], axis=-1)


def crumple(mx, my, seed, amp):
    """The flat sheet plus a random smooth displacement (a few sine modes in x, y, z,
    amplitude ~amp (Mx-1)): large enough for the sheet to pass through itself."""
    rng = np.random.default_rng(seed)
    x = lattice(mx, my)
    u, v = x[..., 0] / (mx - 1), x[..., 1] / (my - 1)
    for _ in range(6):
        kx, ky = rng.uniform(1, 4, 2)
        ph = rng.uniform(0, 2 * np.pi, 2)
        a = rng.normal(size=3) * amp * (mx - 1)
        x += a * (np.sin(2 * np.pi * (kx * u + ph[0])) * np.cos(2 * np.pi * (ky * v + ph[1])))[..., None]
    return x


def orient(a, b, c, d):
    """Six times the signed volume of the tetrahedron abcd (plain floats)."""
    b0, b1, b2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    c0, c1, c2 = c[0] - a[0], c[1] - a[1], c[2] - a[2]
    d0, d1, d2 = d[0] - a[0], d[1] - a[1], d[2] - a[2]
    return b0 * (c1 * d2 - c2 * d1) - b1 * (c0 * d2 - c2 * d0) + b2 * (c0 * d1 - c1 * d0)


def brute(x, tris, edges, touching=False, shared=False):
    """Reference: every (edge, triangle) pair tested by signed volumes, as sorted tuples.
    A piercing: P and Q strictly on either side of ABC, and PQ turning the same strict
    way round AB, BC, CA. touching=True makes every inequality non-strict (touching
    counts, and so does an edge in the plane), shared=True tests pairs sharing a particle
    too: both wrong, for showing what the real test rejects."""
    X = np.asarray(x, dtype=float).reshape(-1, 3).tolist()
    out = []
    for ei, (p, q) in enumerate(np.asarray(edges).tolist()):
        P, Q = X[p], X[q]
        for ti, (a, b, c) in enumerate(np.asarray(tris).tolist()):
            if not shared and (p in (a, b, c) or q in (a, b, c)):
                continue
            A, B, C = X[a], X[b], X[c]
            s1, s2 = orient(A, B, C, P), orient(A, B, C, Q)
            v = orient(P, Q, A, B), orient(P, Q, B, C), orient(P, Q, C, A)
            if touching:
                hit = s1 * s2 <= 0 and (min(v) >= 0 or max(v) <= 0)
            else:
                hit = s1 * s2 < 0 and (min(v) > 0 or max(v) < 0)
            if hit:
                out.append((ei, ti))
    return sorted(out)


def pairs(x, tris, edges):
    got = si.piercings(np.asarray(x).reshape(-1, 3), tris, edges)
    assert got.ndim == 2 and got.shape[1] == 2 and got.dtype.kind == "i"
    return [tuple(p) for p in got.tolist()]


def crossing_sheets(gap=False):
    """A 6-wide lattice: rows 0..3 a horizontal sheet (i, j, 0), the 4 rows after them a
    vertical sheet in the plane y = 1.3, x = i + 0.2, z = -1.5 .. 1.5 (row 4 inactive and
    out of the way with gap=True, else the cells between rows 3 and 4 join the two, a
    strip in one plane touching both). Returns (active, positions, vertical rows).

    By hand: the vertical sheet's weft edges (i, 5)-(i, 6) (with the gap: rows 6-7) cross
    z = 0 at x = i + 0.2, inside the horizontal sheet for i = 0..4 (5.2 is outside), and
    its diagonals at x = i + 0.7, i = 0..4: 10 piercings of horizontal triangles. The
    horizontal sheet's weft edges (i, 1)-(i, 2) cross y = 1.3 at x = i, inside the
    vertical sheet (0.2 < x < 5.2) for i = 1..5, and its diagonals (i, 1)-(i+1, 2) at
    x = i + 0.3, i = 0..4: 10 piercings of vertical triangles. No crossing point lies on a
    lattice line of the other sheet. 20 in all."""
    mx, first = 6, 5 if gap else 4
    my = first + 4
    x = lattice(mx, my)
    active = np.ones((my, mx), dtype=bool)
    for r in range(4):
        x[first + r, :, 0] = np.arange(mx) + 0.2
        x[first + r, :, 1] = 1.3
        x[first + r, :, 2] = r - 1.5
    if gap:
        active[4] = False
        x[4] = [50.0, 50.0, 50.0]
    return active, x, range(first, my)


def test_mesh_full_rectangle():
    mx, my = 7, 5
    tris, edges = si.mesh(np.ones((my, mx), dtype=bool))
    assert tris.shape == (2 * (mx - 1) * (my - 1), 3)
    assert edges.shape == ((mx - 1) * my + mx * (my - 1) + (mx - 1) * (my - 1), 2)
    # cell (0, 0) and the last cell, on flat numbers j Mx + i
    assert tris[:2].tolist() == [[0, 1, mx + 1], [0, mx + 1, mx]]
    n = lambda i, j: j * mx + i  # noqa: E731
    assert tris[-2:].tolist() == [[n(5, 3), n(6, 3), n(6, 4)], [n(5, 3), n(6, 4), n(5, 4)]]
    # the edges are exactly the triangles' edges, each once, (low, high)
    from_tris = {tuple(sorted(e)) for t in tris.tolist() for e in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))}
    assert len({tuple(e) for e in edges.tolist()}) == len(edges)
    assert {tuple(e) for e in edges.tolist()} == from_tris
    assert (edges[:, 0] < edges[:, 1]).all()


def test_mesh_circle_mask():
    # the inscribed disc before its spikes are pruned (drape_h5.active_mask prunes
    # them): its four axis points join the lattice by edges that bound no cell
    mx, my = 13, 11
    a = (np.arange(mx) - 0.5 * (mx - 1)) / (0.5 * (mx - 1))
    b = (np.arange(my) - 0.5 * (my - 1)) / (0.5 * (my - 1))
    active = a[None, :] ** 2 + b[:, None] ** 2 <= 1 + 1e-12
    assert active.sum() == drape_h5.active_mask(mx, my, "circle").sum() + 4
    assert 0 < active.sum() < mx * my
    tris, edges = si.mesh(active)
    cells = {(i, j) for j in range(my - 1) for i in range(mx - 1)
             if active[j, i] and active[j, i + 1] and active[j + 1, i] and active[j + 1, i + 1]}
    assert 0 < len(cells) < (mx - 1) * (my - 1)
    assert len(tris) == 2 * len(cells)
    assert active.ravel()[tris].all() and active.ravel()[edges].all()
    for a, b in zip(tris[0::2].tolist(), tris[1::2].tolist()):
        j, i = divmod(a[0], mx)
        assert (i, j) in cells
        assert a == [j * mx + i, j * mx + i + 1, (j + 1) * mx + i + 1]
        assert b == [j * mx + i, (j + 1) * mx + i + 1, (j + 1) * mx + i]
    assert {(t[0] % mx, t[0] // mx) for t in tris.tolist()} == cells
    from_tris = {tuple(sorted(e)) for t in tris.tolist() for e in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))}
    assert len({tuple(e) for e in edges.tolist()}) == len(edges)
    assert {tuple(e) for e in edges.tolist()} == from_tris
    # an edge between two active particles that bounds no cloth cell is not in the mesh
    assert len(from_tris) < sum(1 for j in range(my) for i in range(mx - 1) if active[j, i] and active[j, i + 1]) \
        + sum(1 for j in range(my - 1) for i in range(mx) if active[j, i] and active[j + 1, i]) + len(cells)


def test_mesh_no_cell():
    for active in (np.ones((1, 5), dtype=bool), np.eye(4, dtype=bool)):
        tris, edges = si.mesh(active)
        assert tris.shape == (0, 3) and edges.shape == (0, 2)
        assert si.piercings(lattice(*active.shape[::-1]).reshape(-1, 3), tris, edges).shape == (0, 2)


def test_single_triangle_cases():
    """One triangle, one edge: a crossing counts; touching (an end on the triangle, through
    its edge or corner, in its plane) does not; inside by 1e-6 counts."""
    tri = np.array([[0, 1, 2]])
    edge = np.array([[3, 4]])
    base = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]

    def hits(p, q):
        return len(si.piercings(np.array(base + [p, q], dtype=float), tri, edge))

    assert hits([0.2, 0.3, -1], [0.25, 0.3, 1]) == 1
    assert hits([0.2, 0.3, 1], [0.2, 0.3, 0.5]) == 0  # above
    assert hits([0.2, 0.3, 0], [0.2, 0.3, 1]) == 0  # ends on the triangle
    assert hits([0.5, 0.5, -1], [0.5, 0.5, 1]) == 0  # through its edge x + y = 1
    assert hits([0.5, 0.0, -1], [0.5, 0.0, 1]) == 0  # through its edge y = 0
    assert hits([0.0, 0.5, -1], [0.0, 0.5, 1]) == 0  # through its edge x = 0
    assert hits([0.0, 0.0, -1], [0.0, 0.0, 1]) == 0  # through its corner
    assert hits([-1, 0.2, 0], [2, 0.2, 0]) == 0  # in its plane
    assert hits([0.6, 0.6, -1], [0.6, 0.6, 1]) == 0  # outside
    assert hits([0.5 - 1e-6, 0.5 - 1e-6, -1], [0.5 - 1e-6, 0.5 - 1e-6, 1]) == 1  # just inside


def test_flat_sheet_has_none():
    tris, edges = si.mesh(np.ones((6, 8), dtype=bool))
    x = lattice(8, 6)
    assert pairs(x, tris, edges) == []
    # in-plane shearing and a tilt of the plane change nothing
    x[..., 0] += 0.3 * np.sin(x[..., 1])
    x[..., 2] = 0.1 * x[..., 0] - 0.2 * x[..., 1]
    assert pairs(x, tris, edges) == []


@pytest.mark.parametrize("gap", [False, True])
def test_crossing_sheets_hand_count(gap):
    active, x, vertical = crossing_sheets(gap)
    my, mx = active.shape
    tris, edges = si.mesh(active)
    got = pairs(x, tris, edges)
    assert len(got) == 20
    assert got == brute(x, tris, edges)
    row = lambda k: k // mx  # noqa: E731
    v_edge_h_tri = [(e, t) for e, t in got if row(edges[e][0]) in vertical and row(tris[t][2]) <= 3]
    h_edge_v_tri = [(e, t) for e, t in got if row(edges[e][1]) <= 3 and row(tris[t][0]) in vertical]
    assert len(v_edge_h_tri) == 10 and len(h_edge_v_tri) == 10
    # the vertical weft edges that cross z = 0 are those from the row at z = -0.5
    wefts = sorted(tuple(edges[e]) for e, t in v_edge_h_tri if edges[e][1] - edges[e][0] == mx)
    r = vertical[1]
    assert wefts == [(r * mx + i, (r + 1) * mx + i) for i in range(5)]


@pytest.mark.parametrize("seed", range(5))
def test_matches_brute_force_on_crumpled_sheets(seed):
    tris, edges = si.mesh(np.ones((10, 10), dtype=bool))
    x = crumple(10, 10, seed, 0.5)
    ref = brute(x, tris, edges)
    assert len(ref) > 0  # the sheet does pass through itself
    assert pairs(x, tris, edges) == ref


def test_matches_brute_force_with_far_particle():
    """One particle 300 spacings away: its six triangles' boxes would cover ~1e4 grid
    cells each, so the grid is coarsened; the answer is the same."""
    tris, edges = si.mesh(np.ones((10, 10), dtype=bool))
    x = crumple(10, 10, 7, 0.3)
    x[4, 5] += [300.0, 250.0, -280.0]
    X = x.reshape(-1, 3)
    tlo, thi = si._boxes(X, tris)
    elo, ehi = si._boxes(X, edges)
    _, h, _ = si._grid(tlo, thi, elo, ehi)
    assert h >= 2 * (thi - tlo).max(axis=1).mean()  # the coarsening did happen (h doubled)
    ref = brute(x, tris, edges)
    assert len(ref) > 0
    assert pairs(x, tris, edges) == ref


def test_circle_mask_crumpled():
    """A circle specimen: inactive particles are not in the mesh (even where they sit,
    or if they were not finite)."""
    active = drape_h5.active_mask(12, 12, "circle")
    tris, edges = si.mesh(active)
    x = crumple(12, 12, 3, 0.5)
    ref = brute(x, tris, edges)
    assert len(ref) > 0
    assert pairs(x, tris, edges) == ref
    x[0, 0] = np.nan  # a corner: outside the disc
    assert not active[0, 0]
    assert pairs(x, tris, edges) == ref
    x[6, 6] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        si.piercings(x.reshape(-1, 3), tris, edges)


def test_fold_onto_itself_shares_nothing():
    """A sheet folded flat onto itself along column 3: the layers coincide, and the
    triangles at the fold overlap others that share their particles. Touching is no
    piercing: 0, with the fold exact or opened by a hair (a test that counted touching
    or shared particles would report pairs). Folded over a little short and twisted so
    that the upper layer passes through the lower one from the fold line on: only pairs
    sharing no particle, as the brute force finds them."""
    mx, my, k = 8, 6, 3
    tris, edges = si.mesh(np.ones((my, mx), dtype=bool))
    x = lattice(mx, my)
    x[:, k + 1:, 0] = 2 * k - x[:, k + 1:, 0]  # flat fold: column k + m onto k - m
    assert pairs(x, tris, edges) == []
    touching = brute(x, tris, edges, touching=True, shared=True)
    assert any(set(edges[e]) & set(tris[t]) for e, t in touching)  # what a wrong test would count
    assert any(not set(edges[e]) & set(tris[t]) for e, t in touching)
    m = np.arange(k + 1, mx) - k  # columns past the fold
    for lift in (1e-9, 1e-3, 0.5):
        y = x.copy()
        y[:, k + 1:, 2] = lift * m
        assert pairs(y, tris, edges) == [] == brute(y, tris, edges)
    y = x.copy()
    y[:, k + 1:, 0] = k - 0.93 * m
    y[:, k + 1:, 2] = 0.05 * m * (np.arange(my) - 2.3)[:, None]  # crosses z = 0 at y = 2.3
    got = pairs(y, tris, edges)
    assert len(got) > 0
    assert got == brute(y, tris, edges)
    assert brute(y, tris, edges, shared=True) == got  # the shared pairs add nothing here either
    assert all(not set(edges[e]) & set(tris[t]) for e, t in got)


def write_h5(path, frames, times=None):
    """A file drape_h5.load reads: positions [n, My, Mx, 3] and the required datasets."""
    frames = np.asarray(frames, dtype=float)
    n = len(frames)
    with h5py.File(path, "w") as f:
        f.attrs["drape_version"] = "test"
        f["position"] = frames
        f["velocity"] = np.zeros_like(frames)
        f["time"] = (np.arange(1, n + 1) * 0.1 if times is None else np.asarray(times)).reshape(n, 1)
        f["step"] = np.arange(n).reshape(n, 1)
    return path


def test_count_and_cli(tmp_path):
    _, cross, _ = crossing_sheets(gap=False)
    flat = lattice(6, 8)
    path = write_h5(tmp_path / "c.h5", [flat, cross, flat, cross])
    assert si.count(path) == [0, 20, 0, 20]
    assert si.count(path, frames=[1, -2]) == [20, 0]
    script = ROOT / "scripts" / "self_intersections.py"
    res = subprocess.run([sys.executable, str(script), str(path)], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr
    rows = [line.split() for line in res.stdout.splitlines() if not line.startswith(("#", "max"))]
    assert [(int(r[0]), int(r[2])) for r in rows] == [(0, 0), (1, 20), (2, 0), (3, 20)]
    assert "max 20 piercings at frame 1" in res.stdout
    res = subprocess.run([sys.executable, str(script), str(path), "--every", "2"], capture_output=True, text=True,
                         timeout=60)
    assert res.returncode == 0, res.stderr
    rows = [line.split() for line in res.stdout.splitlines() if not line.startswith(("#", "max"))]
    assert [(int(r[0]), int(r[2])) for r in rows] == [(0, 0), (2, 0), (3, 20)]  # and the last
    res = subprocess.run([sys.executable, str(script), str(tmp_path / "missing.h5")], capture_output=True, text=True,
                         timeout=60)
    assert res.returncode == 2 and "no such file" in res.stderr
