"""Partitions: DMDA blocks, serial METIS k-way or PT-Scotch through PETSc's
MatPartitioning give the same frames on 1-4 ranks, and the graph partitions balance
an irregular (circular) cloth that DMDA blocks cannot."""
import numpy as np
import pytest

from conftest import ROUNDOFF, printed, run

import drape_h5

CIRCLE = ("-da_grid_x 25 -da_grid_y 25 -cloth_shape circle -cloth_size 0.3 -cloth_center 0,0,0.0025 "
          "-solid_type cylinder -solid_radius 0.09 -solid_height 0.3 -solid_translate 0,0,-0.15 "
          "-ts_max_time 0.1 -output_interval 0.02")


@pytest.mark.parametrize("scheme,tol", [("-ts_type basicsymplectic -ts_dt 2e-4", ROUNDOFF),
                                        ("-ts_type drapebe -ts_dt 2e-3 -ksp_rtol 1e-12", 1e-9)])
def test_same_frames_for_every_partition_and_rank_count(tmp, scheme, tol):
    """The disc on the cylinder gives the one-rank frames on 2, 3 and 4 ranks with each
    partition: every partition on two rank counts and every rank count with two
    partitions (six of the nine pairs: the suite's time; DMDA's blocks on 1, 2 and 4
    ranks are tests/test_integration.py's too)."""
    ref = tmp / "ref.h5"
    run(f"{CIRCLE} {scheme} -output_file {ref}")
    a = drape_h5.load(ref)
    assert a.energies["kinetic"][-1] > 0
    for np_, parts in ((2, ("metis", "ptscotch")), (3, ("dmda", "metis")), (4, ("dmda", "ptscotch"))):
        for part in parts:
            out = tmp / f"{part}{np_}.h5"
            run(f"{CIRCLE} {scheme} -cloth_partition {part} -output_file {out}", np_=np_)
            b = drape_h5.load(out)
            assert np.abs(a.positions - b.positions).max() <= tol, (np_, part)


def quality(res):
    m = printed(res, r"partition: \w+ on \d+ ranks, (\d+ to \d+) active", str).split(" to ")
    return int(m[0]), int(m[1]), printed(res, r"imbalance ([0-9.]+)"), printed(res, r"(\d+) of \d+ stretch edges cut", int)


@pytest.mark.parametrize("part", ["metis", "ptscotch"])
def test_graph_partition_balances_a_circular_cloth(part):
    """Every rank owns particles; METIS and PT-Scotch keep the imbalance below 5 % on 3
    ranks where DMDA's row blocks of a disc are over 20 % off, with a comparable cut."""
    base = "-da_grid_x 41 -da_grid_y 41 -cloth_shape circle -ts_max_steps 0"
    dmda = quality(run(f"{base} -cloth_partition dmda", np_=3))
    graph = quality(run(f"{base} -cloth_partition {part}", np_=3))
    assert graph[0] > 0 and dmda[0] > 0
    assert graph[2] < 1.05 < 1.2 < dmda[2], (graph, dmda)
    assert graph[3] <= 1.5 * dmda[3]


@pytest.mark.parametrize("part", ["metis", "ptscotch"])
def test_graph_partition_shares_out_the_inactive_particles(part):
    """The lattice points outside a disc (pinned, in no element) are shared out
    equally by a graph partition: the particles a rank holds differ by no more than
    its active ones do, plus one. Kept in their DMDA blocks, as they were, the ranks
    whose parts lie by the disc's edge held over a hundred more here."""
    base = "-da_grid_x 41 -da_grid_y 41 -cloth_shape circle -ts_max_steps 0"
    r = run(f"{base} -cloth_partition {part}", np_=3).report
    assert r["held_max"] - r["held_min"] <= r["owned_max"] - r["owned_min"] + 1, r
    assert 3 * r["held_min"] <= 41 * 41 <= 3 * r["held_max"], r


def test_ptscotch_balances_the_cusick_disc_on_4_ranks():
    """The Cusick specimen (runs/cusick.opts) on 4 ranks: PT-Scotch within 5 %."""
    res = run("-options_file runs/cusick.opts -ts_max_steps 0 -cloth_partition ptscotch", np_=4)
    lo, hi, imbalance, cut = quality(res)
    assert lo > 0 and imbalance < 1.05, (lo, hi, imbalance, cut)


def test_ptscotch_runs_or_says_why_it_cannot():
    """PETSc hands PT-Scotch its indices as SCOTCH_Num. Where the widths match (this
    suite's 32-bit PETSc) the disc is partitioned; where they differ (Debian's 64-bit
    PETSc, whose PT-Scotch is the 32-bit one: it failed inside PT-Scotch with
    "communication error" and a traceback; CI's 64-bit run takes this branch) drape
    refuses with one sentence naming both widths and what to use instead."""
    res = run("-da_grid_x 41 -da_grid_y 41 -cloth_shape circle -ts_max_steps 0 -cloth_partition ptscotch", np_=3, check=False)
    if res.returncode == 0:
        assert "partition: ptscotch on 3 ranks" in res.stdout, res.stdout
        return
    lines = [l for l in res.stderr.splitlines() if l.startswith("drape: error:")]
    assert len(lines) == 1 and "indices are 64-bit and the PT-Scotch it is linked with takes 32-bit ones" in lines[0], res.stderr
    assert "use -cloth_partition dmda or metis" in lines[0] and "PETSC ERROR" not in res.stdout + res.stderr, res.stderr


