"""The Cusick study of the measured fabrics (scripts/cusick_fabrics.py): the radial-strip
lower bound against its known answers (the heavy elastica shot from the tip,
elastica.solve_tip, against solve() and the limp limit; the bound's stiff and limp
limits and its monotonicity; the softest direction of an orthotropic sheet), the
--quick smoke run's CSV, markdown and pictures, and real Cusick runs whose drape
coefficient must exceed the bound (issue 13)."""
import csv
import math
import random
import subprocess
import sys

import pytest

from conftest import ROOT, run

sys.path.insert(0, str(ROOT / "scripts"))
import cusick_fabrics as cf  # noqa: E402
import elastica  # noqa: E402


def script(name, *args, timeout=120):
    """Run scripts/<name> with `args` from the repository's root."""
    return subprocess.run([sys.executable, str(ROOT / "scripts" / name), *map(str, args)], capture_output=True, text=True, timeout=timeout, cwd=ROOT)


def csv_rows(path, columns):
    """The rows of the CSV `path`, whose header must be `columns`."""
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        assert reader.fieldnames == columns
        return list(reader)


@pytest.mark.parametrize("lam", [0.3, 8.0, 50.0, 300.0])
def test_elastica_from_the_tip_agrees_with_solve(lam):
    """Shooting from the tip (solve_tip) and from the clamp (solve) find the same strip
    where both converge (measured: 1e-14 at lam <= 110, 1e-11 at 400)."""
    a, b = elastica.solve_tip(lam), elastica.solve(lam)
    assert a.reach == pytest.approx(b.reach, abs=1e-9)
    assert a.drop == pytest.approx(b.drop, abs=1e-9)
    assert a.slope0 == pytest.approx(b.slope0, rel=1e-8)


def test_elastica_from_the_tip_limp_limit():
    """Where solve() no longer converges (lam = 1e4, 1e5) the limp strip hangs straight
    below a bend whose offset is (2 B / (w L))^(1/2): reach / L -> (2 / lam)^(1/2), 0.8 %
    and 0.3 % below the exact reach, and drop / L -> 1 - (2 - 2^(1/2)) lam^(-1/2) (the
    bend's arc beyond its drop); the clamp still carries the weight's moment."""
    for lam, rel in ((1e4, 0.012), (1e5, 0.005)):
        e = elastica.solve_tip(lam)
        assert e.reach == pytest.approx(math.sqrt(2 / lam), rel=rel)
        assert 0 < math.sqrt(2 / lam) < e.reach
        assert e.drop == pytest.approx(1 - (2 - math.sqrt(2)) / math.sqrt(lam), abs=1e-4)
        assert e.slope0 == pytest.approx(lam * sum((e.x[1:] + e.x[:-1]) / 2) / (len(e.x) - 1), rel=1e-4)


def test_bound_small_deflection_limit():
    """A stiff strip (lam = w L^3 / B << 1) stays horizontal: reach -> L, bound -> 1, and
    reach / L = 1 - lam^2 / 112 (elastica.py's expansion)."""
    for b in (1.0, 1e-2):
        bd = cf.radial_strip_bound(0.324, b)
        assert bd["lam"] == pytest.approx(0.324 * cf.G * 0.06 ** 3 / b)
        assert bd["reach"] / 0.06 == pytest.approx(1 - bd["lam"] ** 2 / 112, abs=1e-6)
        r = 0.09 + bd["reach"]
        assert bd["dc"] == pytest.approx((r * r - 0.09 ** 2) / (0.15 ** 2 - 0.09 ** 2), rel=1e-12)
        assert 0.999 < bd["dc"] <= 1


def test_bound_limp_limit():
    """A limp strip (lam ~ 7e4) hangs down at the edge: reach -> 0, bound -> 0 as
    2 R_p L (2 / lam)^(1/2) / (R_o^2 - R_p^2) to first order."""
    bd = cf.radial_strip_bound(0.324, 1e-8)
    assert bd["lam"] > 5e4
    assert bd["reach"] < 1e-3
    assert bd["dc"] < 0.01
    assert bd["dc"] == pytest.approx(2 * 0.09 * 0.06 * math.sqrt(2 / bd["lam"]) / (0.15 ** 2 - 0.09 ** 2), rel=0.02)


def test_bound_monotone_in_rigidity_and_weight():
    """A stiffer strip reaches further (the bound rises with B); a heavier one less far."""
    bs = [1e-7 * 2 ** k for k in range(12)]
    dcs = [cf.radial_strip_bound(0.2, b)["dc"] for b in bs]
    assert all(x < y for x, y in zip(dcs, dcs[1:])), dcs
    assert dcs[0] < 0.05 and dcs[-1] > 0.5
    heavy = [cf.radial_strip_bound(rho, 1e-5)["dc"] for rho in (0.1, 0.2, 0.4)]
    assert heavy[0] > heavy[1] > heavy[2]