def test_a_partitioner_petsc_lacks_is_refused_with_those_it_has():
    res = run("-da_grid_x 8 -da_grid_y 8 -ts_max_steps 1 -cloth_partition nosuch", check=False)
    msg = res.stdout + res.stderr
    assert res.returncode != 0 and "-cloth_partition nosuch is not a partitioner this build has" in msg, msg
    assert "it has dmda, metis, ptscotch" in msg and "PETSC ERROR" not in msg, msg


def inside(polys, x, y):
    """Even-odd rule, as drape applies it."""
    c = False
    for ring in polys:
        n = len(ring)
        for k in range(n):
            (xk, yk), (xl, yl) = ring[k], ring[k - 1]
            if (yk > y) != (yl > y) and x < (xl - xk) * (y - yk) / (yl - yk) + xk:
                c = not c
    return c


def test_polygon_panel_with_a_hole(tmp):
    """A cut garment panel with a hole (runs/outlines/panel.txt): the cloth is exactly
    the lattice cells whose four corners lie inside (even-odd rule), its mass their
    area times the density; the particles of no such cell (the hole's, the cut's
    spikes) never move, and METIS and PT-Scotch on 3 ranks give the 1-rank frames."""
    from conftest import ROOT
    rings, ring = [], []
    for line in (ROOT / "runs/outlines/panel.txt").read_text().splitlines():
        line = line.strip()
        if line.startswith("#"):
            continue
        if not line:
            if ring:
                rings.append(ring)
            ring = []
            continue
        ring.append(tuple(map(float, line.split())))
    if ring:
        rings.append(ring)
    n = 41
    h = 1.0 / (n - 1)  # the same arithmetic as drape: points on an edge fall the same way
    active = np.array([[inside(rings, i * h - 0.5, j * h - 0.5) for i in range(n)] for j in range(n)])
    args = (f"-da_grid_x {n} -da_grid_y {n} -cloth_outline runs/outlines/panel.txt -cloth_center 0,0,0.3 -solid_floor 0 "
            f"-contact_mode friction -ts_type basicsymplectic -ts_dt 2e-4 -ts_max_time 0.3 -output_interval 0.1")
    one, three = tmp / "one.h5", tmp / "three.h5"
    res = run(f"{args} -output_file {one}")
    run(f"{args} -cloth_partition metis -output_file {three}", np_=3)
    scotch = tmp / "scotch.h5"
    run(f"{args} -cloth_partition ptscotch -output_file {scotch}", np_=3)
    a, b = drape_h5.load(one), drape_h5.load(three)
    assert np.abs(a.positions - drape_h5.load(scotch).positions).max() <= ROUNDOFF
    cell = active[:-1, :-1] & active[1:, :-1] & active[:-1, 1:] & active[1:, 1:]
    corner = np.zeros_like(active)
    for dj in (0, 1):
        for di in (0, 1):
            corner[dj:n - 1 + dj, di:n - 1 + di] |= cell
    assert res.report["mass"] == pytest.approx(0.15 * cell.sum() / (n - 1) ** 2, rel=1e-12)  # lumped from the cells' area
    assert res.report["active_particles"] == corner.sum() <= active.sum()
    moved = np.abs(a.positions[-1] - a.positions[0]).max(axis=-1) > 0
    assert np.array_equal(moved, corner)  # exactly the cloth's particles fall
    assert np.abs(a.positions - b.positions).max() <= ROUNDOFF


def test_circle_specimen_is_its_cells():
    """The Cusick specimen (a 61 x 61 lattice cut to its inscribed circle): the four
    particles at the ends of the axes lie inside the circle but are corners of no cell
    inside it; they are not cloth (they were full-mass particles hanging on edges of
    no width). Mass = density x the area of the cells inside."""
    n = 61
    a = (np.arange(n) - (n - 1) / 2) / ((n - 1) / 2)
    inside = a[None, :] ** 2 + a[:, None] ** 2 <= 1 + 1e-12
    cell = inside[:-1, :-1] & inside[1:, :-1] & inside[:-1, 1:] & inside[1:, 1:]
    corner = np.zeros_like(inside)
    for dj in (0, 1):
        for di in (0, 1):
            corner[dj:n - 1 + dj, di:n - 1 + di] |= cell
    rep = run(f"-da_grid_x {n} -da_grid_y {n} -cloth_shape circle -cloth_size 0.3 -ts_max_steps 0", checks=False).report
    assert inside.sum() - corner.sum() == 4 and rep["active_particles"] == corner.sum()
    assert rep["mass"] == pytest.approx(0.15 * cell.sum() * (0.3 / (n - 1)) ** 2, rel=1e-12)


@pytest.mark.parametrize("text,message", [("0 0\n1 x\n", "is not 'x y' in metres"), ("0 0\n1 1\n\n", "needs at least 3"),
                                          ("5 5\n6 5\n6 6\n", "No lattice particle lies inside")])
def test_bad_outline_is_refused(tmp, text, message):
    import subprocess
    from conftest import DRAPE
    path = tmp / "outline.txt"
    path.write_text(text)
    res = subprocess.run([str(DRAPE), "-cloth_outline", str(path), "-ts_max_steps", "1"], capture_output=True, text=True)
    lines = [l for l in res.stderr.splitlines() if l.strip()]
    assert res.returncode != 0 and len(lines) == 1 and message in lines[0], res.stderr