def test_softest_rigidity():
    """The directional rigidity takes Bw, Bf, Bb at 0, 90, 45 deg; its minimum over all
    directions, in closed form, is the sampled minimum (random sheets), and lies below
    all three values when Bb < (Bw + Bf)/2 makes it convex in cos^2: Bw = 2, Bf = Bb = 1
    gives 0.875 at 60 deg. The paper's model (Bb = (Bw + Bf)/4) gives Bw Bf / (Bw + Bf)."""
    assert cf.directional_rigidity(0, 3, 5, 7) == pytest.approx(3)
    assert cf.directional_rigidity(math.pi / 2, 3, 5, 7) == pytest.approx(5)
    assert cf.directional_rigidity(math.pi / 4, 3, 5, 7) == pytest.approx(7)
    b, angle = cf.softest_rigidity(2, 1, 1)
    assert b == pytest.approx(0.875) and angle == pytest.approx(60)
    assert cf.softest_rigidity(3, 5, (3 + 5) / 4)[0] == pytest.approx(3 * 5 / (3 + 5))
    rng = random.Random(13)
    for _ in range(200):
        bw, bf = rng.uniform(1, 30), rng.uniform(1, 30)
        bb = rng.uniform(0.3, 1.2) * (bw + bf) / 2
        sampled = min(cf.directional_rigidity(math.radians(k / 20), bw, bf, bb) for k in range(1801))
        b, angle = cf.softest_rigidity(bw, bf, bb)
        assert b == pytest.approx(sampled, rel=1e-5, abs=0)
        assert b <= min(bw, bf, bb) * (1 + 1e-12)
        assert cf.directional_rigidity(math.radians(angle), bw, bf, bb) == pytest.approx(b, rel=1e-9)


def test_quick_smoke_run(tmp_path):
    """--quick: two fabrics on two coarse lattices for 0.3 s; the CSV has CSV_COLUMNS and
    a row per run (not at rest: the table says so), the markdown MD-style columns and a
    row per fabric, and a picture per fabric."""
    p = script("cusick_fabrics.py", "--quick", "--out", tmp_path)
    assert p.returncode == 0, p.stdout + p.stderr
    rows = csv_rows(tmp_path / "cusick_fabrics.csv", cf.CSV_COLUMNS)
    assert [(r["fabric"], r["grid"]) for r in rows] == [("denim", "21"), ("denim", "25"), ("gray-interlock", "21"), ("gray-interlock", "25")]
    for r in rows:
        assert r["status"] == "ok" and r["at_rest"] == "False" and float(r["t"]) == pytest.approx(0.3)
        assert 0 < float(r["bound"]) < float(r["drape_coefficient"]) <= 1.01
    md = (tmp_path / "cusick_fabrics.md").read_text().splitlines()
    assert md[0] == "| " + " | ".join(cf.md_columns((21, 25))) + " |"
    assert [line.split(" | ")[0] for line in md[2:4]] == ["| denim", "| gray-interlock"]
    assert all("**NO** (0.30)" in line for line in md[2:4])
    assert "Resolution floor" in "\n".join(md)
    for fabric in ("denim", "gray-interlock"):
        png = tmp_path / f"cusick_{fabric}.png"
        assert png.exists() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("fabric", ["denim", "gray-interlock"])
def test_cusick_dc_exceeds_the_radial_strip_bound(fabric):
    """Issue 13: the radial-strip elastica as a lower bound that every Cusick DC must
    exceed. Denim (a woven, softest along the weft) and the interlock knit (softest
    along the warp), on a 31^2 lattice, run to rest: DC (measured 0.533 and 0.392) above
    the bound of the softest direction (0.222, 0.118)."""
    res = run(cf.cusick_args(fabric, 31))
    row = cf.row_from_result(res, fabric, 31)
    assert row["status"] == "ok" and row["at_rest"], row
    assert row["drape_coefficient"] > row["bound"], row
    assert 0.05 < row["bound"] < 0.5 and 0 < row["drape_coefficient"] < 1, row
    assert row["b_min"] == pytest.approx(min(row["bend_warp"], row["bend_weft"], row["bend_bias"]), rel=1e-12)


def test_specimens_quick_smoke_run(tmp_path):
    """scripts/cusick_specimens.py --quick: denim, specimens 1 and 2 on 21^2 and 25^2
    for 0.2 s. Each run carries its seed and the amplitude; the two specimens are two
    different sheets (their DCs differ; with one flat sheet they would be equal), and the
    markdown's means and standard deviations are those of the CSV's DCs."""
    import statistics
    p = script("cusick_specimens.py", "--quick", "--jobs", 2, "--out", tmp_path)
    assert p.returncode == 0, p.stdout + p.stderr
    import cusick_specimens as cs
    rows = csv_rows(tmp_path / "specimens.csv", cs.CSV_COLUMNS)
    assert sorted((r["grid"], r["seed"]) for r in rows) == [("21", "1"), ("21", "2"), ("25", "1"), ("25", "2")]
    assert all(r["status"] == "ok" and float(r["amplitude"]) == cs.AMPLITUDE for r in rows)
    dc = {(r["grid"], r["seed"]): float(r["drape_coefficient"]) for r in rows}
    assert dc[("21", "1")] != dc[("21", "2")] and dc[("25", "1")] != dc[("25", "2")]
    md = (tmp_path / "specimens.md").read_text().splitlines()
    cells = md[2].split(" | ")
    for grid, cell in (("21", cells[2]), ("25", cells[3])):
        values = [dc[(grid, "1")], dc[(grid, "2")]]
        assert cell == f"{statistics.mean(values):.3f} ± {statistics.stdev(values):.3f}", (cell, values)
    assert "Resolution floor on the specimens' mean" in "\n".join(md)
    # --resume keeps the four runs (none is run again) and rewrites the same table
    again = script("cusick_specimens.py", "--quick", "--resume", "--out", tmp_path, timeout=60)
    assert again.returncode == 0 and "4 runs kept" in again.stdout and "0 to run" in again.stdout, again.stdout + again.stderr
    assert (tmp_path / "specimens.md").read_text().splitlines() == md
    other = script("cusick_specimens.py", "--quick", "--resume", "--amplitude", "1e-4", "--out", tmp_path, timeout=60)
    assert other.returncode == 1 and "holds runs of another amplitude" in other.stderr, other.stdout + other.stderr
    bad = script("cusick_specimens.py", "--seeds", "-1", "--out", tmp_path, timeout=60)
    assert bad.returncode == 2 and "--seeds one or more integers >= 0" in bad.stderr
